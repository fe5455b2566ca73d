"""The navigator's body pose from ``odom``, through the mapper's odometry rules."""

from __future__ import annotations

import time
from collections import Counter
from typing import Any

from crawler_motion.mapping.odometry import OdometryGate, OdometryLimits, OdometryVerdict
from crawler_motion.mapping.odometry_pose import odometry_pose
from crawler_motion.model.rotations import yaw_of
from crawler_motion.runtime.log import Severity, Throttle, log


class OdometryInput:
    """The latest accepted pose (x, y [m], yaw [rad]) and when it came (steady clock [s]).

    Each sample goes through `mapping.odometry.OdometryGate` (default `OdometryLimits`): a
    position not finite or beyond 1e5 m, a stamp ahead of the clock, a jump, a stamp not newer
    than the last are refused, counted by verdict (`refused`) and logged once a second per
    verdict to ``logger``; a new stream (ten agreeing refusals) is taken.
    """

    def __init__(self, logger: Any) -> None:
        self.logger = logger
        self.gate = OdometryGate(OdometryLimits())
        self.refused: Counter[str] = Counter()
        self.pose: tuple[float, float, float] | None = None
        self.at = -1e9
        self._log = Throttle(1.0)

    def take(self, msg: Any, now: float) -> None:
        """One nav_msgs/Odometry; ``now``: the node's clock in the stamps' time base [s]."""
        pose = odometry_pose(msg)
        verdict = self.gate.check(pose, now)
        if verdict in (OdometryVerdict.ACCEPT, OdometryVerdict.RESET):
            self.pose = (float(pose.position[0]), float(pose.position[1]),
                         yaw_of(pose.rotation))
            self.at = time.monotonic()
            return
        self.refused[verdict.name] += 1
        if self._log.allow(verdict):
            log(self.logger, Severity.WARNING, f"odom refused: {verdict.value} "
                f"({self.refused[verdict.name]} so far)")
