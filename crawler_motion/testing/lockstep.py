"""The planner core and the seabed physics on one simulated clock, without ROS (lock-step).

The base of the closed-loop harnesses (`avoidance_loop`, `foothold_loop`): they hold a
`SeabedModel` (``sm``) with its ``data``, a `PlannerCore` (``core``) and the simulated time
``t`` [s], and define `tick` (one control period).
"""

from __future__ import annotations

import numpy as np

from crawler_motion.planner.core import PlannerCore
from crawler_motion.sim.seabed.model import SeabedModel


class LockStep:
    """Shared parts of the lock-step loops (subclasses set ``sm``, ``data``, ``core``, ``t``)."""

    sm: SeabedModel
    data: object
    core: PlannerCore
    t: float

    def tick(self) -> object:
        """One control period (subclasses)."""
        raise NotImplementedError

    def joints(self) -> np.ndarray:
        """Measured joint angles ``(12,)`` [rad]."""
        return self.data.qpos[self.sm.qpos_index].copy()  # type: ignore[attr-defined]

    def stand(self, limit: float = 5.0) -> None:
        """Stand up (the planner's stand move from the measured pose), for at most ``limit``
        [s] of simulated time."""
        self.core.set_measured(self.joints(), self.t)
        self.core.submit('{"command": "stand"}', self.t)
        end = self.t + limit
        while self.core.state != "STANDING" and self.t < end:
            self.tick()
