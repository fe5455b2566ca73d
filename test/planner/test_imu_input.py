"""The planner's IMU input: the orientation read from sensor_msgs/Imu, and the node levelling
the body from it in the ``imu`` attitude mode (in-process, over real topics)."""

from __future__ import annotations

import contextlib
import json
import math
import re
import threading
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import String

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.model.rotations import matrix_quaternion, rpy_matrix
from crawler_motion.planner.imu_input import IMU_IDLE_PERIOD, IMU_TIMEOUT, imu_roll_pitch
from crawler_motion.planner.moves import sitting_pose
from crawler_motion.planner.node import PlannerNode
from crawler_motion.testing.polling import wait_until
from crawler_motion.tools.console import TRANSIENT_REFUSALS

CFG = load_config()
NAMES = list(CFG.robot.joint_names)
SIT = sitting_pose(CFG).reshape(-1)


def imu(roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> Imu:
    w, x, y, z = matrix_quaternion(rpy_matrix(np.array([roll, pitch, yaw])))
    msg = Imu()
    msg.orientation.w, msg.orientation.x, msg.orientation.y, msg.orientation.z = w, x, y, z
    return msg


@pytest.mark.parametrize(("roll", "pitch", "yaw"), [
    (0.0, 0.0, 0.0), (0.1, 0.0, 0.0), (0.0, -0.2, 0.0), (0.05, 0.08, 2.5),
    (-0.3, 0.3, -3.0), (0.0, 1.5, 0.0)])
def test_roll_and_pitch_of_the_orientation_whatever_the_yaw(roll, pitch, yaw):
    assert imu_roll_pitch(imu(roll, pitch, yaw)) == pytest.approx((roll, pitch), abs=1e-9)


@pytest.mark.parametrize("frame", ["", "base_link", "crawler1/base_link"])
def test_the_body_frame_and_a_nearly_unit_quaternion_are_taken(frame):
    msg = imu(0.1, -0.1)
    msg.header.frame_id = frame
    for name in "wxyz":
        setattr(msg.orientation, name, 1.005 * getattr(msg.orientation, name))
    assert imu_roll_pitch(msg) == pytest.approx((0.1, -0.1), abs=1e-9)


@pytest.mark.parametrize(("change", "fragment"), [
    (lambda m: m.orientation_covariance.__setitem__(0, -1.0), "has no orientation"),
    (lambda m: setattr(m.orientation, "w", 0.0), "has norm 0:"),
    (lambda m: setattr(m.orientation, "w", 3.0), "has norm 3:"),
    (lambda m: setattr(m.orientation, "w", 1.02), "has norm 1.02:"),
    (lambda m: setattr(m.orientation, "x", math.nan), "not finite"),
    (lambda m: setattr(m.orientation, "z", math.inf), "not finite"),
    (lambda m: setattr(m.header, "frame_id", "imu_link"), "frame 'imu_link'"),
    (lambda m: setattr(m.header, "frame_id", "base_link_2"), "publish it in 'base_link'"),
])
def test_an_orientation_that_cannot_be_used_is_refused_with_the_reason(change, fragment):
    msg = imu()
    change(msg)
    with pytest.raises(CommandError, match=re.escape(fragment)):
        imu_roll_pitch(msg)


class Probe(Node):
    """Publishes the measured joint states, an IMU reading ``roll`` while ``imu_on``, and
    records the planner's statuses."""

    def __init__(self, context: Context) -> None:
        super().__init__("imu_probe", context=context)
        self.gait_command = self.create_publisher(String, "gait_command", 10)
        self.joint_states = self.create_publisher(JointState, "joint_states", 10)
        self.imu = self.create_publisher(Imu, "imu", 10)
        self.imu_on, self.roll = True, 0.05
        self.statuses: list[dict] = []
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.create_subscription(String, "planner_status",
                                 lambda m: self.statuses.append(json.loads(m.data)), qos)
        self.create_timer(0.01, self._publish)

    def _publish(self) -> None:
        self.joint_states.publish(JointState(name=NAMES, position=[float(q) for q in SIT]))
        if self.imu_on:
            self.imu.publish(imu(self.roll))

    def last(self) -> dict:
        return self.statuses[-1] if self.statuses else {}

    def send_until_taken(self, text: str, state: str, attempts: int = 3) -> None:
        """Send a command until the planner reaches ``state`` with it; a refusal that clears
        by itself (a resume after a stalled tick on a loaded machine) is waited out and the
        command sent again (as test_node's `Probe.send_until_taken`)."""
        for _ in range(attempts):
            before = self.last().get("refusals", 0)
            self.gait_command.publish(String(data=text))
            assert wait_until(lambda n=before: self.last().get("state") == state
                              or self.last().get("refusals", 0) > n, 5.0), self.last()
            if self.last().get("state") == state:
                return
            status = self.last()
            assert any(word in status["last_refusal"] for word in TRANSIENT_REFUSALS), status
            assert wait_until(lambda: self.last()["state"] not in ("MOVING", "HOLDING")
                              and not self.last()["resuming"] and not self.last()["paused"],
                              5.0), self.last()
        raise AssertionError(f"{text} refused {attempts} times: {self.last()}")


@contextlib.contextmanager
def running(overrides: list[Parameter]) -> Iterator[tuple[PlannerNode, Probe]]:
    context = Context()
    rclpy.init(context=context)
    planner = PlannerNode(context=context, parameter_overrides=overrides)
    probe = Probe(context)
    executors = [SingleThreadedExecutor(context=context) for _ in range(2)]
    executors[0].add_node(planner)
    executors[1].add_node(probe)
    threads = [threading.Thread(target=ex.spin, daemon=True) for ex in executors]
    for thread in threads:
        thread.start()
    try:
        yield planner, probe
    finally:
        for ex in executors:
            ex.shutdown(timeout_sec=2.0)
        planner.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.fixture
def stack() -> Iterator[tuple[PlannerNode, Probe]]:
    with running([Parameter("foothold_adapt", value=True),
                  Parameter("attitude_mode", value="imu")]) as nodes:
        yield nodes


def test_without_the_imu_mode_a_sample_a_second_is_taken_and_all_of_them_with_it():
    with running([]) as (planner, _probe):
        time.sleep(2.5)  # 250 samples published
        idle = planner.imu.samples
        assert 1 <= idle <= 2.5 / IMU_IDLE_PERIOD + 1
        assert planner.set_parameters([Parameter("foothold_adapt", value=True),
                                       Parameter("attitude_mode", value="imu")])[0].successful
        time.sleep(1.0)
        assert planner.imu.samples - idle >= 50


def until(predicate: Callable[[], bool], timeout: float, what: str) -> None:
    assert wait_until(predicate, timeout), what


def test_the_imu_levels_the_walk_and_its_absence_is_reported(stack):
    planner, probe = stack
    until(lambda: probe.last().get("state") == "IDLE", 10.0, "planner up")
    for _ in range(50):  # refused until the first measured joint states arrive
        probe.gait_command.publish(String(data='{"command": "stand"}'))
        if wait_until(lambda: probe.last().get("state") == "STANDING", 0.2):
            break
    until(lambda: probe.last().get("state") == "STANDING", 10.0, "standing")
    probe.send_until_taken('{"command": "walk"}', "WALKING")  # a resume may refuse it
    # the body measured rolled left by 0.05 rad: the next slots roll it back (negative roll)
    until(lambda: planner.core.walk.foothold.pose.target[1] < -0.04, 10.0, "levelled")
    status = probe.last()["imu"]
    assert status["samples"] > 0 and status["refused"] == 0 and status["missing"] is False
    probe.imu_on = False
    until(lambda: probe.last()["imu"]["missing"] is True, 3.0 + IMU_TIMEOUT, "missing")
    bad = imu()
    bad.orientation_covariance[0] = -1.0
    probe.imu.publish(bad)
    until(lambda: probe.last()["imu"]["refused"] >= 1, 3.0, "refused")
