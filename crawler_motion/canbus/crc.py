"""CRC-8/SAE-J1850 (table driven) and the frame checksum built on it."""

from __future__ import annotations

#: Generator polynomial of CRC-8/SAE-J1850 (x^8 + x^4 + x^3 + x^2 + 1, MSB first).
POLY = 0x1D
#: Initial register value and final XOR of CRC-8/SAE-J1850.
INIT = XOROUT = 0xFF


def _crc8_table(poly: int) -> tuple[int, ...]:
    """The 256-entry lookup table of an MSB-first CRC-8 with generator ``poly``."""
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


_TABLE = _crc8_table(POLY)


def crc8_sae_j1850(data: bytes) -> int:
    """CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, xorout 0xFF); ``b"123456789"`` gives 0x4B."""
    crc = INIT
    for byte in data:
        crc = _TABLE[crc ^ byte]
    return crc ^ XOROUT


def frame_checksum(frame_id: int, data: bytes | bytearray, skip: int) -> int:
    """The Checksum byte of a frame: the CRC over the id (2 bytes, little-endian) and every
    data byte but the one at index ``skip`` (the checksum's own)."""
    body = bytes(data[:skip]) + bytes(data[skip + 1:])
    return crc8_sae_j1850(frame_id.to_bytes(2, "little") + body)
