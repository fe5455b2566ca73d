"""Tests of crawler_motion.driver.core: pure, on python-can virtual buses and stub buses.

A fake steady clock drives the core and `MotorManagerSim.step` drives the manager, so watchdog,
reopen and heartbeat timing are deterministic; one test runs the core's own thread on the real
clock to bound the recovery time after the bus returns.
"""

from __future__ import annotations

import math
import time
import uuid

import can
import numpy as np
import pytest

from crawler_motion.canbus.bus import bus_kwargs
from crawler_motion.canbus.crc import crc8_sae_j1850
from crawler_motion.canbus.protocol import (
    AxisFlags,
    ControlFrame,
    MotorProtocol,
    TargetFrame,
)
from crawler_motion.driver.core import DriverCore
from crawler_motion.driver.diagnostics import Level
from crawler_motion.driver.link import FAILED_FRAMES_BEFORE_REOPEN, DriverError
from crawler_motion.driver.settings import PARAMETERS, DriverSettings
from crawler_motion.model.config import joint_names, load_config
from crawler_motion.runtime.parameters import validate_parameters
from crawler_motion.sim.motor_manager import MotorManagerSim

JOINTS = joint_names()
OK, WARN, ERROR, STALE = Level
DT = 0.01
RES = 0.0001
STAND = np.array([0.0, 0.3, 1.2] * 4)

#: Real-time waits poll this many times longer than the nominal time: a loaded CI machine can
#: starve a process for a while. The timings themselves are measured (and reported) by the
#: fault-injection tests and the benchmarks, and asserted on fake clocks in the unit tests.
WAIT_SLACK = 3.0



@pytest.fixture(scope="module")
def proto():
    return MotorProtocol.from_config(load_config().robot)


class FakeClock:
    """A steady clock the test advances by hand [s]."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t

    def advance(self, dt: float) -> None:
        self.t += dt


class Faults:
    """Shared switches of the flaky buses: a broken bus raises on send, recv and open."""

    def __init__(self) -> None:
        self.broken = False
        self.fail_sends = 0  # the next n send attempts raise (full transmit buffer)
        self.attempts = 0  # send attempts seen


class FlakyBus(can.BusABC):
    """A virtual bus that fails on demand (see `Faults`)."""

    def __init__(self, channel: str, faults: Faults) -> None:
        self.inner = can.Bus(interface="virtual", channel=channel)
        self.faults = faults
        super().__init__(channel=channel)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.faults.attempts += 1
        if self.faults.broken:
            raise can.CanOperationError("bus gone: network is down")
        if self.faults.fail_sends > 0:
            self.faults.fail_sends -= 1
            raise can.CanOperationError("Transmit buffer full")
        self.inner.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if self.faults.broken:
            raise can.CanOperationError("bus gone: network is down")
        return self.inner.recv(timeout), False

    def shutdown(self) -> None:
        self.inner.shutdown()
        super().shutdown()


class Rig:
    """A core, a stepped simulated manager and a spy on one virtual channel."""

    def __init__(self, proto: MotorProtocol, *, flaky: bool = False, factory: bool = False,
                 sim: bool = True, **settings: object) -> None:
        self.proto = proto
        self.channel = f"drv-{uuid.uuid4().hex}"
        self.clock = FakeClock()
        self.faults = Faults()
        self.created: list[FlakyBus] = []
        self.spy = can.Bus(interface="virtual", channel=self.channel)
        self.sim_bus = can.Bus(interface="virtual", channel=self.channel)
        self.sim = MotorManagerSim(self.sim_bus, proto, speed_limit=2.0, rate=100.0,
                                   heartbeat_period=0.1, command_timeout=1.0,
                                   initial_positions=STAND) if sim else None
        self.feedback: list[np.ndarray] = []
        self.efforts: list[np.ndarray] = []
        # a permissive step bound: these tests are about other rules (see test_step_bound)
        options = {"command_timeout": 0.2, "reopen_period": 0.2, "step_speed_limit": 100.0,
                   "step_margin": 1.0}
        options.update(settings)
        kwargs: dict[str, object] = {"settings": DriverSettings(**options),
                                     "clock": self.clock, "on_feedback": self._on_feedback}
        if factory:
            self.core = DriverCore(proto, bus_factory=self._open, **kwargs)
        else:
            self.bus = (FlakyBus(self.channel, self.faults) if flaky
                        else can.Bus(interface="virtual", channel=self.channel))
            self.core = DriverCore(proto, self.bus, **kwargs)
        self.core.open()
        if self.sim is not None:  # a measured pose: the first command after enable needs one
            self.sim.step(DT)
            self.core.poll(0.05)
        self.frames: list[object] = []
        self.counter = 0

    def _on_feedback(self, positions: np.ndarray, efforts: np.ndarray) -> None:
        self.feedback.append(positions)
        self.efforts.append(efforts)

    def _open(self) -> can.BusABC:
        if self.faults.broken:
            raise can.CanOperationError("no such device")
        bus = FlakyBus(self.channel, self.faults)
        self.created.append(bus)
        return bus

    def close(self) -> None:
        self.core.close()
        for bus in [self.spy, self.sim_bus, getattr(self, "bus", None), *self.created]:
            if bus is not None:
                bus.shutdown()

    def collect(self) -> list[object]:
        """Driver-side frames (control, target) seen by the spy since the last call."""
        new = []
        while (msg := self.spy.recv(0.0)) is not None:
            frame = self.proto.decode(msg)
            if isinstance(frame, (ControlFrame, TargetFrame)):
                new.append(frame)
        self.frames.extend(new)
        return new

    def submit(self, q: np.ndarray, names: list[str] | None = None):
        return self.core.submit(names or list(JOINTS), list(q))

    def run(self, seconds: float, q: np.ndarray | None = None) -> None:
        """Advance everything by ``seconds`` in steps of DT, submitting ``q`` every step."""
        for _ in range(round(seconds / DT)):
            if q is not None:
                self.submit(q)
            if self.sim is not None:
                self.sim.step(DT)
            self.clock.advance(DT)
            self.core.poll()
            self.core.tick()

    def entry(self, name: str):
        return next(e for e in self.core.status() if e.name.startswith(name))


def controls(frames: list[object]) -> list[str]:
    return [f.command for f in frames if isinstance(f, ControlFrame)]


def targets(frames: list[object]) -> list[TargetFrame]:
    return [f for f in frames if isinstance(f, TargetFrame)]


@pytest.fixture
def rig(proto):
    r = Rig(proto)
    yield r
    r.close()


def test_nothing_sent_before_activate(rig):
    rig.run(0.3, STAND)  # commands, ticks and feedback while inactive
    assert rig.collect() == []
    assert rig.sim.counters.received == 0
    assert rig.core.counters.inactive == 30 and rig.core.counters.tx == 0
    assert rig.feedback, "feedback is bookkept while inactive"
    ok, _ = rig.core.activate()
    assert ok
    assert controls(rig.collect()) == ["enable"]


def test_enable_then_targets_decode_to_commanded_angles(rig, proto):
    goal = STAND + np.linspace(-0.2, 0.2, 12)
    rig.core.activate()
    result = rig.submit(goal)
    assert result.accepted and result.sent, result
    frames = rig.collect()
    assert controls(frames) == ["enable"] and isinstance(frames[0], ControlFrame)
    sent = targets(frames)
    assert len(sent) == len(proto.frame_ids("target"))
    got = {j: q for f in sent for j, q in f.positions.items()}
    assert set(got) == set(JOINTS)
    for i, joint in enumerate(JOINTS):
        assert abs(got[joint] - goal[i]) <= RES / 2 + 1e-12, joint
    # the manager follows, and the published feedback converges to the command
    rig.run(0.5, goal)
    assert rig.sim.state == "enabled"
    np.testing.assert_allclose(rig.sim.joint_positions, goal, atol=RES)
    np.testing.assert_allclose(rig.feedback[-1], goal, atol=RES)
    assert rig.core.counters.commands == 51 and rig.core.counters.refused == 0


def _variants():
    names = list(JOINTS)
    q = list(STAND)
    upper_knee = 2.6
    return {
        "missing name": (names[:-1], q[:-1], "missing ['rf_knee_joint']"),
        "extra name": ([*names, "tail_joint"], [*q, 0.0], "unknown ['tail_joint']"),
        "duplicate name": ([*names[:-1], names[0]], q, "duplicate ['lf_root_joint']"),
        "short positions": (names, q[:-1], "12 names but 11 positions"),
        "no positions": (names, [], "12 names but 0 positions"),
        "nan": (names, [math.nan, *q[1:]], "non-finite"),
        "inf": (names, [*q[:-1], math.inf], "non-finite"),
        "above limit": (names, [*q[:-1], upper_knee + 0.01], "outside the joint limits"),
        "below limit": (names, [-0.95, *q[1:]], "outside the joint limits"),
        "not a number": (names, ["x", *q[1:]], "must be numbers"),
        "numeric string": (names, ["0.1", *q[1:]], "must be numbers"),
        "bool": (names, [True, *q[1:]], "must be numbers"),
        "int beyond float": (names, [10**400, *q[1:]], "non-finite"),
    }


@pytest.mark.parametrize("velocity", [math.nan, math.inf, "0.1", None])
def test_a_broken_velocity_is_refused(rig, velocity):
    """Velocities are not sent, but a NaN or a string means the sender is broken."""
    rig.core.activate()
    result = rig.core.submit(JOINTS, list(STAND), [velocity, *[0.0] * 11])
    assert not result.accepted and "velocities must be finite numbers" in result.reason
    assert "lf_root_joint" in result.reason and rig.core.counters.refused == 1
    assert rig.core.submit(JOINTS, list(STAND), [0.0] * 12).accepted


@pytest.mark.parametrize("variant", list(_variants()))
def test_invalid_commands_are_refused_and_counted(rig, variant):
    names, positions, reason = _variants()[variant]
    rig.core.activate()
    rig.collect()
    result = rig.core.submit(names, positions)
    assert not result.accepted and reason in result.reason
    assert rig.core.counters.refused == 1 and rig.core.counters.commands == 0
    assert reason in rig.entry("motor manager").values[-1][1]  # last_refusal reported
    assert targets(rig.collect()) == []  # refused, not clipped and sent


def test_velocity_and_effort_lengths_are_checked(rig):
    rig.core.activate()
    bad = rig.core.submit(list(JOINTS), list(STAND), velocities=[0.0] * 5)
    assert not bad.accepted and "5 velocities" in bad.reason
    good = rig.core.submit(list(JOINTS), list(STAND), velocities=[0.0] * 12, efforts=())
    assert good.accepted


def test_commands_are_matched_by_name_not_order(rig):
    rig.core.activate()
    rig.collect()
    order = list(reversed(JOINTS))
    q = {j: STAND[i] + 0.01 * i for i, j in enumerate(JOINTS)}
    assert rig.core.submit(order, [q[j] for j in order]).sent
    got = {j: v for f in targets(rig.collect()) for j, v in f.positions.items()}
    for j in JOINTS:
        assert abs(got[j] - q[j]) <= RES / 2 + 1e-12


@pytest.mark.parametrize("mode", ["hold", "disable"])
def test_deactivate_sends_its_command_and_stops_forwarding(proto, mode):
    rig = Rig(proto, on_deactivate=mode)
    try:
        rig.core.activate()
        rig.run(0.1, STAND)
        rig.collect()
        assert rig.core.deactivate() == f"{mode} sent"
        rig.run(0.3, STAND)
        assert controls(rig.collect()) == [mode]
        assert rig.sim.state == ("hold" if mode == "hold" else "disabled")
        assert rig.core.counters.inactive == 30
    finally:
        rig.close()


@pytest.mark.parametrize("mode", ["hold", "disable"])
def test_watchdog_stops_motion_until_reenabled(proto, mode):
    rig = Rig(proto, on_timeout=mode, command_timeout=0.2)
    try:
        rig.core.activate()
        rig.run(0.3, STAND)
        assert not rig.core.watchdog_tripped
        assert rig.entry("motor manager").level == OK
        rig.collect()
        rig.run(0.19)
        assert not rig.core.watchdog_tripped and rig.collect() == []
        rig.run(0.03)
        assert rig.core.watchdog_tripped
        assert controls(rig.collect()) == [mode]
        entry = rig.entry("motor manager")
        assert entry.level == ERROR and "watchdog" in entry.message
        # commands resume only after an explicit re-enable
        result = rig.submit(STAND)
        assert not result.accepted and "~/enable" in result.reason
        rig.run(0.3, STAND)
        assert targets(rig.collect()) == [] and rig.core.counters.blocked == 31
        assert rig.sim.state == ("hold" if mode == "hold" else "disabled")
        ok, _ = rig.core.enable()
        assert ok and controls(rig.collect()) == ["enable"]
        assert rig.submit(STAND).sent and len(targets(rig.collect())) == 4
        assert rig.core.counters.watchdog_trips == 1
    finally:
        rig.close()


def test_watchdog_arms_only_with_the_first_command(rig):
    rig.core.activate()
    rig.run(1.0)  # enabled, no command yet: nothing to watch
    assert not rig.core.watchdog_tripped
    rig.run(0.05, STAND)
    rig.run(0.25)
    assert rig.core.watchdog_tripped


def test_deactivate_and_activate_clear_the_watchdog(rig):
    rig.core.activate()
    rig.run(0.05, STAND)
    rig.run(0.3)
    assert rig.core.watchdog_tripped
    rig.core.deactivate()
    rig.core.activate()
    assert not rig.core.watchdog_tripped and rig.submit(STAND).sent


def test_estop_latches_and_blocks_motion_until_reset_and_enable(rig):
    rig.core.activate()
    rig.run(0.1, STAND)
    rig.collect()
    assert rig.core.estop("test") is True  # the frame went out within the call
    assert controls(rig.collect()) == ["estop"]
    rig.run(0.3, STAND)
    assert rig.sim.state == "estop"
    assert targets(rig.collect()) == []
    assert rig.entry("motor manager").level == ERROR
    assert not rig.core.enable()[0]  # no re-enable while latched
    assert not rig.submit(STAND).accepted
    ok, message = rig.core.reset()
    assert ok and "~/enable" in message
    rig.run(0.05, STAND)
    assert rig.sim.state == "disabled" and targets(rig.collect()) == []  # needs enable
    assert rig.core.enable()[0]
    rig.run(0.05, STAND)
    assert rig.sim.state == "enabled"
    rig.collect()
    assert controls(rig.frames) == ["enable", "estop", "reset", "enable"]
    assert targets(rig.frames)[-1].positions


def test_activation_is_refused_while_estop_is_latched(rig):
    rig.core.estop("before activation")
    assert controls(rig.collect()) == ["estop"]
    ok, reason = rig.core.activate()
    assert not ok and "~/reset" in reason


def test_estop_is_reasserted_when_the_manager_leaves_it(rig):
    rig.core.activate()
    rig.core.estop("test")
    rig.run(0.2)
    rig.collect()
    rig.spy.send(rig.proto.encode_control("reset"))  # someone else resets the manager
    rig.run(0.4)
    assert controls(rig.collect()) == ["estop"]  # re-sent once, after a disabled heartbeat
    assert rig.sim.state == "estop"


def _late_manager(rig: Rig) -> None:
    """Replace the rig's manager by one that joins the bus only now (it missed everything)."""
    rig.sim_bus.shutdown()
    rig.sim_bus = can.Bus(interface="virtual", channel=rig.channel)
    rig.sim = MotorManagerSim(rig.sim_bus, rig.proto, rate=100.0, heartbeat_period=0.1,
                              command_timeout=1.0, initial_positions=STAND)


def test_an_enable_sent_before_the_manager_listened_is_resent(proto):
    rig = Rig(proto, sim=False)
    try:
        assert rig.core.activate()[0]  # nobody listens yet: the enable is lost
        rig.clock.advance(0.5)
        _late_manager(rig)
        rig.run(0.3, STAND)
        assert rig.sim.state == "enabled"
        assert controls(rig.collect()) == ["enable", "enable"]
        np.testing.assert_allclose(rig.feedback[-1], STAND, atol=RES)
        assert rig.entry("motor manager").level == OK
    finally:
        rig.close()


def test_a_manager_that_fell_back_to_disabled_is_not_re_enabled_silently(rig):
    rig.core.activate()
    rig.run(0.3, STAND)
    assert rig.sim.state == "enabled"
    _late_manager(rig)  # the manager rebooted: disabled, after having confirmed our enable
    rig.collect()
    rig.run(0.3, STAND)
    assert rig.sim.state == "disabled" and controls(rig.collect()) == []
    entry = rig.entry("motor manager")
    assert entry.level == ERROR and "call ~/enable" in entry.message
    assert rig.core.enable()[0]
    rig.run(0.1, STAND)
    assert rig.sim.state == "enabled"


def test_send_errors_are_counted_and_retries_are_bounded(proto):
    rig = Rig(proto, flaky=True, send_retries=2)
    try:
        rig.core.activate()
        rig.collect()
        rig.faults.fail_sends = 2  # two failures: the third attempt goes out
        attempts = rig.faults.attempts
        assert rig.submit(STAND).sent
        assert rig.faults.attempts - attempts == 2 + 4
        assert rig.core.counters.tx_errors == 2
        assert len(targets(rig.collect())) == 4
        rig.faults.fail_sends = 10**6  # a full transmit buffer for good
        attempts = rig.faults.attempts
        result = rig.submit(STAND)  # never raises, never blocks
        assert result.accepted and not result.sent
        assert rig.faults.attempts - attempts == 3  # 1 + send_retries, then it waits
        assert rig.core.counters.tx_errors == 5
        assert "Transmit buffer full" in rig.core.last_tx_error
    finally:
        rig.close()


def test_an_unsent_command_is_dropped_after_one_period_never_sent_late(proto):
    rig = Rig(proto, flaky=True, send_retries=0)
    try:
        rig.core.activate()
        rig.collect()
        rig.faults.fail_sends = 1
        assert not rig.submit(STAND).sent
        rig.clock.advance(0.005)  # younger than the 10 ms target period: retried
        rig.core.tick()
        assert len(targets(rig.collect())) == 4
        rig.faults.fail_sends = 1
        assert not rig.submit(STAND + 0.01).sent
        rig.clock.advance(0.011)  # older than one period: dropped
        rig.core.tick()
        rig.clock.advance(0.1)
        rig.core.tick()
        assert targets(rig.collect()) == []
        assert rig.core.counters.tx_stale == 1
    finally:
        rig.close()


def test_only_the_newest_command_is_ever_sent(proto):
    rig = Rig(proto, flaky=True, send_retries=0)
    try:
        rig.core.activate()
        rig.collect()
        rig.faults.fail_sends = 2
        rig.submit(STAND + 0.01)
        rig.submit(STAND + 0.02)  # supersedes the first one
        rig.core.tick()
        sent = targets(rig.collect())
        assert len(sent) == 4
        knee = sent[0].positions["lf_knee_joint"]
        assert abs(knee - (STAND[2] + 0.02)) <= RES
        assert rig.core.counters.tx_stale == 1
    finally:
        rig.close()


def test_bus_gone_is_survived_and_reopened_within_one_second(proto):
    rig = Rig(proto, factory=True, reopen_period=0.2, command_timeout=5.0)
    try:
        rig.core.activate()
        rig.run(0.2, STAND)
        assert rig.core.bus_ok
        rig.faults.broken = True  # send, recv and open all raise now
        rig.run(1.0, STAND)  # no exception escapes
        c = rig.core.counters
        assert not rig.core.bus_ok and c.bus_failures == 1
        assert 3 <= c.reopen_failures <= 6  # every reopen_period
        assert rig.created[0]._is_shutdown  # the broken bus was closed
        entry = rig.entry("CAN bus")
        assert entry.level == ERROR and "down" in entry.message
        rig.collect()
        rig.faults.broken = False
        targets_before = rig.sim.counters.targets
        back = None
        for step in range(100):
            rig.run(DT, STAND)
            if rig.sim.counters.targets > targets_before:
                back = (step + 1) * DT
                break
        assert back is not None and back <= 0.2 + 2 * DT
        assert rig.core.bus_ok and rig.core.counters.reopens == 1
        assert len(rig.created) == 2 and not rig.created[1]._is_shutdown
        assert rig.entry("CAN bus").level == OK
    finally:
        rig.close()


def test_control_frames_queued_while_the_bus_is_down_go_out_after_reopen(proto):
    rig = Rig(proto, factory=True, reopen_period=0.1)
    try:
        rig.core.activate()
        rig.faults.broken = True
        rig.run(0.05)
        rig.collect()
        assert rig.core.estop("bus down") is False
        rig.run(0.2)
        assert controls(rig.collect()) == []
        rig.faults.broken = False
        rig.run(0.2)
        assert "estop" in controls(rig.collect())
        assert rig.sim.state == "estop"
    finally:
        rig.close()


def test_repeated_send_failures_take_the_bus_down(proto):
    rig = Rig(proto, factory=True, send_retries=1, reopen_period=0.05)
    try:
        rig.core.activate()
        rig.faults.fail_sends = 10**6
        for _ in range(FAILED_FRAMES_BEFORE_REOPEN):
            rig.clock.advance(0.02)
            rig.submit(STAND)
        assert not rig.core.bus_ok and rig.core.counters.bus_failures == 1
        rig.faults.fail_sends = 0
        rig.run(0.1, STAND)
        assert rig.core.bus_ok and rig.core.counters.reopens == 1
    finally:
        rig.close()


def test_recovery_on_the_real_clock_with_the_core_thread(proto):
    """The core's own thread reopens the bus < 1 s after it returns (real time)."""
    channel = f"drv-{uuid.uuid4().hex}"
    faults = Faults()
    created: list[FlakyBus] = []

    def factory() -> can.BusABC:
        if faults.broken:
            raise can.CanOperationError("no such device")
        created.append(FlakyBus(channel, faults))
        return created[-1]

    sim_bus = can.Bus(interface="virtual", channel=channel)
    sim = MotorManagerSim(sim_bus, proto, initial_positions=STAND, command_timeout=1.0)
    core = DriverCore(proto, bus_factory=factory,
                      settings=DriverSettings(reopen_period=0.2, command_timeout=5.0))
    try:
        sim.start()
        core.open()
        core.start()
        assert core.activate()[0]
        for _ in range(10):
            core.submit(list(JOINTS), list(STAND))
            time.sleep(DT)
        faults.broken = True
        for _ in range(30):
            core.submit(list(JOINTS), list(STAND))
            time.sleep(DT)
        assert not core.bus_ok
        before = sim.counters.targets
        faults.broken = False
        back = time.monotonic()
        while sim.counters.targets == before and time.monotonic() - back < 3.0:
            core.submit(list(JOINTS), list(STAND))
            time.sleep(DT)
        elapsed = time.monotonic() - back
        assert sim.counters.targets > before, "targets never reached the manager again"
        assert elapsed < 1.0, f"recovered after {elapsed:.3f} s"
        assert core.counters.bus_failures >= 1 and core.counters.reopens >= 1
    finally:
        core.close()
        sim.stop()
        sim_bus.shutdown()
        for bus in created:
            bus.shutdown()


def _garbage(proto: MotorProtocol) -> dict[str, can.Message]:
    good = proto.encode_feedback(proto.to_axis(STAND), 3)[0]
    bad_crc = bytearray(good.data)
    bad_crc[7] ^= 0x01
    message = proto.database.get_message_by_name("MM_Position_0")
    data = bytearray(message.encode({"Axis0_Position": 0.0, "Axis1_Position": 0.0,
                                     "Axis2_Position": 3.0, "Counter": 1, "Checksum": 0},
                                    strict=True))  # lf knee 3.0 rad: beyond limit + margin
    data[7] = crc8_sae_j1850(message.frame_id.to_bytes(2, "little") + bytes(data[:7]))
    fid = good.arbitration_id
    return {
        "unknown id": can.Message(arbitration_id=0x555, data=bytes(8), is_extended_id=False),
        "wrong dlc": can.Message(arbitration_id=fid, data=bytes(good.data[:7]),
                                 is_extended_id=False),
        "bad checksum": can.Message(arbitration_id=fid, data=bytes(bad_crc),
                                    is_extended_id=False),
        "out of range": can.Message(arbitration_id=message.frame_id, data=bytes(data),
                                    is_extended_id=False),
        "extended id": can.Message(arbitration_id=fid, data=good.data, is_extended_id=True),
        "remote frame": can.Message(arbitration_id=fid, is_remote_frame=True,
                                    is_extended_id=False, dlc=8),
        "error frame": can.Message(arbitration_id=fid, is_error_frame=True,
                                   is_extended_id=False),
    }


def test_garbage_frames_are_counted_and_never_published(proto):
    rig = Rig(proto, sim=False)
    try:
        garbage = _garbage(proto)
        for msg in garbage.values():
            rig.spy.send(msg)
        for group in proto.encode_feedback(proto.to_axis(STAND), 3)[1:]:
            rig.spy.send(group)  # three of the four good groups
        rig.core.poll()
        c = rig.core.counters
        assert c.rx_dropped == len(garbage) and c.rx == len(garbage) + 3
        assert rig.feedback == [] and c.feedback == 0
        assert np.isnan(rig.core.positions[:3]).all()  # group 0 only came as garbage
        assert rig.core.last_rx_error
    finally:
        rig.close()


def test_feedback_is_published_once_every_group_is_fresh(proto):
    rig = Rig(proto, sim=False)
    try:
        frames = proto.encode_feedback(proto.to_axis(STAND), 1)
        for msg in frames[:-1]:
            rig.spy.send(msg)
        rig.core.poll()
        assert rig.feedback == []
        rig.spy.send(frames[-1])
        rig.core.poll()
        assert len(rig.feedback) == 1
        np.testing.assert_allclose(rig.feedback[0], STAND, atol=RES)
        for msg in frames[:2]:  # half a cycle more: nothing new
            rig.spy.send(msg)
        rig.core.poll()
        assert len(rig.feedback) == 1
    finally:
        rig.close()


def test_own_loop_back_is_ignored_and_foreign_controller_frames_are_an_error(proto):
    rig = Rig(proto, sim=False)
    try:
        rig.core.activate()  # sends enable
        rig.spy.send(proto.encode_control("enable"))  # its loop-back (udp_multicast)
        rig.core.poll()
        c = rig.core.counters
        assert (c.rx_ignored, c.foreign_controls, c.rx_dropped) == (1, 0, 0)
        assert "foreign" not in rig.entry("motor manager").message
        rig.spy.send(proto.encode_control("hold"))  # another controller / an attacker
        for msg in proto.encode_targets(STAND, 1):
            rig.spy.send(msg)
        rig.core.poll()
        c = rig.core.counters
        assert (c.rx_ignored, c.foreign_controls, c.foreign_targets) == (1, 1, 4)
        entry = rig.entry("motor manager")
        assert entry.level == ERROR and "foreign target frame" in entry.message
        rig.clock.advance(2.1)  # the alarm holds the ERROR for ALARM_HOLD after the last one
        assert "foreign" not in rig.entry("motor manager").message
    finally:
        rig.close()


def test_conflicting_frames_with_one_counter_are_an_attack_not_a_stale_drop(proto):
    rig = Rig(proto, sim=False)
    try:
        genuine = proto.encode_feedback(proto.to_axis(STAND), 7)
        forged = proto.encode_feedback(proto.to_axis(STAND + 0.3), 7)
        for msg in [*genuine, genuine[0]]:  # an identical repeat: stale, dropped
            rig.spy.send(msg)
        rig.core.poll()
        assert rig.core.counters.rx_conflicts == 0 and rig.core.counters.rx_dropped == 1
        rig.spy.send(forged[0])  # the same counter, other data
        rig.core.poll()
        assert rig.core.counters.rx_conflicts == 1
        np.testing.assert_allclose(rig.core.positions, STAND, atol=1e-3)  # not taken
        assert "forged" in rig.entry("motor manager").message
    finally:
        rig.close()


def test_heartbeat_silence_is_an_error(rig):
    rig.core.activate()
    rig.run(0.3, STAND)
    entry = rig.entry("motor manager")
    assert entry.level == OK, entry.message
    assert dict(entry.values)["manager_state"] == "enabled"
    rig.sim.silence_heartbeat()
    rig.run(0.25, STAND)
    assert rig.entry("motor manager").level == OK  # within 3 periods of 0.1 s
    rig.run(0.1, STAND)
    entry = rig.entry("motor manager")
    assert entry.level == ERROR and "heartbeat missing" in entry.message


def stall(rig, seconds: float) -> None:
    """``seconds`` of the manager running while the driver's process does not (its frames
    queue on the bus)."""
    for _ in range(round(seconds / DT)):
        rig.sim.step(DT)
        rig.clock.advance(DT)


@pytest.mark.parametrize("stalled, level, text", [
    (0.29, OK, "enabled"),  # shorter than the heartbeat timeout: nothing to say
    (0.5, OK, "enabled"),  # the driver did not listen: the heartbeats are queued, not missing
    (0.99, OK, "enabled"),
    (1.01, ERROR, "CAN receiver stalled"),  # the driver itself is the fault
])
def test_a_stall_of_the_receiver_is_not_a_missing_heartbeat(rig, stalled, level, text):
    rig.core.activate()
    rig.run(0.3, STAND)
    assert rig.entry("motor manager").level == OK
    stall(rig, stalled)
    entry = rig.entry("motor manager")
    assert entry.level == level and text in entry.message, entry.message
    rig.run(0.05, STAND)  # listening again: the queued heartbeats arrive
    assert rig.entry("motor manager").level == OK


def test_silence_while_listening_is_missing_after_a_stall(rig):
    rig.core.activate()
    rig.run(0.3, STAND)
    rig.sim.silence_heartbeat()
    stall(rig, 0.5)  # a stall of the driver ...
    assert rig.entry("motor manager").level == OK
    rig.run(0.35, STAND)  # ... then listening, and no heartbeat comes
    entry = rig.entry("motor manager")
    assert entry.level == ERROR and "heartbeat missing" in entry.message, entry.message


@pytest.mark.parametrize("grace, waited, level", [
    (0.0, 0.29, WARN), (0.0, 0.31, ERROR),  # no grace: 3 heartbeat periods of 0.1 s
    (5.0, 0.31, WARN), (5.0, 4.99, WARN), (5.0, 5.01, ERROR),  # start-up grace
])
def test_no_heartbeat_at_all_is_an_error_after_the_startup_grace(proto, grace, waited, level):
    rig = Rig(proto, sim=False, heartbeat_startup_grace=grace)
    try:
        assert rig.entry("motor manager").level == WARN  # waiting, inactive
        rig.clock.advance(waited)
        entry = rig.entry("motor manager")
        assert entry.level == level, entry.message
        if level == ERROR:
            assert "no heartbeat" in entry.message
        else:
            assert "waiting for the first heartbeat" in entry.message
        assert all(e.level == STALE for e in rig.core.status() if e.name.startswith("axis"))
    finally:
        rig.close()


def test_an_axis_fault_bit_is_an_error(rig):
    rig.core.activate()
    rig.run(0.2, STAND)
    assert all(e.level == OK for e in rig.core.status())
    rig.sim.inject_axis_fault(4, "over_temp")
    rig.run(0.05)
    axis = rig.entry("axis 04")
    assert axis.level == ERROR and "over_temp" in axis.message
    assert dict(axis.values)["over_temp"] == "True"
    manager = rig.entry("motor manager")
    assert manager.level == ERROR and "lb_shoulder_joint" in manager.message
    assert rig.entry("axis 03").level != ERROR


def test_status_reports_counters_and_ages(rig):
    rig.core.activate()
    rig.run(0.1, STAND)
    rig.core.submit(["nope"], [0.0])
    status = rig.core.status()
    assert [e.name for e in status[:2]] == ["motor manager", "CAN bus"]
    assert len(status) == 2 + 12
    bus = dict(status[1].values)
    for key in ("tx", "rx", "tx_errors", "rx_dropped", "refused"):
        assert key in bus
    assert bus["refused"] == "1" and int(bus["tx"]) == 1 + 10 * 4
    manager = dict(status[0].values)
    assert float(manager["heartbeat_age"]) <= 0.1 + 1e-9
    assert float(manager["command_age"]) <= DT + 1e-9


def test_open_failure_raises_and_leaves_nothing_open(proto):
    def factory() -> can.BusABC:
        raise OSError("no such device: can7")

    core = DriverCore(proto, bus_factory=factory)
    with pytest.raises(DriverError, match="can7"):
        core.open()
    assert not core.is_open and not core.activate()[0]


def test_exactly_one_of_bus_and_factory(proto):
    with pytest.raises(ValueError, match="exactly one"):
        DriverCore(proto)


@pytest.mark.parametrize(("name", "value", "reason"), [
    ("on_timeout", "explode", "one of ['hold', 'disable']"),
    ("on_deactivate", "stop", "one of ['disable', 'hold']"),
    ("command_timeout", 0.0, "within [0.02, 10]"),
    ("command_timeout", math.nan, "finite"),
    ("send_retries", 11, "within [0, 10]"),
    ("send_retries", 1.5, "must be a int"),
    ("reopen_period", 2.0, "within [0.01, 1]"),
    ("autostart", 1, "must be a bool"),
    ("can_interface", "carrier_pigeon", "not a python-can interface"),
    ("can_channel", " ", "must not be empty"),
    ("dbc_file", "", "must not be empty"),
    ("heartbeat_timeout_periods", 0, "within [1, 100]"),
    ("heartbeat_startup_grace", -0.1, "within [0, 60]"),
    ("bogus", 1, "unknown parameter"),
])
def test_validator_refuses_with_a_reason(name, value, reason):
    reasons = validate_parameters(PARAMETERS, {name: value})
    assert len(reasons) == 1 and reason in reasons[0]


def test_validator_accepts_the_defaults():
    defaults = {p.name: p.default for p in PARAMETERS if p.name not in (
        "dbc_file", "axes_file", "config_file")}
    assert validate_parameters(PARAMETERS, defaults) == []
    assert validate_parameters(PARAMETERS, {"command_timeout": 1}) == []  # an int is a float
    with pytest.raises(ValueError, match="on_timeout"):
        DriverSettings(on_timeout="explode")


def test_bus_kwargs():
    assert bus_kwargs("udp_multicast", "239.1.2.3", 0) == {
        "interface": "udp_multicast", "channel": "239.1.2.3", "receive_own_messages": False}
    assert bus_kwargs("udp_multicast", "239.1.2.3", 5000)["port"] == 5000
    assert bus_kwargs("socketcan", "vcan0") == {"interface": "socketcan", "channel": "vcan0"}
    assert bus_kwargs("pcan", "PCAN_USBBUS1", bitrate=500000)["bitrate"] == 500000


class RaisingLogger:
    """A logger that fails on every call (rclpy's raises e.g. when a call site's level changes)."""

    def __init__(self) -> None:
        self.calls = 0

    def _fail(self, message: str) -> None:
        self.calls += 1
        raise ValueError("Logger severity cannot be changed between calls.")

    info = warning = error = _fail


def test_a_failing_logger_never_breaks_the_safety_path(proto):
    channel = f"drv-{uuid.uuid4().hex}"
    faults = Faults()
    logger = RaisingLogger()
    spy = can.Bus(interface="virtual", channel=channel)
    core = DriverCore(proto, bus_factory=lambda: FlakyBus(channel, faults), logger=logger,
                      settings=DriverSettings(command_timeout=0.1, send_retries=0))
    try:
        core.open()
        core.start()
        for frame in proto.encode_feedback(proto.to_axis(STAND), 1):  # a measured pose
            spy.send(frame)
        assert wait_for(lambda: np.all(np.isfinite(core.positions)), 2.0)
        assert core.activate()[0]
        faults.fail_sends = 10**6  # logs "not sent", then "bus down" from the executor side
        for _ in range(FAILED_FRAMES_BEFORE_REOPEN + 1):
            core.submit(list(JOINTS), list(STAND))
        faults.fail_sends = 0
        assert wait_for(lambda: core.bus_ok, 2.0)  # the thread reopened it (and logged)
        core.submit(list(JOINTS), list(STAND))
        assert wait_for(lambda: core.watchdog_tripped, 2.0)  # the thread is still alive
        assert core.estop("logger test")
        assert logger.calls >= 4
        assert core.running  # the thread is alive
    finally:
        core.close()
        spy.shutdown()


def wait_for(predicate, timeout: float) -> bool:
    """Poll ``predicate`` for up to WAIT_SLACK x ``timeout`` [s] of real time."""
    deadline = time.monotonic() + WAIT_SLACK * timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return bool(predicate())


def test_a_stalled_axis_is_an_error_until_it_moves_again(rig):
    """A stall (a leg blocked by a rock) pauses the gait like a fault bit; it clears by itself."""
    rig.core.activate()
    rig.run(0.2, STAND)
    rig.sim.stall_axis(4)
    rig.run(0.05, STAND)
    axis = rig.entry("axis 04")
    assert axis.level == ERROR and "stalled" in axis.message
    manager = rig.entry("motor manager")
    assert manager.level == ERROR and "stalled" in manager.message
    assert "lb_shoulder_joint" in manager.message
    rig.sim.stall_axis(4, stalled=False)
    rig.run(0.05, STAND)
    assert rig.entry("axis 04").level == OK and rig.entry("motor manager").level == OK


def test_a_repeated_feedback_counter_is_a_stale_frame(proto):
    """A position or status frame repeating its group's counter (a stuck sender, a replay)
    is dropped and counted, never published."""
    rig = Rig(proto, sim=False)
    try:
        first = proto.encode_feedback(proto.to_axis(STAND), 1)
        for msg in first:
            rig.spy.send(msg)
        rig.core.poll()
        assert len(rig.feedback) == 1
        moved = STAND.copy()
        moved[:3] += 0.2
        replay = proto.encode_feedback(proto.to_axis(moved), 1)  # same counter, new values
        for msg in replay:
            rig.spy.send(msg)
        status = proto.encode_status([AxisFlags(enabled=True)] * proto.n_axes, 5)
        for msg in status + status:  # the second copy repeats the counters
            rig.spy.send(msg)
        rig.core.poll()
        c = rig.core.counters
        assert c.rx_dropped == len(replay) + len(status)
        assert "repeated" in rig.core.last_rx_error
        assert len(rig.feedback) == 1
        for msg in proto.encode_feedback(proto.to_axis(moved), 2):  # the next counter: fine
            rig.spy.send(msg)
        rig.core.poll()
        assert len(rig.feedback) == 2
        np.testing.assert_allclose(rig.feedback[-1], moved, atol=RES)
    finally:
        rig.close()


def test_reset_without_enable_is_an_error(rig):
    """After ~/reset the motors stay disabled until ~/enable: an ERROR, so the planner keeps
    the gait paused instead of walking on while nothing moves."""
    rig.core.activate()
    rig.run(0.2, STAND)
    assert rig.core.estop("test")
    rig.run(0.1)
    assert rig.core.reset()[0]
    rig.run(0.1)
    manager = rig.entry("motor manager")
    assert manager.level == ERROR and "~/enable" in manager.message
    assert rig.core.enable()[0]
    rig.run(0.3, STAND)
    assert rig.entry("motor manager").level == OK, rig.entry("motor manager").message


def test_a_hold_the_driver_did_not_send_is_an_error_until_enable(rig, proto):
    rig.core.activate()
    rig.run(0.3, STAND)
    assert rig.entry("motor manager").level == OK
    rig.spy.send(proto.encode_control("hold"))  # spoofed: the manager obeys it
    rig.run(0.3, STAND)
    entry = rig.entry("motor manager")
    assert entry.level == ERROR and "hold, which the driver did not command" in entry.message
    assert rig.core.counters.foreign_controls == 1
    rig.clock.advance(2.1)  # the foreign-frame alarm is over; the manager is still in hold
    rig.run(0.2, STAND)
    assert "did not command" in rig.entry("motor manager").message
    epoch = rig.core.enable_epoch
    assert rig.core.enable()[0] and rig.core.enable_epoch == epoch + 1
    rig.run(0.3, STAND)
    assert rig.entry("motor manager").level == OK


def test_a_heartbeat_without_positions_is_an_error(rig):
    rig.core.activate()
    rig.run(0.3, STAND)
    for i in range(5):  # only heartbeats arrive (a frozen manager behind a forged heartbeat)
        rig.spy.send(rig.proto.encode_heartbeat("enabled", 100 + i))
        rig.clock.advance(0.1)
        rig.core.poll()
    entry = rig.entry("motor manager")
    assert entry.level == ERROR and "heartbeat without positions" in entry.message


def test_two_racing_publishers_are_refused(rig):
    rig.core.activate()
    rig.run(0.1)
    names = list(JOINTS)
    assert rig.core.submit(names, list(STAND), sequence=500).accepted
    assert rig.core.submit(names, list(STAND), sequence=501).accepted
    assert rig.core.submit(names, list(STAND), sequence=3).accepted  # a new publisher alone
    result = rig.core.submit(names, list(STAND), sequence=502)  # the first again: racing
    assert not result.accepted and "more than one publisher" in result.reason
    assert rig.core.counters.sender_conflicts == 1
    assert "more than one publisher" in rig.entry("motor manager").message
    rig.clock.advance(2.1)
    assert rig.core.submit(names, list(STAND), sequence=503).accepted


def test_a_heartbeat_whose_counter_does_not_advance_is_no_sign_of_life(rig):
    rig.core.activate()
    rig.run(0.3, STAND)
    rig.sim.silence_heartbeat()
    for _ in range(5):  # a replayed heartbeat: the same frame again and again
        rig.spy.send(rig.proto.encode_heartbeat("enabled", 7))
        rig.run(0.1, STAND)
    entry = rig.entry("motor manager")
    assert entry.level == ERROR and "heartbeat missing" in entry.message
    assert rig.core.counters.rx_dropped >= 4
