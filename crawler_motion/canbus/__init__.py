"""The motor manager's CAN protocol: DBC codec, axis map, CRC and bus opening."""
