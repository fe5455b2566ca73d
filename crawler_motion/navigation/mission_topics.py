"""The navigator's mission topics: ``mission`` in, ``mission_status`` out (ROS side).

Missions walk on the improved potential field (`ApfNavigator`) whatever the node's ``method``
(with ``virtual_body``, an apf navigator of the same settings steers while a mission runs).
``mission`` (std_msgs/String): a mission file's text (`mission.parse_mission`); a bad one is
refused through the navigator's refusal path (counted, logged, in ``navigation_status``) and
``mission_status`` says why (state ``REFUSED``). A new mission replaces a running one; the
same text again while it runs is a sender's repeat and changes nothing.
``mission_status`` (std_msgs/String JSON, transient local): `MissionRunner.status` plus the
time since the mission started, on every change of task or state and once a second. The navigator's
``~/cancel`` and a new ``goal_pose`` or ``follow_command`` cancel a running mission.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import String

from crawler_motion.errors import CommandError
from crawler_motion.navigation.apf_navigator import ApfNavigator
from crawler_motion.navigation.mission import parse_mission
from crawler_motion.navigation.mission_runner import MissionRunner, MissionState
from crawler_motion.navigation.navigator import TerrainView

#: Period of the repeated ``mission_status`` [s].
STATUS_PERIOD = 1.0
#: The fields whose change publishes ``mission_status`` at once (the others ride the 1 Hz).
CHANGE_KEYS = ("mission", "task_index", "task_kind", "state", "reason", "last_refusal")


class MissionTopics:
    """One running mission at most, on the node's `ApfNavigator`."""

    def __init__(self, node: Node, nav: Any, tool_width: float,
                 pose: Callable[[], tuple[float, float, float] | None],
                 refuse: Callable[[str], None], on_start: Callable[[], None]) -> None:
        # missions walk on the improved potential field whatever the node's method: its own
        # apf navigator (same settings) when the node's is another method
        self.nav = nav if isinstance(nav, ApfNavigator) else ApfNavigator(nav.settings)
        self.node, self.tool_width = node, tool_width
        self.pose, self.refuse, self.on_start = pose, refuse, on_start
        self.runner: MissionRunner | None = None
        self._count = 0
        self._last = ""
        self._refused = ""
        self._text = ""  # of the running mission
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._status = node.create_publisher(String, "mission_status", latched)
        node.create_subscription(String, "mission", self._on_mission, 10)
        node.create_timer(STATUS_PERIOD, lambda: self.publish(force=True))

    @property
    def running(self) -> bool:
        """A mission is running."""
        return self.runner is not None and self.runner.state is MissionState.RUNNING

    def _on_mission(self, msg: String) -> None:
        if self.running and msg.data == self._text:
            return  # a sender's repeat of the mission running (it had no answer yet)
        pose = self.pose()
        if pose is None:
            self._refuse("no odometry yet: the mission's home is unknown")
            return
        self._count += 1
        try:
            mission = parse_mission(msg.data, f"mission-{self._count}")
        except CommandError as exc:
            self._refuse(str(exc))
            return
        self.cancel("replaced by a new mission")
        self.runner = MissionRunner(mission, self.nav, np.array(pose[:2]), time.monotonic(),
                                    self.tool_width)
        self._text = msg.data
        self._refused = ""
        self.on_start()
        self.node.get_logger().info(f"mission {mission.id}: {len(mission.tasks)} tasks")
        self.publish()

    def _refuse(self, why: str) -> None:
        self._refused = why
        self.refuse(f"mission refused: {why}")
        self.publish(force=True)

    def cancel(self, reason: str = "cancelled") -> None:
        """Cancel a running mission (its goal with it)."""
        if self.running:
            assert self.runner is not None
            self.runner.cancel(reason)
            self.publish()

    def before(self, pose: tuple[float, float, float], view: TerrainView, disc: float) -> bool:
        """Before the navigator's cycle (`MissionRunner.before`); True when the mission ended
        in it (failed: the robot must be stopped)."""
        if not self.running:
            return False
        assert self.runner is not None
        self.runner.before(pose, view, disc, time.monotonic())
        return not self.running

    def after(self, view: TerrainView, disc: float) -> bool:
        """After the navigator's cycle (`MissionRunner.after`); True when the mission ended
        in it."""
        if not self.running:
            return False
        assert self.runner is not None
        self.runner.after(view, disc, time.monotonic())
        self.publish()
        return not self.running

    def publish(self, force: bool = False) -> None:
        """``mission_status`` on a change (``force``: always)."""
        if self.runner is None:
            status: dict[str, Any] = {"mission": None, "state": "REFUSED" if self._refused
                                      else "IDLE", "reason": self._refused}
        else:
            status = {**self.runner.status(),
                      "elapsed": round(time.monotonic() - self.runner.began, 1)}
            if self._refused:
                status["last_refusal"] = self._refused
        text = json.dumps(status)
        changed = json.dumps([status.get(k) for k in CHANGE_KEYS])
        if force or changed != self._last:
            self._last = changed
            self._status.publish(String(data=text))
