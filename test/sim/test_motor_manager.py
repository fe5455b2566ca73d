"""Tests of crawler_motion.sim.motor_manager on python-can buses (virtual and udp_multicast)."""

from __future__ import annotations

import signal
import time
import uuid
from pathlib import Path

import can
import numpy as np
import pytest

from crawler_motion.canbus.bus import open_bus
from crawler_motion.canbus.protocol import (
    AxisFlags,
    AxisStatus,
    EffortFeedback,
    Heartbeat,
    MotorProtocol,
    PositionFeedback,
)
from crawler_motion.errors import ProtocolError
from crawler_motion.model.config import joint_names, load_config
from crawler_motion.sim.manager_cli import main
from crawler_motion.sim.manager_loop import PeriodicSchedule
from crawler_motion.sim.motor_manager import MotorManagerSim
from crawler_motion.testing.bus import free_udp_port, random_multicast_group
from crawler_motion.testing.stack import manager_process

JOINTS = joint_names()
RES = 0.0001
DT = 0.01
SPEED = 1.0
TIMEOUT = 0.2
ROOT = Path(__file__).resolve().parents[2]

#: Real-time waits poll this many times longer than the nominal time: a loaded CI machine can
#: starve a process for a while. The timings themselves are measured (and reported) by the
#: fault-injection tests and the benchmarks, and asserted on fake clocks in the unit tests.
WAIT_SLACK = 3.0



@pytest.fixture(scope="module")
def proto():
    return MotorProtocol.from_config(load_config().robot)


class Rig:
    """The simulated manager and a controller on one in-process virtual bus."""

    def __init__(self, proto: MotorProtocol, **kwargs: object) -> None:
        channel = f"mm-{uuid.uuid4().hex}"
        self.proto = proto
        self.sim_bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        self.ctl = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        options = {"speed_limit": SPEED, "rate": 100.0, "heartbeat_period": 0.1,
                   "command_timeout": TIMEOUT}
        options.update(kwargs)
        self.sim = MotorManagerSim(self.sim_bus, proto, **options)
        self.counter = 0
        self.frames: list[object] = []

    def close(self) -> None:
        self.sim.stop()
        self.sim_bus.shutdown()
        self.ctl.shutdown()

    def send(self, msg: can.Message | list[can.Message]) -> None:
        for m in msg if isinstance(msg, list) else [msg]:
            self.ctl.send(m)

    def command(self, name: str) -> None:
        self.send(self.proto.encode_control(name))

    def targets(self, q: np.ndarray) -> None:
        self.counter += 1
        self.send(self.proto.encode_targets(q, self.counter))

    def run(self, seconds: float, q: np.ndarray | None = None) -> None:
        """Step the manager for ``seconds``, sending targets ``q`` before every step if given."""
        for _ in range(round(seconds / DT)):
            if q is not None:
                self.targets(q)
            self.sim.step(DT)
        self.collect()

    def collect(self) -> list[object]:
        new = []
        while (msg := self.ctl.recv(0.0)) is not None:
            new.append(self.proto.decode(msg))
        self.frames.extend(new)
        return new

    def of(self, kind: type) -> list:
        return [f for f in self.frames if isinstance(f, kind)]

    def last_positions(self) -> np.ndarray:
        latest: dict[str, float] = {}
        for frame in self.of(PositionFeedback):
            latest.update(frame.positions)
        return np.array([latest[j] for j in JOINTS])

    def last_flags(self) -> dict[str, AxisFlags]:
        latest: dict[str, AxisFlags] = {}
        for frame in self.of(AxisStatus):
            latest.update(frame.flags)
        return latest

    def last_state(self) -> str:
        return self.of(Heartbeat)[-1].state


@pytest.fixture
def rig(proto):
    r = Rig(proto)
    yield r
    r.close()


def valid_pose(proto: MotorProtocol) -> np.ndarray:
    """A pose inside every joint range and near zero."""
    return np.clip(np.zeros(12), proto.lower, proto.upper)


def test_starts_disabled_at_zero_and_reports_it(rig):
    rig.run(0.1)
    assert rig.sim.state == "disabled"
    assert rig.last_state() == "disabled"
    np.testing.assert_array_equal(rig.last_positions(), np.zeros(12))
    assert all(not f.enabled and not f.tracking for f in rig.last_flags().values())
    # 10 steps at 100 Hz: 10 x (4 effort + 4 position + 2 status) frames, heartbeats at
    # t = 0.01 and 0.1 s; no plant: the axes carry no load
    assert len(rig.of(EffortFeedback)) == 40
    assert all(v == 0.0 for f in rig.of(EffortFeedback) for v in f.efforts.values())
    assert len(rig.of(PositionFeedback)) == 40
    assert len(rig.of(AxisStatus)) == 20
    assert len(rig.of(Heartbeat)) == 2
    assert rig.sim.counters.sent == 102


def test_initial_pose_is_reported_in_joint_space(proto):
    q0 = valid_pose(proto)
    q0[JOINTS.index("rb_knee_joint")] = 1.2  # direction -1 axis
    rig = Rig(proto, initial_positions=q0)
    try:
        rig.run(0.02)
        np.testing.assert_allclose(rig.last_positions(), q0, atol=RES)
        assert rig.sim.positions[8] == pytest.approx(-1.2)
    finally:
        rig.close()


def test_enable_then_targets_converge_at_the_speed_limit(rig, proto):
    goal = valid_pose(proto)
    goal[JOINTS.index("lf_knee_joint")] = 0.8  # 0.8 rad away
    goal[JOINTS.index("rf_shoulder_joint")] = -0.3  # direction -1: axis +0.3
    goal[JOINTS.index("lb_root_joint")] = 0.05
    rig.command("enable")
    rig.run(0.5, goal)
    assert rig.sim.state == "enabled"
    pos = rig.last_positions()
    knee = JOINTS.index("lf_knee_joint")
    # after 0.5 s at 1 rad/s: 0.5 rad of travel, reported by the feedback sent after the step
    assert pos[knee] == pytest.approx(0.5, abs=RES)
    assert rig.sim.joint_positions[knee] == pytest.approx(0.5, abs=1e-9)
    assert pos[JOINTS.index("lb_root_joint")] == pytest.approx(0.05, abs=RES)
    assert pos[JOINTS.index("rf_shoulder_joint")] == pytest.approx(-0.3, abs=RES)
    steps = np.diff([f.positions["lf_knee_joint"] for f in rig.of(PositionFeedback)
                     if "lf_knee_joint" in f.positions])
    assert np.max(np.abs(steps)) <= SPEED * DT + 2 * RES
    rig.run(0.5, goal)
    np.testing.assert_allclose(rig.last_positions(), goal, atol=RES)
    flags = rig.last_flags()
    assert all(f.enabled and f.tracking and not f.command_timeout for f in flags.values())
    assert rig.last_state() == "enabled"
    assert rig.sim.counters.targets == 400


def test_targets_are_ignored_before_enable(rig, proto):
    goal = valid_pose(proto)
    goal[2] = 1.0
    rig.run(0.3, goal)
    np.testing.assert_array_equal(rig.sim.positions, np.zeros(12))
    assert rig.sim.counters.targets == 0
    assert rig.sim.counters.ignored >= 120
    rig.command("enable")
    rig.run(0.1, goal)
    assert rig.sim.joint_positions[2] == pytest.approx(0.1, abs=1e-9)


def test_estop_latches_until_reset(rig, proto):
    goal = valid_pose(proto)
    goal[2] = 1.0
    rig.command("enable")
    rig.run(0.2, goal)
    rig.command("estop")
    rig.run(0.2, goal)
    frozen = rig.sim.joint_positions[2]
    assert frozen == pytest.approx(0.2, abs=1e-9)
    assert rig.last_state() == "estop"
    assert not any(f.enabled for f in rig.last_flags().values())
    for command in ("enable", "hold", "disable"):  # all refused while latched
        rig.command(command)
        rig.run(0.1, goal)
        assert rig.sim.state == "estop"
    assert rig.sim.joint_positions[2] == frozen
    rig.command("reset")
    rig.run(0.1, goal)
    assert rig.last_state() == "disabled"
    assert rig.sim.joint_positions[2] == frozen
    rig.command("enable")
    rig.run(0.1, goal)
    assert rig.sim.joint_positions[2] == pytest.approx(frozen + 0.1, abs=1e-9)


def test_hold_and_disable_stop_following(rig, proto):
    goal = valid_pose(proto)
    goal[2] = 1.5
    rig.command("enable")
    rig.run(0.1, goal)
    rig.command("hold")
    rig.run(0.1, goal)
    assert rig.last_state() == "hold"
    flags = rig.last_flags()["lf_knee_joint"]
    assert flags.enabled and not flags.tracking
    assert rig.sim.joint_positions[2] == pytest.approx(0.1, abs=1e-9)
    rig.command("enable")
    rig.run(0.1, goal)
    assert rig.sim.joint_positions[2] == pytest.approx(0.2, abs=1e-9)
    rig.command("disable")
    rig.run(0.1, goal)
    assert rig.sim.state == "disabled"
    assert rig.sim.joint_positions[2] == pytest.approx(0.2, abs=1e-9)


def test_command_timeout_holds_and_reports(rig, proto):
    goal = valid_pose(proto)
    goal[2] = 1.5
    rig.command("enable")
    rig.run(0.1, goal)
    moved = rig.sim.joint_positions[2]
    rig.run(TIMEOUT - 0.05)  # silence shorter than the timeout: still tracking
    assert not rig.sim.command_timed_out
    assert rig.sim.joint_positions[2] > moved
    rig.run(0.1)  # now beyond the timeout
    assert rig.sim.command_timed_out
    held = rig.sim.joint_positions[2]
    rig.run(0.2)
    assert rig.sim.joint_positions[2] == held
    assert held < moved + TIMEOUT * SPEED + 1e-9
    flags = rig.last_flags()
    assert all(f.command_timeout and f.enabled and not f.tracking for f in flags.values())
    assert rig.last_state() == "enabled"
    rig.run(0.1, goal)  # fresh targets resume tracking and clear the bit
    assert not rig.sim.command_timed_out
    assert rig.sim.joint_positions[2] > held
    assert not any(f.command_timeout for f in rig.last_flags().values())


def test_stale_counter_does_not_feed_the_timeout(rig, proto):
    goal = valid_pose(proto)
    goal[2] = 1.5
    rig.command("enable")
    stale = proto.encode_targets(goal, 5)
    for _ in range(round(0.4 / DT)):
        rig.send(stale)
        rig.sim.step(DT)
    assert rig.sim.counters.targets == 4  # only the first copy was fresh
    assert rig.sim.counters.rejected == 4 * (round(0.4 / DT) - 1)
    assert "stale" in rig.sim.last_error
    assert rig.sim.command_timed_out


def test_stalled_axis_does_not_move_and_reports(rig, proto):
    goal = valid_pose(proto)
    goal[1] = 0.5
    goal[2] = 0.5
    rig.sim.stall_axis(1)
    rig.command("enable")
    rig.run(0.3, goal)
    assert rig.sim.joint_positions[1] == 0.0
    assert rig.sim.joint_positions[2] == pytest.approx(0.3, abs=1e-9)
    flags = rig.last_flags()
    assert flags["lf_shoulder_joint"].stalled and not flags["lf_shoulder_joint"].tracking
    assert not flags["lf_knee_joint"].stalled and flags["lf_knee_joint"].tracking
    rig.sim.stall_axis(1, False)
    rig.run(0.1, goal)
    assert rig.sim.joint_positions[1] == pytest.approx(0.1, abs=1e-9)
    assert not rig.last_flags()["lf_shoulder_joint"].stalled


def test_fault_latches_until_cleared_and_reset(rig, proto):
    goal = valid_pose(proto)
    goal[2] = 1.0
    rig.command("enable")
    rig.run(0.1, goal)
    rig.sim.inject_axis_fault(4, "over_temp")
    rig.run(0.2, goal)
    assert rig.last_state() == "fault"
    flags = rig.last_flags()
    assert flags["lb_shoulder_joint"].over_temp and flags["lb_shoulder_joint"].fault
    assert not flags["lb_knee_joint"].fault
    assert not any(f.enabled for f in flags.values())
    assert rig.sim.joint_positions[2] == pytest.approx(0.1, abs=1e-9)
    rig.command("reset")  # the condition is still there
    rig.run(0.1)
    assert rig.last_state() == "fault"
    rig.sim.clear_faults()
    rig.run(0.1)
    assert rig.last_state() == "fault"  # latched until reset
    assert rig.last_flags()["lb_shoulder_joint"].over_temp
    rig.command("reset")
    rig.run(0.1)
    assert rig.last_state() == "disabled"
    assert not any(f.fault for f in rig.last_flags().values())


@pytest.mark.parametrize(("kind", "attr"), [("over_current", "over_current"),
                                            ("encoder_fault", "encoder_fault")])
def test_fault_kinds_reach_their_bit(rig, kind, attr):
    rig.sim.inject_axis_fault(11, kind)
    rig.run(0.02)
    flags = rig.last_flags()["rf_knee_joint"]
    assert getattr(flags, attr)
    assert sum(f.fault for f in rig.last_flags().values()) == 1


def test_silent_heartbeat(rig):
    rig.run(0.15)
    assert len(rig.of(Heartbeat)) == 2
    rig.sim.silence_heartbeat(True)
    rig.frames.clear()
    rig.run(0.5)
    assert rig.of(Heartbeat) == []
    assert len(rig.of(PositionFeedback)) == 200
    rig.sim.silence_heartbeat(False)
    rig.run(0.3)
    assert len(rig.of(Heartbeat)) == 3


def test_garbage_frames_are_counted_not_fatal(rig, proto):
    garbage = [
        can.Message(arbitration_id=0x7FF, data=bytes(8), is_extended_id=False),
        can.Message(arbitration_id=0x100, data=bytes(3), is_extended_id=False),
        can.Message(arbitration_id=0x101, data=bytes.fromhex("0123456789abcdef"),
                    is_extended_id=False),
        can.Message(arbitration_id=0x080, data=bytes([1, 1]), is_extended_id=False),
        can.Message(arbitration_id=0x100, is_error_frame=True),
        can.Message(arbitration_id=0x1ABCDEF, data=bytes(8), is_extended_id=True),
    ]
    rig.send(garbage)
    rig.run(0.02)
    assert rig.sim.counters.rejected == len(garbage)
    assert rig.sim.counters.received == len(garbage)
    assert rig.sim.state == "disabled"  # the corrupted enable (bad complement) did nothing
    rig.command("enable")
    rig.run(0.02)
    assert rig.sim.state == "enabled"


def test_feedback_frames_on_the_bus_are_ignored(rig, proto):
    rig.send([*proto.encode_feedback(np.zeros(12), 0), proto.encode_heartbeat("estop", 0)])
    rig.run(0.01)
    assert rig.sim.counters.ignored == 5
    assert rig.sim.counters.rejected == 0
    assert rig.sim.state == "disabled"


def test_background_thread_runs_and_stops(rig, proto):
    goal = valid_pose(proto)
    goal[2] = 0.3
    rig.sim.start()
    assert rig.sim.running
    with pytest.raises(RuntimeError, match="background thread"):
        rig.sim.step(DT)
    with pytest.raises(RuntimeError, match="already running"):
        rig.sim.start()
    rig.send(can.Message(arbitration_id=0x100, data=b"\xff" * 8, is_extended_id=False))
    rig.command("enable")
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and rig.sim.joint_positions[2] < 0.3 - 1e-9:
        rig.targets(goal)
        time.sleep(0.01)
    assert rig.sim.joint_positions[2] == pytest.approx(0.3, abs=1e-9)
    assert rig.sim.time >= 0.3 / SPEED
    rig.sim.stop()
    assert not rig.sim.running
    counters = rig.sim.counters
    assert counters.rejected >= 1 and counters.targets > 0 and counters.sent > 0
    rig.collect()
    assert rig.last_state() == "enabled"
    time.sleep(0.05)
    assert rig.ctl.recv(0.0) is None  # nothing is sent after stop()


@pytest.mark.parametrize(("kwargs", "error", "pattern"), [
    ({"speed_limit": 0.0}, ValueError, "speed_limit"),
    ({"speed_limit": [1.0] * 11}, ValueError, "speed_limit"),
    ({"rate": 0.0}, ValueError, "rate"),
    ({"heartbeat_period": float("nan")}, ValueError, "heartbeat_period"),
    ({"command_timeout": -1.0}, ValueError, "command_timeout"),
    ({"initial_positions": [0.0] * 11 + [5.0]}, ProtocolError, "rf_knee_joint"),
    ({"initial_positions": [0.0] * 5}, ProtocolError, "12 values"),
])
def test_constructor_validates(proto, kwargs, error, pattern):
    bus = can.Bus(interface="virtual", channel=f"mm-{uuid.uuid4().hex}")
    try:
        with pytest.raises(error, match=pattern):
            MotorManagerSim(bus, proto, **kwargs)
    finally:
        bus.shutdown()


def test_fault_injection_validates(rig):
    with pytest.raises(ValueError, match="axis"):
        rig.sim.inject_axis_fault(12)
    with pytest.raises(ValueError, match="fault kind"):
        rig.sim.inject_axis_fault(0, "flood")
    with pytest.raises(ValueError, match="axis"):
        rig.sim.stall_axis(-1)


@pytest.mark.parametrize(("argv", "code", "pattern"), [
    (["--rate", "0"], 2, "--rate must be a finite number > 0"),
    (["--speed-limit", "nan"], 2, "--speed-limit must be"),
    (["--command-timeout", "-1"], 2, "--command-timeout must be"),
    (["--port", "70000"], 2, "--port must be"),
    (["--bogus"], 2, "unrecognized arguments: --bogus"),
    (["--config", "missing-robot.yaml"], 1, "cannot read config file"),
    (["--axes", "missing-axes.yaml"], 1, "cannot read axis map"),
    (["--interface", "virtual"], 1, "--channel is required"),
])
def test_main_rejects_bad_options_in_one_line(capsys, argv, code, pattern):
    try:
        result = main(argv)
    except SystemExit as exc:
        result = exc.code
    assert result == code
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("motor_manager_sim: error: ")
    assert pattern in err
    assert "Traceback" not in err


# ---- cross-process: the manager as a subprocess on udp_multicast ------------------------------



def _open_variant(variant: str) -> tuple[can.BusABC, list[str]]:
    """The controller's bus and the manager's bus options of a cross-process variant."""
    if variant == "socketcan":
        try:
            bus = open_bus("socketcan", "vcan0")
        except ValueError as exc:
            pytest.skip(f"no SocketCAN vcan0 on this machine ({exc}); create it with "
                        f"'ip link add dev vcan0 type vcan && ip link set up vcan0'")
        return bus, ["--interface", "socketcan", "--channel", "vcan0"]
    group = random_multicast_group()
    port = free_udp_port()  # unique per test: sockets bind the port, not the group
    try:
        bus = open_bus("udp_multicast", group, port)
    except (ValueError, RuntimeError) as exc:
        pytest.skip(f"udp_multicast cannot be opened on this machine: {exc}")
    return bus, ["--interface", "udp_multicast", "--channel", group, "--port", str(port)]


def _wait_for(bus: can.BusABC, proto: MotorProtocol, predicate, timeout: float):
    deadline = time.monotonic() + WAIT_SLACK * timeout
    while time.monotonic() < deadline:
        msg = bus.recv(0.05)
        if msg is None:
            continue
        frame = proto.decode(msg)
        if predicate(frame):
            return frame
    return None


@pytest.mark.parametrize("variant", ["udp_multicast", "socketcan"])
def test_subprocess_manager(proto, variant):
    bus, options = _open_variant(variant)
    proc = manager_process([*options, "--speed-limit", "2.0", "--command-timeout", "0.5"])
    try:
        beat = _wait_for(bus, proto, lambda f: isinstance(f, Heartbeat), 15.0)
        assert beat is not None, "no heartbeat from the manager subprocess"
        assert beat.state == "disabled"
        bus.send(proto.encode_control("enable"))
        assert _wait_for(bus, proto, lambda f: isinstance(f, Heartbeat)
                         and f.state == "enabled", 2.0) is not None
        goal = valid_pose(proto)
        goal[JOINTS.index("rb_knee_joint")] = 0.6  # direction -1 through the whole chain
        reached = None
        deadline = time.monotonic() + 5.0
        counter = 0
        while reached is None and time.monotonic() < deadline:
            counter += 1
            for msg in proto.encode_targets(goal, counter):
                bus.send(msg)
            reached = _wait_for(bus, proto, lambda f: isinstance(f, PositionFeedback)
                                and abs(f.positions.get("rb_knee_joint", 0.0) - 0.6) <= RES,
                                0.02)
        assert reached is not None, "the rb knee did not reach its target"
        bus.send(proto.encode_control("estop"))
        assert _wait_for(bus, proto, lambda f: isinstance(f, Heartbeat)
                         and f.state == "estop", 2.0) is not None
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
        assert proc.returncode == 0, err
        assert f"running on {variant}" in out and "stopped" in out
        assert "targets=" in out and "Traceback" not in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        bus.shutdown()



@pytest.mark.parametrize(("times", "due"), [
    ([0.0, 0.05, 0.1 - 1e-10, 0.15, 0.2], [True, False, True, False, True]),
    ([0.0, 0.35, 0.4, 0.45], [True, True, False, True]),  # behind at 0.35: next at 0.45, once
])
def test_periodic_schedule(times, due):
    schedule = PeriodicSchedule(0.1)
    assert [schedule.due(t) for t in times] == due
