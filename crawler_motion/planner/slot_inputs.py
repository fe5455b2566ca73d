"""What the next gait slot of a walk is planned from: the parameters and step budget asked
for, and when a twist takes effect."""

from __future__ import annotations

from dataclasses import dataclass

from crawler_motion.motion.gait import WalkParams
from crawler_motion.planner.next_slot import PLAN_AHEAD_HORIZON


@dataclass
class SlotInputs:
    """The parameters and step budget asked for since the slot being walked was planned.

    *Rule*: a twist that arrives within `PLAN_AHEAD_HORIZON` of a slot boundary, while the
    next slot is being planned ahead from the parameters as they were, is kept for the slot
    after it, so the tick never has to plan a slot that a twist made stale (a navigator
    steers with twists at 10 Hz; a slot planned in the tick took 10-150 ms on the real-time
    stack and interrupted the walk). A twist takes effect 0.2 s to one slot plus 0.2 s after
    it arrives. A ``walk`` command is for the next slot and replaces a twist not yet taken.
    """

    pending: WalkParams | None = None  # the next slot's parameters (None: unchanged)
    later: WalkParams | None = None  # a twist's, for the slot after the next one
    steps: tuple[int | None] | None = None  # a new step budget from the next slot
    #: The parameters asked for of the slot being walked, which may have been planned slower
    #: (`next_slot.SLOWED_SHARES`): each next slot asks for them again, never for a slowed
    #: slot's (a slowed stride is not slowed again as if asked for).
    asked: WalkParams | None = None

    def clear(self) -> None:
        """Forget everything asked for."""
        self.pending = self.later = self.steps = self.asked = None

    def newest(self, current: WalkParams | None) -> WalkParams | None:
        """The newest parameters asked for, else ``current`` (the slot's)."""
        return self.later or self.pending or self.asked or current

    def next(self, current: WalkParams | None) -> WalkParams | None:
        """The next slot's parameters: the new ones asked for, else those asked for of the
        slot ``current`` (its parameters) when it was slowed, else None (unchanged)."""
        if self.pending is not None:
            return self.pending
        return self.asked if self.asked is not None and self.asked != current else None

    def take_twist(self, params: WalkParams, current: WalkParams | None,
                   to_boundary: float) -> None:
        """A twist's parameters, ``to_boundary`` [s] before the slot boundary (inf while no
        slot is being planned ahead)."""
        if params == self.newest(current):
            return
        if to_boundary <= PLAN_AHEAD_HORIZON:
            self.later = params
        else:
            self.pending, self.later = params, None

    def take_command(self, params: WalkParams, steps: int | None) -> None:
        """A ``walk`` command's parameters and step budget (None: until stopped)."""
        self.pending, self.later = params, None
        self.steps = (steps,)

    def advance(self, stopping: bool) -> None:
        """The next slot was planned (``stopping``: a stop): what it was asked for is kept
        (`asked`), and a twist kept for the slot after it becomes the next one's."""
        if self.pending is not None:
            self.asked = self.pending
        self.pending, self.later = (None if stopping else self.later), None
