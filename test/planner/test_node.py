"""The planner node in-process (launch-free): a probe node talks to it over real topics."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Twist
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import foot_jacobians
from crawler_motion.motion.gait import standing_pose
from crawler_motion.planner.moves import sitting_pose
from crawler_motion.planner.node import STATUS_MIN_INTERVAL, PlannerNode
from crawler_motion.tools.console import TRANSIENT_REFUSALS

CFG = load_config()
NAMES = list(CFG.robot.joint_names)
SIT = sitting_pose(CFG).reshape(-1)


class Probe(Node):
    """Publishes commands and a fake measured joint_states; records what the planner says."""

    def __init__(self, context: Context) -> None:
        super().__init__("planner_probe", context=context)
        self.cmd_vel = self.create_publisher(Twist, "cmd_vel", 10)
        self.gait_command = self.create_publisher(String, "gait_command", 10)
        self.joint_states = self.create_publisher(JointState, "joint_states", 10)
        self.diagnostics = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.commands: list[tuple[float, JointState]] = []
        self.statuses: list[dict] = []
        self.measured = SIT.copy()
        self.effort: np.ndarray | None = None  # joint order [N m]; None: joint_states without
        self.lock = threading.Lock()
        status_qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)  # keep every one
        self.create_subscription(JointState, "joint_commands", self._on_command, 100)
        self.create_subscription(String, "planner_status", self._on_status, status_qos)
        self.create_timer(0.02, self._publish_measured)

    def _on_command(self, msg: JointState) -> None:
        with self.lock:
            self.commands.append((time.monotonic(), msg))

    def _on_status(self, msg: String) -> None:
        with self.lock:
            self.statuses.append(json.loads(msg.data))

    def _publish_measured(self) -> None:
        order = list(reversed(range(12)))  # any order: the planner sorts by name
        msg = JointState(name=[NAMES[i] for i in order],
                         position=[float(self.measured[i]) for i in order],
                         effort=[] if self.effort is None else [float(self.effort[i])
                                                                for i in order])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.joint_states.publish(msg)

    def send(self, text: str) -> None:
        self.gait_command.publish(String(data=text))

    def twist(self, vx: float, vy: float = 0.0, wz: float = 0.0) -> None:
        msg = Twist()
        msg.linear.x, msg.linear.y, msg.angular.z = vx, vy, wz
        self.cmd_vel.publish(msg)

    def diagnose(self, level: bytes, hardware_id: str = "motor_manager",
                 message: str = "") -> None:
        status = DiagnosticStatus(level=level, name="motor_manager: axes",
                                  hardware_id=hardware_id, message=message)
        self.diagnostics.publish(DiagnosticArray(status=[status]))

    def last_status(self) -> dict:
        with self.lock:
            return self.statuses[-1] if self.statuses else {}

    def mark(self) -> int:
        """Index of the next status: wait only for statuses after an action."""
        with self.lock:
            return len(self.statuses)

    def wait_status(self, predicate: Callable[[dict], bool], timeout: float = 5.0,
                    since: int = 0) -> dict:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self.lock:
                found = [s for s in self.statuses[since:] if predicate(s)]
            if found:
                return found[-1]
            time.sleep(0.01)
        raise AssertionError(f"no such planner_status within {timeout} s; last: "
                             f"{self.last_status()}")

    def wait_state(self, state: str, since: int, timeout: float = 5.0) -> dict:
        return self.wait_status(lambda s: s["state"] == state, timeout, since)

    def send_until_taken(self, text: str, state: str, attempts: int = 3) -> tuple[dict, int]:
        """Send a command until the planner reaches ``state`` with it; a refusal that clears
        by itself (a resume after a stalled tick on a loaded machine) is waited out and the
        command sent again. Returns the status and how many such refusals there were."""
        for waited in range(attempts):
            before = self.last_status().get("refusals", 0)
            mark = self.mark()
            self.send(text)
            status = self.wait_status(
                lambda s, n=before: s["state"] == state or s["refusals"] > n, since=mark)
            if status["state"] == state:
                return status, waited
            assert any(word in status["last_refusal"] for word in TRANSIENT_REFUSALS), status
            self.wait_status(settled, since=mark)
        raise AssertionError(f"{text} refused {attempts} times: {self.last_status()}")

    def commands_between(self, t0: float, t1: float) -> list[JointState]:
        with self.lock:
            return [msg for t, msg in self.commands if t0 <= t <= t1]

    def clear(self) -> None:
        with self.lock:
            self.commands.clear()
            self.statuses.clear()


def settled(status: dict) -> bool:
    """No resume due or moving (its move is MOVING with ``resuming`` already false), no
    pause: a command refused for one of them may be sent again."""
    return (status["state"] not in ("MOVING", "HOLDING") and not status["resuming"]
            and not status["paused"])


class Ros:
    """One context; the planner spins in its own executor thread, the probe in another
    (the test thread calls the planner's set_parameters concurrently: the node's lock)."""

    def __init__(self, overrides: list[Parameter] | None = None) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.planner = PlannerNode(context=self.context, parameter_overrides=overrides or [])
        self.probe = Probe(self.context)
        # rclpy's MultiThreadedExecutor starves a 100 Hz timer in a mutually exclusive group
        # on a loaded machine (seen: 15-85 Hz); the node runs under rclpy.spin (single) anyway
        self.executors = [SingleThreadedExecutor(context=self.context),
                          SingleThreadedExecutor(context=self.context)]
        self.executors[0].add_node(self.planner)
        self.executors[1].add_node(self.probe)
        self.threads = [threading.Thread(target=ex.spin, daemon=True) for ex in self.executors]
        for thread in self.threads:
            thread.start()

    def close(self) -> None:
        for ex in self.executors:
            ex.shutdown(timeout_sec=2.0)
        self.planner.destroy_node()
        self.probe.destroy_node()
        rclpy.try_shutdown(context=self.context)
        for thread in self.threads:
            thread.join(timeout=2.0)

    def stand(self) -> None:
        """Measured joint_states flowing, then stand; returns once STANDING."""
        self.probe.wait_state("IDLE", 0)
        time.sleep(0.1)  # a few joint_states
        mark = self.probe.mark()
        self.probe.send('{"command": "stand"}')
        self.probe.wait_state("STANDING", mark)


@pytest.fixture
def ros() -> Iterator[Ros]:
    env = Ros([Parameter("cmd_vel_timeout", value=0.3)])
    try:
        yield env
    finally:
        env.close()


def rate_of(msgs: list[JointState]) -> float:
    """The publisher's rate [Hz] from the median period of its stamps (a loaded machine may
    starve the planner now and then: it then skips ticks, it does not change its rate)."""
    stamps = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in msgs])
    return 1.0 / float(np.median(np.diff(stamps)))


def test_idle_then_stand_publishes_joint_commands_at_the_rate(ros):
    probe = ros.probe
    status = probe.wait_state("IDLE", 0)
    assert status["paused"] is False and status["gait"] == "diagonal_zmp" and "time" in status
    assert isinstance(status["missed_ticks"], int)  # > 0 only if the process was starved
    # the probe is the one publisher of joint_states; a second one is counted and warned of
    assert probe.wait_status(lambda s: s["joint_states"]["publishers"] == 1, since=0)
    extra = probe.create_publisher(JointState, "joint_states", 10)
    try:
        assert probe.wait_status(lambda s: s["joint_states"]["publishers"] == 2, since=0)
    finally:
        probe.destroy_publisher(extra)
    time.sleep(0.3)
    assert probe.commands_between(0, time.monotonic()) == []  # IDLE publishes nothing
    mark = probe.mark()
    probe.send('{"command": "stand"}')
    probe.wait_status(lambda s: s["state"] == "MOVING" and s["target"] == "stand", since=mark)
    t0 = time.monotonic()
    time.sleep(1.6)
    msgs = probe.commands_between(t0 + 0.1, t0 + 1.6)
    assert len(msgs) > 100
    assert rate_of(msgs) == pytest.approx(100.0, rel=0.10)  # the publisher's stamps
    first = probe.commands_between(0, time.monotonic())[0]
    assert list(first.name) == NAMES
    np.testing.assert_allclose(first.position, SIT, atol=0.02)  # from the measured pose
    for msg in msgs:
        assert len(msg.position) == 12 and len(msg.velocity) == 12 and len(msg.effort) == 0
        assert msg.header.stamp.sec > 0
    probe.wait_state("STANDING", mark)
    time.sleep(0.1)
    last = probe.commands_between(0, time.monotonic())[-1]
    np.testing.assert_allclose(last.position, standing_pose(CFG).reshape(-1), atol=1e-9)
    np.testing.assert_array_equal(last.velocity, 0.0)


def test_bad_json_is_refused_with_the_reason_in_the_status(ros):
    probe = ros.probe
    probe.wait_state("IDLE", 0)
    probe.send("{oops")
    status = probe.wait_status(lambda s: s["refusals"] >= 1)
    assert "not valid JSON" in status["last_refusal"] and status["state"] == "IDLE"
    probe.send('{"command": "walk"}')
    status = probe.wait_status(lambda s: s["refusals"] >= 2)
    assert "walk refused in state IDLE: send stand first" in status["last_refusal"]


def test_parameter_sets_are_validated_by_the_node(ros):
    planner, probe = ros.planner, ros.probe
    probe.wait_state("IDLE", 0)
    # within every descriptor range, but lift + arc above the maximum clearance
    result = planner.set_parameters([Parameter("lift", value=0.035)])[0]
    assert not result.successful and "parameters refused" in result.reason
    assert "arc" in result.reason
    assert planner.get_parameter("lift").value == CFG.gait.lift
    status = probe.wait_status(lambda s: s["refusals"] >= 1)
    assert "parameters refused" in status["last_refusal"]
    result = planner.set_parameters([Parameter("stride", value=0.5)])[0]  # descriptor range
    assert not result.successful and result.reason
    result = planner.set_parameters([Parameter("gait", value="gallop")])[0]
    assert not result.successful and (
        "gait must be one of ['diagonal', 'diagonal_sway', 'diagonal_zmp', 'wave'], "
        "got 'gallop'" in result.reason)
    result = planner.set_parameters([Parameter("config_file", value="other.yaml")])[0]
    assert not result.successful  # read-only
    result = planner.set_parameters_atomically([Parameter("lift", value=0.02),
                                                Parameter("arc", value=0.015)])
    assert result.successful
    # the rate applies to the running timer
    assert planner.set_parameters([Parameter("rate", value=50.0)])[0].successful
    ros.stand()
    t0 = time.monotonic()
    time.sleep(1.2)
    msgs = probe.commands_between(t0 + 0.1, t0 + 1.2)
    assert rate_of(msgs) == pytest.approx(50.0, rel=0.10)


def test_walk_steps_and_status(ros):
    probe = ros.probe
    ros.stand()
    mark = probe.mark()
    status, waited = probe.send_until_taken('{"command": "walk", "steps": 1, "swing_time": 0.3}',
                                            "WALKING")
    assert (status["steps"], status["source"], status["gait"]) == (1, "command", "diagonal_zmp")
    status = probe.wait_status(lambda s: s["state"] == "STANDING" and s["step"] == 1, since=mark)
    assert (status["step"], status["steps"], status["refusals"]) == (1, 1, waited)


def test_motor_manager_fault_pauses(ros):
    probe = ros.probe
    probe.wait_state("IDLE", 0)
    probe.diagnose(DiagnosticStatus.ERROR, hardware_id="some_other_board")
    probe.diagnose(DiagnosticStatus.ERROR, message="axis 4 overcurrent")
    status = probe.wait_status(lambda s: s["paused"])
    assert "axis 4 overcurrent" in status["pause_reason"]
    probe.diagnose(DiagnosticStatus.STALE)  # no information: still paused
    time.sleep(0.2)
    assert probe.last_status()["paused"]
    probe.diagnose(DiagnosticStatus.WARN)
    probe.wait_status(lambda s: not s["paused"] and s["revision"] > status["revision"])


def test_cmd_vel_walk_times_out_and_estop_stops_the_output(ros):
    probe = ros.probe
    ros.stand()
    mark = probe.mark()
    end = time.monotonic() + 5.0
    while probe.last_status()["state"] != "WALKING" and time.monotonic() < end:
        probe.twist(0.05, 0.0, 0.1)  # until the walk has started, then no more twists
        time.sleep(0.05)
    status = probe.wait_state("WALKING", mark)
    assert status["source"] == "cmd_vel" and status["steps"] is None
    probe.wait_state("STOPPING", mark, timeout=3.0)  # no twists: timeout 0.3 s
    with probe.lock:
        events = [s["last_event"] or "" for s in probe.statuses[mark:]]
    assert any("cmd_vel timeout" in e for e in events), events
    mark = probe.mark()
    probe.wait_state("STANDING", mark, timeout=3.0)
    probe.twist(0.5)  # beyond the speed limit
    status = probe.wait_status(lambda s: s["refusals"] >= 1, since=mark)
    assert "exceeds the maximum" in status["last_refusal"] and status["state"] == "STANDING"
    mark = probe.mark()
    probe.send('{"command": "estop"}')
    probe.wait_state("ESTOP", mark)
    time.sleep(0.1)
    t0 = time.monotonic()
    time.sleep(0.4)
    assert probe.commands_between(t0, time.monotonic()) == []


@pytest.mark.parametrize(("param", "fragment"), [("lift:=0.035", "arc"),
                                                  ("tick_priority:=100", "tick_priority")])
def test_main_refuses_invalid_parameters_and_exits_1(param, fragment):
    proc = subprocess.run(
        [sys.executable, "-m", "crawler_motion.planner.node", "--ros-args", "-p", param],
        capture_output=True, text=True, timeout=20)
    assert proc.returncode == 1
    assert "planner cannot start" in proc.stderr + proc.stdout
    assert fragment in proc.stderr + proc.stdout


def test_calibration_file_gives_the_planner_its_legs(tmp_path):
    from crawler_motion.calibration.synthetic import perturbed_robot
    from crawler_motion.model.calibration_file import write_calibration
    from crawler_motion.model.config import load_config

    true = perturbed_robot(load_config().robot, 3)
    write_calibration(tmp_path / "legs.yaml", true.geometry)
    env = Ros([Parameter("calibration_file", value=str(tmp_path / "legs.yaml"))])
    try:
        assert env.planner.cfg.robot.calibrated
        np.testing.assert_array_equal(env.planner.cfg.robot.geometry.params,
                                      true.geometry.params)
        result = env.planner.set_parameters([Parameter("calibration_file", value="")])[0]
        assert not result.successful  # read-only
    finally:
        env.close()


def test_main_refuses_an_implausible_calibration_file(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("calibration: {legs: {rf: {knee_offset: 0.2}}}")  # 11.5 deg
    proc = subprocess.run(
        [sys.executable, "-m", "crawler_motion.planner.node", "--ros-args", "-p",
         f"calibration_file:={bad}"], capture_output=True, text=True, timeout=20)
    assert proc.returncode == 1
    assert "beyond ±10 deg" in proc.stderr + proc.stdout


def test_a_flood_of_bad_commands_is_counted_not_republished_one_by_one(ros):
    probe = ros.probe
    probe.wait_state("IDLE", 0)
    mark = probe.mark()
    before = probe.last_status().get("refusals", 0)
    n = 300
    t0 = time.monotonic()
    for _ in range(n):
        probe.send("{oops")
        time.sleep(0.002)  # the subscription keeps 10: a faster flood is dropped by DDS
    time.sleep(0.5)  # the last refusals reach the status
    elapsed = time.monotonic() - t0
    status = probe.last_status()
    refused = status["refusals"] - before
    published = len(probe.statuses) - mark
    # one status per STATUS_MIN_INTERVAL at most (+ the periodic one), not one per refusal
    assert refused > 100 and published <= elapsed / STATUS_MIN_INTERVAL + 3, (
        refused, published, elapsed)
    assert "not valid JSON" in status["last_refusal"]


def test_driver_status_ends_a_walk_and_bad_text_is_ignored(ros):
    probe = ros.probe
    pub = probe.create_publisher(String, "driver_status", QoSProfile(  # as the driver's
        depth=1, reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL))
    probe.wait_state("IDLE", 0)
    deadline = time.monotonic() + 5.0
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    pub.publish(String(data='{"state": "flying"}'))  # ignored with a warning
    enabled = String(data=json.dumps({"state": "enabled", "enable_epoch": 1}))
    for _ in range(50):
        pub.publish(enabled)
        if probe.last_status().get("driver") == "enabled":
            break
        time.sleep(0.1)
    probe.wait_status(lambda s: s["driver"] == "enabled")
    mark = probe.mark()
    probe.send('{"command": "stand"}')
    probe.wait_state("STANDING", mark)
    mark = probe.mark()
    pub.publish(String(data=json.dumps({"state": "estop", "enable_epoch": 1,
                                        "reason": "~/estop service"})))
    status = probe.wait_state("IDLE", mark)
    assert "ended" in status["last_event"] and status["driver"] == "estop"


def test_foot_contacts_are_unknown_without_efforts_and_estimated_with_them(ros):
    """joint_states without efforts: every foot unknown on foot_contacts and in the status, the
    planner's foot contacts status at WARN; with efforts holding 2 N on each foot: contact."""
    probe = ros.probe
    contacts: list[dict] = []
    statuses: list[DiagnosticStatus] = []
    probe.create_subscription(String, "foot_contacts",
                              lambda m: contacts.append(json.loads(m.data)), 10)
    probe.create_subscription(DiagnosticArray, "/diagnostics", lambda m: statuses.extend(
        s for s in m.status if s.hardware_id == "crawler_planner"), 10)

    def seen(predicate: Callable[[], bool], timeout: float = 5.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end and not predicate():
            time.sleep(0.02)
        return predicate()

    assert seen(lambda: any(s.level == DiagnosticStatus.WARN for s in statuses))
    warn = next(s for s in statuses if s.level == DiagnosticStatus.WARN)
    assert warn.name == "planner: foot contacts" and "no effort" in warn.message
    assert seen(lambda: bool(contacts))
    last = contacts[-1]
    assert last["effort"] is False and "no effort" in last["reason"]
    assert {f["contact"] for f in last["feet"].values()} == {"unknown"}
    assert all(f["force"] is None for f in last["feet"].values())
    status = probe.wait_status(lambda s: s["contacts"]["effort"] is False)
    assert set(status["contacts"]["feet"]) == {"lf", "lb", "rb", "rf"}
    force = np.zeros((4, 3))
    force[:, 2] = 2.0
    jac = foot_jacobians(CFG.robot, SIT.reshape(4, 3))
    probe.effort = -np.einsum("lji,lj->li", jac, force).reshape(-1)
    assert seen(lambda: contacts[-1]["effort"] and {
        f["contact"] for f in contacts[-1]["feet"].values()} == {"yes"})
    assert all(f["force"] == pytest.approx(2.0, abs=0.01)
               for f in contacts[-1]["feet"].values())
    assert seen(lambda: statuses[-1].level == DiagnosticStatus.OK)
    probe.wait_status(lambda s: s["contacts"]["feet"]["lf"]["contact"] == "yes")


@pytest.mark.parametrize(("namespace", "names", "faulted"), [
    ("/", ["driver: motor manager"], True),
    ("/crawler1", ["crawler1/driver: motor manager"], True),
    ("/crawler1", ["crawler2/driver: motor manager"], False),  # another robot's fault
    ("/", ["crawler2/driver: motor manager"], False),
    ("/crawler1", ["crawler2/driver: x", "crawler1/driver: y"], True),
    ("/crawler1", ["motor_manager/axes"], True),  # cannot be placed: taken as ours
])
def test_fault_levels_pause_on_their_own_robots_statuses_only(namespace, names, faulted):
    from crawler_motion.planner.node import FaultLevels

    statuses = [DiagnosticStatus(level=DiagnosticStatus.ERROR, name=name, message="bad",
                                 hardware_id="motor_manager") for name in names]
    assert FaultLevels().update(statuses, "motor_manager", namespace)[0] is faulted


@pytest.mark.parametrize("mode", ["off", "imu", "stance_plane"])
def test_a_documented_choice_is_accepted_from_the_command_line(mode, tmp_path):
    """``-p attitude_mode:=off``: YAML reads off as false; the planner takes it as "off"."""
    log = tmp_path / "planner.log"
    with open(log, "w") as out:
        proc = subprocess.Popen(
            [sys.executable, "-m", "crawler_motion.planner.node", "--ros-args", "-p",
             "foothold_adapt:=true", "-p", f"attitude_mode:={mode}", "-p", "tick_priority:=0"],
            stdout=out, stderr=subprocess.STDOUT, text=True)
    try:
        end = time.monotonic() + 20.0
        while time.monotonic() < end and proc.poll() is None and "planner ready" not in (
                log.read_text()):
            time.sleep(0.1)
        assert proc.poll() is None and "planner ready" in log.read_text(), log.read_text()
    finally:
        proc.kill()
        proc.wait()
