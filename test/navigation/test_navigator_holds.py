"""The navigator process against a scripted map, odometry and planner: a map stale in content
or another cmd_vel publisher holds the goal (zero twist, the reason in navigation_status, the
counters in /diagnostics) and it resumes when the cause is gone; a refusal of another
publisher's twist does not fail the goal."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

rclpy = pytest.importorskip("rclpy")

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PoseStamped, Twist  # noqa: E402
from nav_msgs.msg import OccupancyGrid, Odometry  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from sensor_msgs.msg import PointCloud2, PointField  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from crawler_motion.testing.stack import (  # noqa: E402
    StackProcesses,
    isolated_env,
    node_command,
    ros_args,
)

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class World:
    """Odometry at the origin and a free 2 m map at 10 Hz whose content stamp the test sets."""

    def __init__(self) -> None:
        self.node = rclpy.create_node("holds_world")
        n = self.node
        self.fresh = True  # map_load_time follows the clock
        self.mapper_alive = True  # maps published
        self.racing = False  # another publisher sends zero twists
        self.odom_alive = True  # odometry published
        self.load = Time()
        self.status: dict = {}
        self.twists: list[Twist] = []
        self.diagnostics: dict[str, dict[str, str]] = {}
        self._odom = n.create_publisher(Odometry, "odom", 10)
        self._map = n.create_publisher(OccupancyGrid, "terrain_map", 2)
        self.goal = n.create_publisher(PoseStamped, "goal_pose", 10)
        self.planner = n.create_publisher(String, "planner_status", LATCHED)
        # the planner's latched status before any refusal (the navigator's baseline)
        self.planner.publish(String(data=json.dumps({"refusals": 0, "last_refusal": ""})))
        n.create_subscription(String, "navigation_status", self._on_status, LATCHED)
        n.create_subscription(Twist, "cmd_vel", self.twists.append, 50)
        n.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 10)
        n.create_timer(0.1, self._tick)

    def _on_status(self, msg: String) -> None:
        self.status = json.loads(msg.data)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        for s in msg.status:
            self.diagnostics[s.name] = {kv.key: kv.value for kv in s.values}

    def _tick(self) -> None:
        now = self.node.get_clock().now().to_msg()
        odom = Odometry()
        odom.header.stamp, odom.header.frame_id = now, "odom"
        odom.pose.pose.orientation.w = 1.0
        if self.odom_alive:
            self._odom.publish(odom)
        if self.fresh:
            self.load = now
        if not self.mapper_alive:
            return
        grid = OccupancyGrid()
        grid.header.stamp, grid.header.frame_id = now, "odom"
        grid.info.resolution, grid.info.width, grid.info.height = 0.05, 40, 40
        grid.info.origin.position.x = grid.info.origin.position.y = -1.0
        grid.info.map_load_time = self.load
        grid.data = [0] * 1600
        self._map.publish(grid)

    def send_goal(self, x: float) -> None:
        msg = PoseStamped()
        msg.header.frame_id = "odom"
        msg.pose.position.x = x
        self.goal.publish(msg)

    def send_odom(self, x: float, ahead: float = 0.0) -> None:
        """One odometry sample at (x, 0), stamped ``ahead`` [s] after now."""
        odom = Odometry()
        stamp = self.node.get_clock().now().nanoseconds + int(ahead * 1e9)
        odom.header.stamp = Time(sec=stamp // 10 ** 9, nanosec=stamp % 10 ** 9)
        odom.header.frame_id = "odom"
        odom.pose.pose.position.x = x
        odom.pose.pose.orientation.w = 1.0
        self._odom.publish(odom)

    def spin_until(self, cond: Callable[[], bool], timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.05)
            if cond():
                return True
        return False

    def nav_twists(self) -> list[Twist]:
        return [t for t in self.twists if t.linear.x != 0.0 or not self.racing]

    def walking(self) -> bool:
        return bool(self.twists) and self.twists[-1].linear.x > 0.0

    def stopped(self) -> bool:
        return bool(self.twists) and self.twists[-1].linear.x == 0.0


@contextmanager
def walking_navigator(tmp_path: Path, domain: int, procs: StackProcesses | None = None,
                      **params: Any) -> Iterator[World]:
    """The navigator process (``params``) walking a goal 0.8 m ahead in the scripted world."""
    procs = procs or StackProcesses(tmp_path)
    procs.start({"navigator": [*node_command("navigator"), *ros_args(params)]},
                isolated_env(domain))
    world = World()
    try:
        assert world.spin_until(lambda: world.status.get("state") == "IDLE", 20.0), (
            procs.log_tails(20))
        # the goal is sent once: only after it matched the navigator's subscription (a
        # navigation_status heard says nothing of it; a sample sent before the match is lost)
        assert world.spin_until(lambda: world.goal.get_subscription_count() > 0, 10.0), (
            procs.log_tails(20))
        world.send_goal(0.8)
        assert world.spin_until(world.walking, 5.0), procs.log_tails(20)
        yield world
    finally:
        world.node.destroy_node()
        procs.stop()


def test_a_stale_map_or_another_cmd_vel_publisher_holds_the_goal(tmp_path: Path,
                                                                  ros_domain: int) -> None:
    procs = StackProcesses(tmp_path)
    with walking_navigator(tmp_path, ros_domain, procs, map_max_age=0.5,
                           timeout=60.0) as world:
        # the mapper stops fusing: maps keep coming with fresh stamps, the content ages
        world.fresh = False
        assert world.spin_until(lambda: "fresh map" in world.status.get("reason", ""), 3.0), (
            world.status)
        assert world.status["state"] == "ACTIVE" and world.spin_until(world.stopped, 1.0)
        held_at = len(world.twists)
        world.spin_until(lambda: False, 1.5)
        assert all(t.linear.x == 0.0 for t in world.twists[held_at - 1:])
        # one hold, logged once and counted once, though its reason's age grows every cycle
        assert procs.log_path("navigator").read_text().count("goal held: waiting for a "
                                                              "fresh map") == 1
        assert world.spin_until(lambda: world.diagnostics.get(
            "navigator: navigation", {}).get("holds_map", "0") == "1", 3.0), world.diagnostics
        world.fresh = True  # fusing again: the goal resumes from the measured pose
        assert world.spin_until(world.walking, 3.0), world.status
        assert world.spin_until(lambda: world.status["reason"] == "", 1.0), world.status
        # another node's publisher that sends nothing (an idle console) holds nothing
        other = world.node.create_publisher(Twist, "cmd_vel", 10)
        world.spin_until(lambda: False, 1.0)
        assert world.status["reason"] == "" and world.walking(), world.status
        # its zero twists at 50 Hz: held with the reason (no stop and start), named
        world.node.create_timer(0.02, lambda: other.publish(Twist()) if world.racing else None)
        world.racing = True
        assert world.spin_until(lambda: "another node steers" in world.status.get(
            "reason", ""), 3.0), world.status
        assert "/holds_world" in world.status["reason"]
        mark = len(world.nav_twists())
        world.spin_until(lambda: False, 1.5)
        assert all(t.linear.x == 0.0 for t in world.nav_twists()[mark:])  # no walk restarted
        world.racing = False  # the other node stops: the goal resumes
        assert world.spin_until(world.walking, 3.0), world.status
        # one 1e6 m/s twist of the other node: a hold of FOREIGN_HOLD, then the goal goes on
        fast = Twist()
        fast.linear.x = 1e6
        other.publish(fast)
        assert world.spin_until(lambda: "another node steers" in world.status.get(
            "reason", ""), 3.0), world.status
        assert world.spin_until(lambda: world.walking() and world.twists[-1].linear.x < 1.0,
                                3.0), world.status
        # the planner refuses a twist the navigator never sent: counted, the goal goes on
        world.planner.publish(String(data=json.dumps({
            "refusals": 1, "refused_twist": [1e6, 0.0, 0.0],
            "last_refusal": "cmd_vel speed 1e+06 m/s exceeds the maximum 0.06 m/s"})))
        assert world.spin_until(lambda: world.status.get("foreign_twists_refused") == 1, 3.0)
        assert world.status["state"] == "ACTIVE", world.status
        assert world.spin_until(world.walking, 3.0)


def test_a_dead_mapper_holds_the_goal_with_the_reason(tmp_path: Path, ros_domain: int) -> None:
    with walking_navigator(tmp_path, ros_domain, map_max_age=0.5) as world:
        world.mapper_alive = False  # no map at all any more
        assert world.spin_until(lambda: "fresh map" in world.status.get("reason", ""), 3.0), (
            world.status)
        assert world.spin_until(world.stopped, 1.0) and world.status["state"] == "ACTIVE"


def test_hostile_odometry_and_goal_floods_neither_kill_nor_flood(tmp_path: Path,
                                                                 ros_domain: int) -> None:
    procs = StackProcesses(tmp_path)
    with walking_navigator(tmp_path, ros_domain, procs, method="apf") as world:
        # the mapper's odometry rules: an absurd position (it crashed an apf goal's cycle),
        # a jump of 100 m and a future stamp are refused and counted; the walk goes on
        for x, ahead in ((1e300, 0.0), (100.0, 0.0), (0.0, 3600.0)):
            world.send_odom(x, ahead)
        assert world.spin_until(lambda: all(world.diagnostics.get(
            "navigator: navigation", {}).get(f"odom_{k}", "0") != "0"
            for k in ("BAD_POSE", "JUMP", "FUTURE")), 4.0), world.diagnostics
        # a terrain_heights cloud whose field lies beyond its point step (it killed the node)
        bad = PointCloud2(height=1, width=1, point_step=4, row_step=4, data=bytes(4))
        bad.fields = [PointField(name=n, offset=100, datatype=PointField.FLOAT32, count=1)
                      for n in ("x", "y", "z", "variance")]
        heights = world.node.create_publisher(PointCloud2, "terrain_heights", 2)
        # published once matched (a sample published before the match would be lost)
        assert world.spin_until(lambda: heights.get_subscription_count() > 0, 10.0)
        heights.publish(bad)
        assert world.spin_until(lambda: world.diagnostics.get("navigator: navigation", {}).get(
            "heights_refused") == "1", 3.0), world.diagnostics
        assert world.status["state"] == "ACTIVE" and world.spin_until(world.walking, 2.0)
        assert world.diagnostics["navigator: navigation"]["callback_errors"] == "0"
        # no odometry: held ("waiting for odometry"), and on again when it comes back
        world.odom_alive = False
        assert world.spin_until(lambda: world.status.get("reason") == "waiting for odometry",
                                3.0), world.status
        assert world.spin_until(world.stopped, 1.0)
        world.odom_alive = True
        assert world.spin_until(world.walking, 3.0), world.status
        # floods: 300 valid goals and 300 refused ones of different numbers
        statuses: list[int] = []
        world.node.create_subscription(String, "navigation_status",
                                       lambda _m: statuses.append(1), 1000)
        world.spin_until(lambda: False, 0.5)
        before = len(statuses)
        log = procs.log_path("navigator")
        lines = log.read_text().count("\n")
        start = time.monotonic()
        for k in range(300):
            world.send_goal(0.5 + k * 1e-4)
            world.send_goal(20.0 + k)  # beyond max_goal_distance: refused
        world.spin_until(lambda: False, 1.0)
        took = time.monotonic() - start
        sent = len(statuses) - before
        assert sent <= 2 + 2 * took / 0.1, (sent, took)  # at most every 0.1 s (+ 1 Hz)
        added = log.read_text().count("\n") - lines
        assert added <= 2 * (2 + took), log.read_text()[-2000:]  # once a second per kind
        assert not procs.died(), procs.log_tails(20)
        assert world.spin_until(lambda: world.status.get("state") == "ACTIVE", 2.0)
