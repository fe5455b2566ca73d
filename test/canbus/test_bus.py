"""Tests of crawler_motion.canbus.bus: opening buses, and udp_multicast without own frames."""

from __future__ import annotations

import can

from crawler_motion.canbus.bus import drop_own_frames, make_bus_factory
from crawler_motion.testing.bus import BusSpec, random_multicast_group


def _frame(i: int) -> can.Message:
    return can.Message(arbitration_id=0x100 + i, data=[i], is_extended_id=False)


def _drain(bus: can.BusABC, timeout: float = 0.3) -> list[int]:
    ids = []
    while (msg := bus.recv(timeout)) is not None:
        ids.append(msg.arbitration_id)
        timeout = 0.05
    return ids


def test_a_bus_without_own_frames_still_reaches_every_other_member() -> None:
    spec = BusSpec.fresh(channel=random_multicast_group())
    quiet = make_bus_factory(spec.interface, spec.channel, spec.port, own_frames=False)()
    plain, other = spec.open(), spec.open()
    try:
        quiet.send(_frame(1))
        plain.send(_frame(2))
        assert _drain(other) == [0x101, 0x102]
        assert _drain(quiet) == [0x102]  # not its own 0x101
        assert _drain(plain) == [0x101, 0x102]  # python-can's plain bus hears itself
    finally:
        for bus in (quiet, plain, other):
            bus.shutdown()


def test_other_interfaces_are_left_as_they_are() -> None:
    bus = can.Bus(interface="virtual", channel="cm_bus_test")
    try:
        assert drop_own_frames(bus) is False
    finally:
        bus.shutdown()
