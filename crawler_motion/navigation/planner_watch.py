"""What the planner says of the navigator's twists: a refusal that repeats ends the goal.

The planner refuses a ``cmd_vel`` twist beyond what its walk can do (the speed or yaw rate of
its gait and timing, `planner.commands.TWIST_BEYOND_LIMITS`) and records it in
``planner_status`` (``refusals``, ``last_refusal``). The navigator would send the same twist
again at every map, and the robot would stand while the goal stays ACTIVE until its timeout.
`RefusalWatch` tells it instead, from the statuses, so it fails the goal with the planner's
reason. Other refusals (a pause, a stop in progress) pass and change nothing.
"""

from __future__ import annotations

import json

from crawler_motion.planner.commands import TWIST_BEYOND_LIMITS


class RefusalWatch:
    """The planner's refusal count as of the goal's start, and the refusals since."""

    def __init__(self) -> None:
        self.refusals = 0  # the planner's count in its latest status
        self._baseline = 0

    def start(self) -> None:
        """A goal starts: only refusals after this count."""
        self._baseline = self.refusals

    def update(self, text: str) -> str | None:
        """One ``planner_status`` JSON text: the reason to end the goal, if the planner has
        refused a twist beyond its limits since `start` (None otherwise, and for a status that
        is not a JSON object with those keys)."""
        try:
            status = json.loads(text)
            refusals, last = int(status["refusals"]), str(status["last_refusal"] or "")
        except (ValueError, KeyError, TypeError):
            return None
        new = refusals > self._baseline
        self.refusals = refusals
        if new and last.startswith(TWIST_BEYOND_LIMITS):
            self._baseline = refusals
            return f"the planner refuses the navigator's twists: {last}"
        return None
