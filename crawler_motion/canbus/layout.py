"""Bit layouts of the DBC's frames, compiled once from the cantools database: packing and
unpacking without cantools' per-call machinery.

The DBC stays the one description of the frames; cantools loads it, and this module reads each
message's signals (start bit, length, sign, and cantools' own conversion objects for scaling)
into a `FrameLayout`, which packs and unpacks a frame's payload as one little-endian integer.
The driver unpacks ~1,000 feedback frames/s and packs four target frames per joint command; in
cantools each call builds dictionaries and runs ``bitstruct`` and its checks, several times the
work of the bit arithmetic. The results are those of cantools (``scaling=True``,
``decode_choices=False``, ``strict=True``: the same values, the same refusals), which the tests
check property-wise against cantools itself.

Only what `dbc.DbcIndex` accepts is compiled: classic frames of little-endian,
non-multiplexed signals. A message with a floating-point signal is not (`compile_layout`
returns None): its frames go through cantools as before.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from cantools.database import DecodeError, EncodeError
from cantools.database.conversion import IdentityConversion

#: Relative slack of cantools' strict range check, in units of a signal's scale.
CANTOOLS_RANGE_SLACK = 1e-6


@dataclass(frozen=True)
class SignalLayout:
    """Where one integer signal lies in the payload and how it scales."""

    name: str
    start: int  # first bit, little-endian numbering (cantools' ``start``)
    mask: int  # (1 << length) - 1
    sign_bit: int  # 1 << (length - 1) for signed signals, 0 for unsigned
    raw_min: int
    raw_max: int
    to_scaled: Callable[[int, bool], Any] | None  # conversion.raw_to_scaled; None: identity
    to_raw: Callable[[float], Any]  # cantools' conversion.numeric_scaled_to_raw
    low: float | None  # minimum - slack (cantools' strict range), None if open
    high: float | None  # maximum + slack
    choices: frozenset[int]  # raw values of the value table (exempt from the range check)


def _signal_layout(signal: Any) -> SignalLayout:
    length = int(signal.length)
    signed = bool(signal.is_signed)
    slack = abs(signal.conversion.scale) * CANTOOLS_RANGE_SLACK
    return SignalLayout(
        name=str(signal.name), start=int(signal.start), mask=(1 << length) - 1,
        sign_bit=(1 << (length - 1)) if signed else 0,
        raw_min=-(1 << (length - 1)) if signed else 0,
        raw_max=(1 << (length - 1)) - 1 if signed else (1 << length) - 1,
        to_scaled=(None if type(signal.conversion) is IdentityConversion
                   else signal.conversion.raw_to_scaled),
        to_raw=signal.conversion.numeric_scaled_to_raw,
        low=None if signal.minimum is None else signal.minimum - slack,
        high=None if signal.maximum is None else signal.maximum + slack,
        choices=frozenset(int(k) for k in (signal.conversion.choices or {})))


class FrameLayout:
    """Packs and unpacks the payload of one DBC message (see the module docstring)."""

    def __init__(self, message: Any) -> None:
        self.name = str(message.name)
        self.length = int(message.length)
        self.signals = tuple(_signal_layout(s) for s in message.signals)
        self._names = frozenset(s.name for s in self.signals)

    def unpack(self, data: bytes) -> dict[str, Any]:
        """Signal name -> scaled value of a payload of `length` bytes (as cantools'
        ``decode(data, decode_choices=False, scaling=True)``); cantools' ``DecodeError`` if the
        length differs."""
        if len(data) != self.length:
            raise DecodeError(f"Wrong data size: {len(data)} instead of {self.length} bytes")
        bits = int.from_bytes(data, "little")
        values = {}
        for s in self.signals:
            raw = (bits >> s.start) & s.mask
            if raw & s.sign_bit:
                raw -= s.mask + 1
            values[s.name] = raw if s.to_scaled is None else s.to_scaled(raw, False)
        return values

    def pack(self, values: Mapping[str, Any]) -> bytes:
        """The payload of ``values`` (signal name -> scaled number), unused bits zero (as
        cantools' ``encode(values, scaling=True, padding=False, strict=True)``); cantools'
        ``EncodeError`` for a missing or unknown signal, a value beyond the signal's range or
        its bits (``ValueError`` / ``OverflowError`` for NaN / infinity, as in cantools)."""
        if values.keys() != self._names:
            missing = sorted(self._names - values.keys())
            extra = sorted(values.keys() - self._names)
            raise EncodeError(f"{self.name}: signals missing {missing}, unknown {extra}")
        bits = 0
        for s in self.signals:
            value = values[s.name]
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise EncodeError(f"{self.name}.{s.name}: {value!r} is not a number")
            raw = s.to_raw(value)
            if raw not in s.choices and ((s.low is not None and value < s.low)
                                         or (s.high is not None and value > s.high)):
                raise EncodeError(f"{self.name}.{s.name} = {value} is beyond its range")
            if not s.raw_min <= raw <= s.raw_max:
                raise EncodeError(f"{self.name}.{s.name} = {value} does not fit its bits")
            bits |= (raw & s.mask) << s.start
        return bits.to_bytes(self.length, "little")


def compile_layout(message: Any) -> FrameLayout | None:
    """The `FrameLayout` of a cantools message of little-endian, non-multiplexed integer
    signals; None for any other (it is then packed and unpacked by cantools)."""
    if message.is_container or message.is_fd or message.length > 8:
        return None
    for signal in message.signals:
        if (signal.byte_order != "little_endian" or signal.multiplexer_ids
                or signal.is_multiplexer or signal.conversion.is_float):
            return None
    return FrameLayout(message)
