"""The ``navigator`` ROS node: goal in, ``cmd_vel`` out, around the mapped obstacles.

Subscribes ``goal_pose`` (geometry_msgs/PoseStamped in the map frame), ``terrain_map``
(nav_msgs/OccupancyGrid) and ``terrain_heights`` (sensor_msgs/PointCloud2 x y z variance) of
``terrain_mapper``, ``odom``, ``joint_states``, ``planner_status`` (a twist the planner refuses
as beyond its walk's limits fails the goal with its reason: `planner_watch`) and, for method
``apf``, ``follow_command`` (std_msgs/String JSON ``{"length": L, "side": "right"|"left"}``:
walk L m along the nearest structure at the stand-off distance); serves ``~/cancel``
(std_srvs/Trigger).
On every map it runs one cycle of the method (parameter ``method``; `methods.METHODS`) and
publishes the twist on ``cmd_vel``. Publishes ``navigation_status`` (std_msgs/String JSON,
transient local) on every change and once a second. Leaving ACTIVE (arrived, failed,
cancelled) sends a zero twist: the planner stops the walk into standing. A goal in another
frame or not finite is refused (counted, logged, in the status) and changes nothing. Until
joint_states arrive the virtual radius is the envelope radius; ``odom`` and ``joint_states``
are taken by threads of their own (`body_inputs.BodyInputs`), not through the executor.

An ACTIVE goal is *held* (a zero twist: the robot stands; the reason in the status; checked on
every map and every `WATCH_PERIOD`) while the odometry is older than ``odom_timeout``, while
the map's content (its last fused scan, ``map_load_time``: `guards.MapFreshness`) is older
than ``map_max_age``, or while another node steers: a ``cmd_vel`` twist the navigator did
not send (it listens to its own topic) was seen within `FOREIGN_HOLD` (the reason names the
topic's other publishers from the graph; a publisher that sends nothing, such as an idle
console, holds nothing). It resumes by itself when the cause is gone: every cycle plans from
the measured pose on the map of that moment, as at the start of a goal (the goal's
``timeout`` keeps running). A planner refusal of a twist the
navigator did not send is counted, not blamed on the goal (`planner_watch`). Counters
(refusals, holds by cause, foreign twists) go to ``/diagnostics`` once a second (status
``navigator: navigation``, hardware_id ``crawler_navigator``).
"""

from __future__ import annotations

import json
import time
from collections import Counter
from collections.abc import Sequence
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, Twist, Vector3
from nav_msgs.msg import OccupancyGrid
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import String
from std_srvs.srv import Trigger

from crawler_motion.errors import CommandError
from crawler_motion.mapping.clouds import read_float32
from crawler_motion.model.config import load_config
from crawler_motion.navigation.apf_navigator import ApfNavigator, FollowCommand
from crawler_motion.navigation.body_inputs import BodyInputs
from crawler_motion.navigation.command_log import CommandLog
from crawler_motion.navigation.guards import (
    MapFreshness,
    SentTwists,
    foreign_publishers,
    foreign_reason,
)
from crawler_motion.navigation.methods import make_navigator
from crawler_motion.navigation.mission_topics import MissionTopics
from crawler_motion.navigation.navigator import Method, NavState, Output, goal_error
from crawler_motion.navigation.parameters import NAVIGATOR_PARAMETERS, navigator_settings
from crawler_motion.navigation.planner_watch import RefusalWatch
from crawler_motion.navigation.view import view_from_grid
from crawler_motion.runtime.callback_guard import CallbackGuard
from crawler_motion.runtime.ros_diagnostics import counters_array
from crawler_motion.runtime.ros_main import run_node
from crawler_motion.runtime.ros_parameters import descriptor, parameter_values

NAME = "navigator"
STATUS_PERIOD = 1.0  # [s]
#: Refusals publish ``navigation_status`` at most this often [s] (as the planner's do).
REFUSAL_STATUS_PERIOD = 0.1
#: Period of the hold checks (map age, odometry age, cmd_vel publishers) [s].
WATCH_PERIOD = 0.1
#: A goal is held this long after a cmd_vel twist the navigator did not send [s].
FOREIGN_HOLD = 1.0
#: Period of the ``/diagnostics`` status [s].
DIAGNOSTICS_PERIOD = 1.0
HARDWARE_ID = "crawler_navigator"


def read_heights(msg: PointCloud2) -> np.ndarray | None:
    """``(k, 4)`` x y z variance of a terrain_heights cloud; None when it lacks the fields or
    they do not fit the cloud (`mapping.clouds.read_float32`)."""
    return read_float32(msg, ("x", "y", "z", "variance"))


class NavigatorNode(Node):
    """Subscriptions and publishers around one navigator core; ``kwargs`` go to
    `rclpy.node.Node` (context, parameter overrides)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NAME, **kwargs)
        for spec in NAVIGATOR_PARAMETERS:
            self.declare_parameter(spec.name, spec.default, descriptor(spec))
        values = parameter_values(self, NAVIGATOR_PARAMETERS)
        settings = navigator_settings(values)
        self.cfg = load_config(values["config_file"] or None)
        self.nav = make_navigator(Method(values["method"]), settings)
        self.frame, self.odom_timeout, self.map_max_age = (
            values["map_frame"], values["odom_timeout"], values["map_max_age"])
        self.freshness, self.sent = MapFreshness(), SentTwists()
        self.holds: Counter[str] = Counter()  # holds by cause
        self._held_cause: str | None = None  # of the hold in force (logged once)
        # steady time of the last cmd_vel twist of another node [s], and how many were seen
        self._foreign_at, self.foreign_twists = -float("inf"), 0
        self._heights: np.ndarray | None = None
        self.heights_refused = 0  # terrain_heights clouds whose fields do not fit them
        self._last_status = ""
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._cmd = self.create_publisher(Twist, "cmd_vel", 10)
        self._status = self.create_publisher(String, "navigation_status", latched)
        self.guard = CallbackGuard(self.get_logger(), alive=self.context.ok)
        self._planner = RefusalWatch()
        self.commands = CommandLog(self.get_logger(), REFUSAL_STATUS_PERIOD)
        for kind, topic, callback, qos in (
                (PoseStamped, "goal_pose", self._on_goal, 10),
                (String, "follow_command", self._on_follow, 10),
                (OccupancyGrid, "terrain_map", self._on_map, 2),
                (PointCloud2, "terrain_heights", self._on_heights, 2),
                (String, "planner_status", self._on_planner_status, latched),
                (Twist, "cmd_vel", self._on_cmd_vel, 50)):
            on_error = self._fail_all if topic == "terrain_map" else None
            self.create_subscription(kind, topic, self.guard.wrap(topic, callback, on_error),
                                     qos)
        self.body = BodyInputs(self, self.cfg.robot, self.guard.wrap,
                               lambda: self.get_clock().now().nanoseconds * 1e-9)
        self.odom = self.body.odom
        self.body.start()
        self.create_service(Trigger, "~/cancel", self._on_cancel)
        self.missions = MissionTopics(self, self.nav, self.cfg.tool_width, lambda: self.odom.pose,
                                      self._refuse, self._planner.start)
        self.create_timer(STATUS_PERIOD, lambda: self._publish_status(force=True))
        self._diagnostics = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(WATCH_PERIOD, self._watch)
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        self._publish_status(force=True)

    def _refuse(self, why: str) -> None:
        """Count and log a refusal (`CommandLog`); the status at most every 0.1 s."""
        if self.commands.refused(why):
            self._publish_status(force=True)

    def _on_goal(self, msg: PoseStamped) -> None:
        if msg.header.frame_id != self.frame:
            self._refuse(f"goal in frame '{msg.header.frame_id}'; send it in '{self.frame}'")
            return
        x, y = msg.pose.position.x, msg.pose.position.y
        why = goal_error(x, y, None if self.odom.pose is None else self.odom.pose[:2],
                         self.nav.settings.max_goal_distance)
        if why is not None:
            self._refuse(why)
            return
        try:
            self.missions.cancel("replaced by a goal")
            self.nav.set_goal(x, y, time.monotonic())
        except CommandError as exc:
            self._refuse(str(exc))
            return
        self._accepted("goal", f"goal ({x:.3f}, {y:.3f})")

    def _on_follow(self, msg: String) -> None:
        if not isinstance(self.nav, ApfNavigator):
            self._refuse("following a structure needs method apf")
            return
        try:
            command = FollowCommand.from_json(msg.data)
        except CommandError as exc:
            self._refuse(str(exc))
            return
        self.missions.cancel("replaced by a follow command")
        self.nav.set_follow(command, time.monotonic())
        self._accepted("follow", f"follow {command.length:.3f} m, structure "
                       f"{command.side.value}")

    def _accepted(self, kind: str, text: str) -> None:
        self._planner.start()
        if self.commands.taken(kind, text):
            self._publish_status()

    @property
    def _nav(self) -> Any:
        """The navigator steering now: the mission's while one runs."""
        return self.missions.nav if self.missions.running else self.nav

    def _on_planner_status(self, msg: String) -> None:
        reason = self._planner.update(msg.data, self.sent)
        if reason is not None and self._nav.fail(reason):
            self._stop()
            self.get_logger().error(f"goal failed: {reason}")
        self._publish_status()  # a foreign twist counted changes it too

    def _fail_all(self, why: str) -> None:
        """A map cycle raised (a defect the guard caught): fail the goal and the mission, stop."""
        self.missions.cancel(f"navigator error: {why}")
        self._nav.fail(f"navigator error: {why}")  # an ACTIVE goal only
        self._stop()
        self._publish_status(force=True)

    def destroy_node(self) -> None:
        """Stop the reader threads, then the node."""
        self.body.close()
        super().destroy_node()

    def _on_heights(self, msg: PointCloud2) -> None:
        """The newest heights; a malformed cloud leaves none (counted in the diagnostics)."""
        self._heights = read_heights(msg)
        self.heights_refused += self._heights is None

    def _on_cancel(self, _req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        nav, mission = self._nav, self.missions.running
        self.missions.cancel()
        if nav.cancel() or mission:
            self._stop()
        resp.success, resp.message = True, "cancelled; the robot stands"
        self._publish_status()
        return resp

    def _stop(self) -> None:
        self.sent.add((0.0, 0.0, 0.0))
        self._cmd.publish(Twist())

    def _hold_reason(self) -> tuple[str, str] | None:
        """(cause, reason) of a hold of the ACTIVE goal, None when it may walk."""
        now = time.monotonic()
        if self.odom.pose is None or now - self.odom.at > self.odom_timeout:
            return "odometry", "waiting for odometry"
        if now - self._foreign_at < FOREIGN_HOLD:
            return "cmd_vel_publisher", foreign_reason(self._other_publishers(), FOREIGN_HOLD)
        stale = self.freshness.stale_reason(now, self.map_max_age)
        return None if stale is None else ("map", stale)

    def _held(self) -> bool:
        """Hold the ACTIVE goal if a cause says so (stop once, the reason in the status, the
        cause counted and logged); True while held."""
        hold = self._hold_reason()
        if hold is None or self._nav.state is not NavState.ACTIVE:
            self._held_cause = None
            return hold is not None
        cause, reason = hold
        if self._nav.reason != reason and self._held_cause == cause:
            self._nav.reason = reason  # the same hold, its figures grown (e.g. the map's age)
        elif self._nav.reason != reason:
            self._stop()
            self._nav.reason, self._held_cause = reason, cause
            self.holds[cause] += 1
            self.get_logger().warning(f"goal held: {reason}")
            self._publish_status()
        return True

    def _other_publishers(self) -> list[str]:
        """The other publishers of cmd_vel on the graph, by full name."""
        infos = self.get_publishers_info_by_topic(self._cmd.topic_name)
        return foreign_publishers(((i.node_name, i.node_namespace) for i in infos),
                                  (self.get_name(), self.get_namespace()))

    def _on_cmd_vel(self, msg: Twist) -> None:
        """A twist on cmd_vel: another node's when the navigator did not send it."""
        if not self.sent.echo((msg.linear.x, msg.linear.y, msg.angular.z)):
            self._foreign_at = time.monotonic()
            self.foreign_twists += 1
            if self._nav.state is NavState.ACTIVE:
                self._held()

    def _watch(self) -> None:
        """Every `WATCH_PERIOD`: a hold when due (a dead mapper sends no map to check on)."""
        if self._nav.state is NavState.ACTIVE:
            self._held()

    def _publish_diagnostics(self) -> None:
        held = self._nav.state is NavState.ACTIVE and self._hold_reason() is not None
        others = self._other_publishers()
        warn = held or time.monotonic() - self._foreign_at < FOREIGN_HOLD
        values = {"state": self._nav.state.value, "refusals": self.commands.refusals,
                  "last_refusal": self.commands.last_refusal,
                  **{f"holds_{c}": self.holds[c] for c in ("odometry", "map",
                                                           "cmd_vel_publisher")},
                  "foreign_twists_refused": self._planner.foreign,
                  "foreign_twists_seen": self.foreign_twists,
                  "other_cmd_vel_publishers": " ".join(others),
                  "map_age": round(min(self.freshness.age(time.monotonic()), 1e9), 3),
                  "callback_errors": self.guard.total, "heights_refused": self.heights_refused,
                  **{f"odom_{k}": v for k, v in sorted(self.odom.refused.items())}}
        self._diagnostics.publish(counters_array(
            self, "navigation", HARDWARE_ID, "warn" if warn else "ok",
            self._nav.reason if held else ("another node publishes cmd_vel" if warn else "ok"),
            values))

    def _on_map(self, msg: OccupancyGrid) -> None:
        info = msg.info
        self.freshness.note(info.map_load_time.sec + 1e-9 * info.map_load_time.nanosec,
                            self.get_clock().now().nanoseconds * 1e-9, time.monotonic())
        nav = self._nav
        if (nav.state is not NavState.ACTIVE and not self.missions.running) or self._held():
            return
        try:
            view = view_from_grid((info.origin.position.x, info.origin.position.y),
                                  info.resolution, info.width, info.height,
                                  np.asarray(msg.data, dtype=np.int8), self._heights)
        except CommandError as exc:
            self.get_logger().warning(str(exc), throttle_duration_sec=1.0)
            return
        if nav.state is NavState.ACTIVE:
            nav.reason = ""  # a hold's reason (a failure's stays for the mission to report)
        disc = self.body.radius + nav.settings.margin
        ended = self.missions.before(self.odom.pose, view, disc)
        command = (nav.goal, getattr(nav, "command", None))
        out = nav.step(self.odom.pose, self.body.radius, view, time.monotonic())
        ended = self.missions.after(view, disc) or ended
        if nav.state is NavState.ACTIVE and (nav.goal is not command[0]
                                             or getattr(nav, "command", None) is not command[1]):
            # the mission sent the next waypoint in the same cycle: walk on to it, no stop
            # (only then: a navigator waiting with a zero twist is not planned twice a cycle)
            out = nav.step(self.odom.pose, self.body.radius, view, time.monotonic())
        elif nav.state is not NavState.ACTIVE and out.twist is not None and any(out.twist):
            out = Output(twist=(0.0, 0.0, 0.0), changed=True)  # the mission dropped the goal
        if ended and out.twist is None:
            self._stop()  # a mission that ended in this cycle leaves the robot standing
        if out.twist is not None:
            self.sent.add(out.twist)
            self._cmd.publish(Twist(linear=_vec(out.twist[0], out.twist[1]),
                                    angular=_vec(0.0, 0.0, out.twist[2])))
        self._publish_status()

    def _publish_status(self, force: bool = False) -> None:
        status = {**self._nav.status(), "radius": round(self.body.radius, 4),
                  "refusals": self.commands.refusals, "last_refusal": self.commands.last_refusal,
                  "foreign_twists_refused": self._planner.foreign,
                  "last_foreign_twist": self._planner.last_foreign,
                  "foreign_twists_seen": self.foreign_twists}
        text = json.dumps(status)
        if force or text != self._last_status:
            self._last_status = text
            self._status.publish(String(data=text))


def _vec(x: float, y: float, z: float = 0.0) -> Vector3:
    return Vector3(x=float(x), y=float(y), z=float(z))


def main(args: Sequence[str] | None = None) -> None:
    """Console script ``navigator``: run until Ctrl-C; a bad parameter prints one line and
    exits 1."""
    run_node(NavigatorNode, f"{NAME}: error", args)


if __name__ == "__main__":
    main()
