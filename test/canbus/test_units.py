"""Tests of the small units of crawler_motion.canbus: CRC, bus load, frame kinds, bus opening."""

from __future__ import annotations

import can
import pytest

from crawler_motion.canbus.bus import (
    bus_kwargs,
    default_channel,
    describe_bus,
    make_bus_factory,
    open_bus,
)
from crawler_motion.canbus.busload import cycle_bits, frame_bits_worst_case
from crawler_motion.canbus.crc import crc8_sae_j1850, frame_checksum
from crawler_motion.canbus.frames import CONTROLLER_KINDS, FrameKind, Side, sender_of
from crawler_motion.errors import BusOpenError, ProtocolError


@pytest.mark.parametrize(("data", "crc"), [
    (b"", 0x00),  # init 0xFF, xorout 0xFF
    (b"\x00", 0x3B),
    (b"\xff", 0xFF),  # init ^ 0xFF indexes table[0] = 0, then xorout
    (b"123456789", 0x4B),  # the catalogue check value of CRC-8/SAE-J1850
])
def test_crc8_rows(data, crc):
    assert crc8_sae_j1850(data) == crc


@pytest.mark.parametrize("skip", [0, 3, 7])
def test_frame_checksum_covers_id_and_every_other_byte(skip):
    data = bytearray(range(1, 9))
    expected = crc8_sae_j1850((0x123).to_bytes(2, "little") + bytes(data[:skip] + data[skip + 1:]))
    assert frame_checksum(0x123, data, skip) == expected
    data[skip] ^= 0xFF  # the checksum byte itself does not count
    assert frame_checksum(0x123, data, skip) == expected
    data[(skip + 1) % 8] ^= 0x01  # every other byte does
    assert frame_checksum(0x123, data, skip) != expected
    assert frame_checksum(0x124, bytes(range(1, 9)), skip) != expected  # and so does the id


@pytest.mark.parametrize(("n", "extended", "bits"), [
    (0, False, 55), (1, False, 65), (2, False, 75), (8, False, 135),
    (0, True, 80), (8, True, 160),
])
def test_frame_bits_rows(n, extended, bits):
    assert frame_bits_worst_case(n, extended) == bits


@pytest.mark.parametrize("n", [-1, 9])
def test_frame_bits_refuses_beyond_classic(n):
    with pytest.raises(ProtocolError, match=r"0\.\.8 data bytes, got"):
        frame_bits_worst_case(n)


def test_cycle_bits_sums_per_family():
    assert cycle_bits([]) == {}
    assert cycle_bits([(FrameKind.TARGET, 8)] * 4 + [("heartbeat", 2)]) == {
        "target": 540, "heartbeat": 75}
    assert all(type(k) is str for k in cycle_bits([(FrameKind.STATUS, 8)]))


def test_frame_kinds_and_senders():
    assert [k.value for k in FrameKind] == ["control", "target", "position", "effort",
                                            "status", "heartbeat"]
    assert f"{FrameKind.TARGET}" == "target" and FrameKind("status") is FrameKind.STATUS
    rows = {FrameKind.CONTROL: Side.CONTROLLER, FrameKind.TARGET: Side.CONTROLLER,
            FrameKind.POSITION: Side.MANAGER, FrameKind.EFFORT: Side.MANAGER,
            FrameKind.STATUS: Side.MANAGER,
            FrameKind.HEARTBEAT: Side.MANAGER}
    for kind, side in rows.items():
        assert sender_of(kind) is side and (kind in CONTROLLER_KINDS) == (side == "controller")


@pytest.mark.parametrize(("args", "kwargs"), [
    (("udp_multicast", "239.1.2.3", 0),
     {"interface": "udp_multicast", "channel": "239.1.2.3", "receive_own_messages": False}),
    (("udp_multicast", "239.1.2.3", 1),
     {"interface": "udp_multicast", "channel": "239.1.2.3", "receive_own_messages": False,
      "port": 1}),
    (("socketcan", "vcan0", 0, 500_000), {"interface": "socketcan", "channel": "vcan0"}),
    (("virtual", "x"), {"interface": "virtual", "channel": "x"}),
    (("pcan", "PCAN_USBBUS1"),
     {"interface": "pcan", "channel": "PCAN_USBBUS1", "bitrate": 1_000_000}),
    (("pcan", "PCAN_USBBUS1", 0, None), {"interface": "pcan", "channel": "PCAN_USBBUS1"}),
])
def test_bus_kwargs_rows(args, kwargs):
    assert bus_kwargs(*args) == kwargs


def test_default_channel_and_description():
    assert default_channel("udp_multicast") == "239.74.163.2"
    assert default_channel("socketcan") == "vcan0"
    assert default_channel("virtual") is None
    assert (describe_bus("udp_multicast", "239.74.163.2", 43113)
            == "udp_multicast 239.74.163.2:43113")
    assert describe_bus("socketcan", "vcan0", 43113) == "socketcan vcan0"


def test_open_bus_and_factory():
    bus = open_bus("virtual", "canbus-unit")
    other = make_bus_factory("virtual", "canbus-unit")()
    try:
        bus.send(can.Message(arbitration_id=0x10, data=b"\x01", is_extended_id=False))
        assert other.recv(timeout=1.0).arbitration_id == 0x10
    finally:
        bus.shutdown()
        other.shutdown()
    with pytest.raises(BusOpenError,
                       match="cannot open the CAN bus no_such_interface x: ") as info:
        open_bus("no_such_interface", "x")
    assert (info.value.interface, info.value.channel, info.value.port) == (
        "no_such_interface", "x", 0)
    assert isinstance(info.value, ValueError)
    with pytest.raises(can.CanInterfaceNotImplementedError):  # the factory passes errors on
        make_bus_factory("no_such_interface", "x")()
