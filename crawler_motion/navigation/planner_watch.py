"""What the planner says of the navigator's twists: a refusal that repeats ends the goal.

The planner refuses a ``cmd_vel`` twist beyond what its walk can do (the speed or yaw rate of
its gait and timing, `planner.commands.TWIST_BEYOND_LIMITS`), or any twist while the robot
is not up (`planner.commands.needs_stand`: never stood, sat, or posed), and records it in
``planner_status`` (``refusals``, ``last_refusal``). The navigator would send the same twist
again at every map, and the robot would stand while the goal stays ACTIVE until its timeout.
`RefusalWatch` tells it instead, from the statuses, so it fails the goal with the planner's
reason. Other refusals (a pause, a stop in progress) pass and change nothing. A refused twist
that the navigator did not send (the planner's ``refused_twist`` is none of its recent twists:
another node publishes ``cmd_vel``) is not blamed on it: counted in `foreign`, the goal goes
on. The first status the watch hears is its baseline, not news: it is the planner's latched
one, and its refusals predate the navigator (a restarted navigator took the "send stand first"
of a restarted driver, minutes old, for a refusal of its first goal's twists); a refusal of
its own twists before it heard the planner is caught at the next twist.
"""

from __future__ import annotations

import json
from collections.abc import Container

from crawler_motion.planner.commands import TWIST_BEYOND_LIMITS, needs_stand


class RefusalWatch:
    """The planner's refusal count as of the goal's start, and the refusals since."""

    def __init__(self) -> None:
        self.refusals = 0  # the planner's count in its latest status
        self._baseline = 0
        self._heard = False  # a status was heard: the first one is the baseline
        self.foreign = 0  # refusals of twists the navigator did not send
        self.last_foreign = ""  # the latest of those

    def start(self) -> None:
        """A goal starts: only refusals after this count."""
        self._baseline = self.refusals

    def update(self, text: str, sent: Container[object] | None = None) -> str | None:
        """One ``planner_status`` JSON text: the reason to end the goal, if the planner has
        refused a twist beyond its limits since `start` that is in ``sent`` (the navigator's
        recent twists; None: every refused twist counts as its own). None otherwise, and for
        a status that is not a JSON object with those keys."""
        try:
            status = json.loads(text)
            refusals, last = int(status["refusals"]), str(status["last_refusal"] or "")
        except (ValueError, KeyError, TypeError):
            return None
        if not self._heard:
            self._heard, self._baseline = True, refusals
        new = refusals > self._baseline
        self.refusals = refusals
        if not (new and (last.startswith(TWIST_BEYOND_LIMITS) or needs_stand(last))):
            return None
        self._baseline = refusals
        refused = status.get("refused_twist")
        if sent is not None and refused is not None and refused not in sent:
            self.foreign += 1
            self.last_foreign = f"the planner refused another publisher's twist: {last}"
            return None
        return f"the planner refuses the navigator's twists: {last}"
