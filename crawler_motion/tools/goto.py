"""``crawler-motion console goto X Y`` / ``cancel``: a goal for the navigator, followed to its end.

``goto`` publishes ``goal_pose`` (in ``--frame``, default odom) and prints each change of
``navigation_status`` until the navigator reports ARRIVED (exit 0) or FAILED / a refusal /
the timeout (exit 1; on a timeout the goal is cancelled, so the robot stands). ``cancel``
calls ``navigator/cancel``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from typing import Any

#: States that end a goal.
FINAL_STATES = ("ARRIVED", "FAILED")


def describe(status: dict[str, Any]) -> str:
    """One line of a navigation status."""
    parts = [status.get("state", "?")]
    if status.get("distance") is not None:
        parts.append(f"{status['distance']:.3f} m to go")
    if status.get("heading") is not None:
        parts.append(f"heading {status['heading']:.2f} rad ({status.get('rule')})")
    if status.get("reason"):
        parts.append(status["reason"])
    return ", ".join(parts)


class GoalConsole:
    """A node that sends goals, cancels them and follows ``navigation_status``."""

    def __init__(self, node_name: str = "crawler_goal_console") -> None:
        from geometry_msgs.msg import PoseStamped
        from rclpy.node import Node
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from std_msgs.msg import String
        from std_srvs.srv import Trigger

        self._pose_type = PoseStamped
        self.node = Node(node_name)
        self.status: dict[str, Any] | None = None
        self.printer: Callable[[str], None] = print
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._goal = self.node.create_publisher(PoseStamped, "goal_pose", 10)
        self.node.create_subscription(String, "navigation_status", self._on_status, latched)
        self._cancel = self.node.create_client(Trigger, "navigator/cancel")
        self._trigger = Trigger

    def _on_status(self, msg: Any) -> None:
        try:
            status = json.loads(msg.data)
        except ValueError:
            return
        if status.get("state") != (self.status or {}).get("state") or status.get(
                "reason") != (self.status or {}).get("reason"):
            self.printer(describe(status))
        self.status = status

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Spin until ``predicate`` or ``timeout`` [s]."""
        import rclpy

        end = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() >= end:
                return False
            rclpy.spin_once(self.node, timeout_sec=0.05)
        return True

    def goto(self, x: float, y: float, frame: str, timeout: float) -> tuple[bool, str]:
        """Send the goal and follow it; (arrived, last status line)."""
        if not self.spin_until(lambda: self.status is not None, min(timeout, 10.0)):
            return False, "no navigator answering on navigation_status"
        # the goal is sent once: a sample published before the match is lost
        if not self.spin_until(lambda: self._goal.get_subscription_count() > 0,
                               min(timeout, 10.0)):
            return False, "no navigator subscribed to goal_pose"
        refusals = self.status.get("refusals", 0)
        msg = self._pose_type()
        msg.header.frame_id = frame
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.pose.position.x, msg.pose.position.y = float(x), float(y)
        msg.pose.orientation.w = 1.0
        self._goal.publish(msg)
        goal = [float(x), float(y)]

        def ended() -> bool:
            s = self.status or {}
            return s.get("refusals", 0) > refusals or (
                s.get("goal") == goal and s.get("state") in FINAL_STATES)

        if not self.spin_until(ended, timeout):
            self.cancel(5.0)
            return False, f"timed out after {timeout:g} s; goal cancelled"
        s = self.status or {}
        if s.get("refusals", 0) > refusals:
            return False, f"goal refused: {s.get('last_refusal')}"
        return s.get("state") == "ARRIVED", describe(s)

    def cancel(self, timeout: float) -> tuple[bool, str]:
        """Call ``navigator/cancel``."""
        if not self._cancel.wait_for_service(timeout_sec=timeout):
            return False, "no navigator/cancel service"
        future = self._cancel.call_async(self._trigger.Request())
        if not self.spin_until(future.done, timeout):
            return False, "navigator/cancel did not answer"
        return bool(future.result().success), future.result().message

    def close(self) -> None:
        """Destroy the node."""
        self.node.destroy_node()


def run(action: str, x: float, y: float, frame: str, timeout: float, quiet: bool,
        ros_args: Sequence[str] = ()) -> int:
    """The ``goto`` / ``cancel`` action of the console (``ros_args``: ``--ros-args ...``);
    the exit status."""
    from crawler_motion.tools.console import outcome, run_session

    def act(console: GoalConsole) -> int:
        return outcome(*(console.goto(x, y, frame, timeout) if action == "goto"
                         else console.cancel(min(timeout, 10.0))))

    return run_session(GoalConsole, act, quiet, ros_args)
