"""Two complete robots in one ROS domain: each a simulated manager on its own bus, a driver and
a planner under its own namespace (``--ros-args -r __ns:=/crawlerN``). They walk
independently, and no message of one reaches the other: not on the topics, not on the bus,
and not through the shared ``/diagnostics`` (a fault of one robot pauses that robot only)."""

from __future__ import annotations

import json
import os
import random
import signal
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from crawler_motion.canbus.protocol import MotorProtocol, TargetFrame  # noqa: E402
from crawler_motion.errors import ProtocolError  # noqa: E402
from crawler_motion.model.config import load_config  # noqa: E402
from crawler_motion.testing.bus import BusSpec, random_multicast_group  # noqa: E402
from crawler_motion.testing.stack import (  # noqa: E402
    SHORT_NAMES,
    StackProcesses,
    StackSpec,
    isolated_env,
)
from crawler_motion.testing.tap import BusTap, FrameRecorder  # noqa: E402
from crawler_motion.tools.console import Console  # noqa: E402

CFG = load_config()
PROTOCOL = MotorProtocol.from_config(CFG.robot)
NAMES = list(CFG.robot.joint_names)
WAIT = 30.0  # [s] generous bound of waits for a state (never a measured time)
#: The robots' own topics: every endpoint of each lies in that robot's namespace.
TOPICS = ("joint_commands", "joint_states", "planner_status", "driver_status", "gait_command",
          "cmd_vel")


@dataclass
class Robot:
    """One robot's processes (by their short names + its index), bus tap and observer."""

    ns: str
    bus: BusSpec
    console: Console
    tap: FrameRecorder
    listener: BusTap
    commands: list[np.ndarray] = field(default_factory=list)
    standing_from = 0  # index of the first command after the robot stood up
    stood = 0.0  # time.time() when it stood
    statuses: list[dict[str, Any]] = field(default_factory=list)

    def targets(self, after: float = 0.0) -> list[dict[str, float]]:
        """Joint positions of every target frame seen on this robot's bus after ``after``
        (kernel receive time, system clock [s])."""
        out = []
        for t, msg in self.tap.frames[:]:
            if t <= after:
                continue
            try:
                frame = PROTOCOL.decode(msg)
            except ProtocolError:
                continue
            if isinstance(frame, TargetFrame):
                out.append(dict(frame.positions))
        return out


@pytest.fixture()
def robots(tmp_path: Path) -> Iterator[tuple[list[Robot], StackProcesses]]:
    domain = random.randint(102, 200)
    procs = StackProcesses(tmp_path)
    rclpy.init(domain_id=domain)
    made: list[Robot] = []
    try:
        for i in (1, 2):
            ns = f"/crawler{i}"
            bus = BusSpec.fresh(channel=random_multicast_group())
            spec = StackSpec(bus, rate=100.0, remaps=(f"__ns:={ns}",),
                             names={k: f"{v}{i}" for k, v in SHORT_NAMES.items()})
            procs.start(spec.commands(), isolated_env(domain))
            tap = FrameRecorder()
            robot = Robot(ns, bus, Console(f"ns_console{i}", namespace=ns), tap,
                          BusTap(bus.open(), [tap]))
            robot.console.printer = lambda _line: None
            node = robot.console.node
            node.create_subscription(JointState, "joint_commands",
                                     lambda m, r=robot: r.commands.append(np.array(m.position)),
                                     100)
            node.create_subscription(String, "planner_status",
                                     lambda m, r=robot: r.statuses.append(json.loads(m.data)), 100)
            made.append(robot)
        yield made, procs
    finally:
        for robot in made:
            robot.console.close()
            robot.listener.stop()
        rclpy.try_shutdown()
        procs.stop()


def _spin(robots: list[Robot], seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        for robot in robots:
            robot.console.spin_for(0.01)


def _start_walk(console: Console, command: dict[str, Any]) -> None:
    """Send ``command`` until the planner walks. A loaded machine may starve a planner while
    it stands (its hold is interrupted, then resumed from the measured pose), and a walk sent
    during the resume is refused with "retry when it is done": it is sent again after it."""
    for _ in range(5):
        refusals = console.status.get("refusals", 0)
        console.send(command)
        assert console.wait_until(lambda n=refusals: console.status.get("state") == "WALKING"
                                  or console.status.get("refusals", 0) > n, WAIT), (
            f"the walk neither started nor was refused: {console.status}")
        if console.status.get("state") == "WALKING":
            return
        refusal = str(console.status.get("last_refusal"))
        assert "retry when it is done" in refusal, refusal
        assert console.wait_until(lambda: not console.status.get("resuming"), WAIT), (
            console.status)
    raise AssertionError(f"the walk was refused 5 times: {console.status}")


def _endpoints_outside(robot: Robot) -> list[str]:
    """Endpoints of the robot's topics whose node is not in the robot's namespace."""
    node, bad = robot.console.node, []
    for topic in TOPICS:
        name = f"{robot.ns}/{topic}"
        for info in (*node.get_publishers_info_by_topic(name),
                     *node.get_subscriptions_info_by_topic(name)):
            if info.node_namespace != robot.ns:
                bad.append(f"{name}: {info.node_namespace}/{info.node_name}")
    return bad


def test_two_robots_in_one_domain_walk_independently_and_nothing_crosses(robots) -> None:
    (one, two), procs = robots
    for robot in (one, two):
        assert robot.console.connect(WAIT), f"{robot.ns}: no planner\n{procs.log_tails(10)}"
    # robot 2 stands 1 cm lower: none of its joint targets is one of robot 1's
    for robot, height in ((one, CFG.robot.body_height), (two, CFG.robot.body_height - 0.01)):
        ok, message = robot.console.run_when_ready({"command": "stand", "body_height": height},
                                                   WAIT)
        assert ok, f"{robot.ns}: {message}\n{procs.log_tails(10)}"
        robot.console.spin_for(0.1)
        robot.standing_from, robot.stood = len(robot.commands), time.time()
    _start_walk(one.console, {"command": "walk", "steps": 2})
    # a fault of robot 2 (its manager frozen: the heartbeat stops) while robot 1 walks
    t_freeze = time.monotonic()
    sim2 = procs.pids()["sim2"]
    os.kill(sim2, signal.SIGSTOP)
    try:
        assert two.console.wait_until(lambda: bool(two.console.status.get("paused")), 5.0), (
            f"robot 2 did not pause: {two.console.status}")
    finally:
        os.kill(sim2, signal.SIGCONT)
    frozen = time.monotonic() - t_freeze
    assert one.console.wait_until(lambda: one.console.status.get("state") == "STANDING",
                                  WAIT), f"robot 1 did not finish its walk: {one.console.status}"
    assert two.console.wait_until(lambda: not two.console.status.get("paused"), WAIT)
    _spin([one, two], 0.3)

    walked = [s for s in one.statuses if s.get("state") == "WALKING"]
    print(f"\n[namespaces] robot 1 walked ({len(one.commands)} commands, "
          f"{len(one.targets())} target frames on its bus); robot 2 stood "
          f"({len(two.commands)} commands, {len(two.targets())} target frames); robot 2's "
          f"manager frozen {frozen:.2f} s paused robot 2 only")
    # a pause names the statuses that caused it: robot 2's (crawler2/driver: ...) never
    # reached robot 1 (a pause of robot 1's own, on a starved machine, would name crawler1)
    reasons1 = [str(s.get("pause_reason")) for s in one.statuses if s.get("paused")]
    reasons2 = [str(s.get("pause_reason")) for s in two.statuses if s.get("paused")]
    assert walked and not [r for r in reasons1 if "crawler2/" in r], reasons1
    assert any("crawler2/driver: motor manager" in r for r in reasons2), reasons2
    assert not any(s.get("state") == "WALKING" for s in two.statuses)
    # standing, robot 2 commanded one pose only, and its bus carried exactly that pose: none
    # of robot 1's walking targets; robot 1's bus never carried robot 2's pose
    pose2 = two.commands[-1]
    assert np.ptp(np.array(two.commands[two.standing_from:]), axis=0).max() < 1e-9
    assert np.ptp(np.array(one.commands[one.standing_from:]), axis=0).max() > 0.05
    tolerance = PROTOCOL.resolution_rad / 2 + 1e-9

    def is_pose2(positions: dict[str, float]) -> bool:
        idx = [NAMES.index(n) for n in positions]
        return bool(np.abs(pose2[idx] - np.array(list(positions.values()))).max() <= tolerance)

    on_two = two.targets(after=two.stood)
    assert len(on_two) > 50 and all(is_pose2(p) for p in on_two)
    on_one = one.targets(after=one.stood)
    assert len(on_one) > 50 and not any(is_pose2(p) for p in on_one)
    # on the graph, each robot's topics have endpoints in its own namespace only
    assert _endpoints_outside(one) == [] and _endpoints_outside(two) == []
