"""The driver's joint efforts: decoded from the manager's effort frames into joint order [N m],
published with the positions of their cycle, never invented; bad effort frames are dropped and
counted like the other feedback."""

from __future__ import annotations

import uuid

import can
import numpy as np
import pytest

from crawler_motion.canbus.crc import crc8_sae_j1850
from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.driver.core import DriverCore
from crawler_motion.model.config import joint_names, load_config
from crawler_motion.sim.motor_manager import MotorManagerSim

JOINTS = joint_names()
STAND = np.array([0.0, 0.3, 1.2] * 4)
TAU = np.linspace(-3.0, 3.0, 12)  # joint order [N m]
RES = 0.001


@pytest.fixture(scope="module")
def proto() -> MotorProtocol:
    return MotorProtocol.from_config(load_config())


class Rig:
    """A driver core on a virtual channel and a sender of hand-made manager frames."""

    def __init__(self, proto: MotorProtocol) -> None:
        self.proto = proto
        self.channel = f"eff-{uuid.uuid4().hex}"
        self.bus = can.Bus(interface="virtual", channel=self.channel)
        self.spy = can.Bus(interface="virtual", channel=self.channel)
        self.now = 0.0
        self.out: list[tuple[np.ndarray, np.ndarray]] = []
        self.core = DriverCore(proto, self.bus, clock=lambda: self.now,
                               on_feedback=lambda q, e: self.out.append((q, e)))
        self.core.open()

    def send(self, frames: list[can.Message]) -> None:
        for msg in frames:
            self.spy.send(msg)
        self.now += 0.01
        self.core.poll()

    def cycle(self, counter: int, tau: np.ndarray | None = TAU) -> list[can.Message]:
        """One feedback cycle as the manager sends it: efforts first, then positions."""
        efforts = [] if tau is None else self.proto.encode_efforts(
            self.proto.effort_to_axis(tau), counter)
        return efforts + self.proto.encode_feedback(self.proto.to_axis(STAND), counter)

    def close(self) -> None:
        self.core.close()
        self.bus.shutdown()
        self.spy.shutdown()


@pytest.fixture
def rig(proto):
    r = Rig(proto)
    yield r
    r.close()


def test_efforts_go_out_with_the_positions_of_their_cycle(rig):
    rig.send(rig.cycle(0))
    assert len(rig.out) == 1
    q, tau = rig.out[0]
    np.testing.assert_allclose(q, STAND, atol=1e-4)
    np.testing.assert_allclose(tau, TAU, atol=RES / 2)  # joint order, directions undone
    assert rig.core.counters.rx_dropped == 0


def test_no_effort_frames_give_an_empty_effort_never_zeros(rig):
    rig.send(rig.cycle(0, tau=None))
    assert rig.out[0][1].shape == (0,)


def test_an_incomplete_effort_set_is_not_published(rig):
    frames = rig.cycle(0)
    rig.send(frames[1:])  # effort group 0 missing
    rig.send(rig.cycle(1))
    assert [e.size for _, e in rig.out] == [0, 12]


def test_efforts_sent_after_the_positions_go_with_the_next_vector(rig):
    first = rig.cycle(0)
    rig.send(first[4:] + first[:4])  # positions complete before the efforts came
    rig.send(rig.cycle(1, tau=None))  # the next cycle's positions, no efforts
    assert [e.size for _, e in rig.out] == [0, 12]


def crafted_effort(proto: MotorProtocol, group: int, raw: int, counter: int) -> can.Message:
    message = proto.database.get_message_by_name(f"MM_Effort_{group}")
    signals = {s.name: 0 for s in message.signals}
    signals.update({f"Axis{3 * group}_Effort": raw, "Counter": counter})
    data = bytearray(message.encode(signals, scaling=False, strict=False))
    data[7] = crc8_sae_j1850(message.frame_id.to_bytes(2, "little") + bytes(data[:7]))
    return can.Message(arbitration_id=message.frame_id, data=bytes(data), is_extended_id=False)


@pytest.mark.parametrize("flaw", ["checksum", "range", "repeated", "conflicting"])
def test_bad_effort_frames_are_dropped_and_counted(rig, flaw):
    rig.send(rig.cycle(0))
    frames = rig.cycle(1)
    if flaw == "checksum":
        data = bytearray(frames[2].data)
        data[0] ^= 0x01
        frames[2] = can.Message(arbitration_id=frames[2].arbitration_id, data=bytes(data),
                                is_extended_id=False)
    elif flaw == "range":
        frames[2] = crafted_effort(rig.proto, 2, -32768, 1)  # outside the DBC range
    else:  # group 2 repeats counter 0 of the previous cycle
        same = rig.proto.encode_efforts(rig.proto.effort_to_axis(
            TAU if flaw == "repeated" else TAU + 1.0), 0)
        frames[2] = same[2]
    rig.send(frames)
    c = rig.core.counters
    assert c.rx_dropped == 1 and c.feedback == 2
    assert rig.out[1][1].size == 0  # one effort group missing: no efforts, not old ones
    assert c.rx_conflicts == (1 if flaw == "conflicting" else 0)
    expected = {"checksum": "checksum", "range": "outside its range",
                "repeated": "repeated", "conflicting": "conflicting"}[flaw]
    assert expected in rig.core.last_rx_error
    rig.send(rig.cycle(2))
    assert rig.out[2][1].size == 12  # the next complete cycle has them again


def test_efforts_of_the_simulated_manager_reach_the_driver(proto):
    """The kinematic manager (no plant) reports unloaded axes, 0 N m; with ``effort=False``
    (a manager without effort frames) the efforts stay empty."""
    for effort, size in ((True, 12), (False, 0)):
        rig = Rig(proto)
        sim_bus = can.Bus(interface="virtual", channel=rig.channel)
        try:
            sim = MotorManagerSim(sim_bus, proto, rate=100.0, initial_positions=STAND,
                                  effort=effort)
            for _ in range(3):
                sim.step(0.01)
                rig.core.poll()
            assert rig.out and all(e.size == size for _, e in rig.out)
            if size:
                assert np.all(rig.out[-1][1] == 0.0)
        finally:
            sim_bus.shutdown()
            rig.close()


def test_the_diagnostics_give_the_age_of_the_efforts(rig):
    def effort_age() -> str:
        entry = next(e for e in rig.core.status() if e.name == "motor manager")
        return dict(entry.values)["effort_age"]

    assert effort_age() == "never"
    rig.send(rig.cycle(0, tau=None))
    assert effort_age() == "never"  # positions alone
    rig.send(rig.cycle(1))
    rig.now += 0.02
    assert float(effort_age()) == pytest.approx(0.02)  # since the vector that carried them
