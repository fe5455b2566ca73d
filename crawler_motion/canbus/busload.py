"""Worst-case wire bits of classic CAN frames, for bus-load budgets."""

from __future__ import annotations

import operator
from collections.abc import Iterable, Mapping

from crawler_motion.errors import ProtocolError

#: Bits of a classic frame outside the data field that are subject to stuffing, by id length.
STUFFED_OVERHEAD_BITS = {False: 34, True: 54}  # 11-bit id, 29-bit id
#: CRC delimiter, ACK slot and delimiter, end of frame (7) and interframe space (3): never stuffed.
UNSTUFFED_BITS = 13
#: Data bytes of a classic CAN frame at most.
MAX_DATA_BYTES = 8
#: Bit rate the bus-load figures refer to [bit/s].
DEFAULT_BITRATE = 1_000_000


def frame_bits_worst_case(data_bytes: int, extended: bool = False) -> int:
    """Bits on the wire of one classic CAN data frame with worst-case bit stuffing.

    Includes the 3-bit interframe space (Davis, Burns, Bril, Lukkien 2007):
    ``8n + g + 13 + floor((g + 8n - 1) / 4)`` with g = 34 for an 11-bit id, 54 for a 29-bit id.
    Eight data bytes and an 11-bit id give 135 bits, i.e. 135 us at 1 Mbit/s.
    """
    n = operator.index(data_bytes)
    if not 0 <= n <= MAX_DATA_BYTES:
        raise ProtocolError(f"a classic CAN frame carries 0..{MAX_DATA_BYTES} data bytes, "
                            f"got {n}")
    g = STUFFED_OVERHEAD_BITS[bool(extended)]
    return 8 * n + g + UNSTUFFED_BITS + (g + 8 * n - 1) // 4


def cycle_bits(frames: Iterable[tuple[str, int]]) -> dict[str, int]:
    """Worst-case wire bits of one cycle per frame family, of ``(family, data bytes)`` pairs
    (11-bit ids); e.g. four 8-byte target frames give ``{"target": 540}``."""
    bits: dict[str, int] = {}
    for kind, length in frames:
        key = str(getattr(kind, "value", kind))
        bits[key] = bits.get(key, 0) + frame_bits_worst_case(length)
    return bits


def load_percent(bits: Mapping[str, int], rates: Mapping[str, float],
                 bitrate: float = DEFAULT_BITRATE) -> float:
    """Worst-case bus load [%] of frame families sending ``bits[family]`` wire bits per cycle
    at ``rates[family]`` [Hz] on a bus of ``bitrate`` [bit/s]; families without a rate
    (sporadic ones, e.g. control) are not counted."""
    if not bitrate > 0:
        raise ProtocolError(f"bitrate must be > 0 bit/s, got {bitrate!r}")
    return 100.0 * sum(b * rates[k] for k, b in bits.items() if k in rates) / bitrate
