"""Planning the next gait slot ahead of its boundary, detached so it may run in another thread."""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TypeVar

from crawler_motion.errors import GaitError, KinematicsError, TrajectoryError
from crawler_motion.model.config import RobotConfig
from crawler_motion.motion.fastpath import Track
from crawler_motion.motion.gait import GaitSequencer, Slot, WalkParams, check_trajectories
from crawler_motion.planner.footholds import SlotFacts, slot_facts

#: `PlannerCore.plan_ahead(now)` plans the next slot at most this long before its boundary [s].
PLAN_AHEAD_HORIZON = 0.2

#: *Rule*: a ``cmd_vel`` walk's next slot that the limits refuse at the asked stride and turn
#: (a heading that swings between slots can carry a stance foot past its reach) is planned
#: again with both times each of these shares, in order, before the walk stops into standing;
#: a twist that starts a walk the up-front check refuses starts at the first share it passes.
#: The slowed slot is stated in ``planner_status`` (``slowed_share``, ``slowed_slots``); the
#: next slot asks for the twist's own stride again. A ``walk`` command's steps are never
#: shortened: it stops, or is refused.
SLOWED_SHARES = (0.6, 0.3)

T = TypeVar("T")


@dataclass(frozen=True)
class Slowed:
    """A slot planned at ``share`` of the asked stride and turn, because of ``why``."""

    share: float
    why: str


def plan_next(robot: RobotConfig, trial: GaitSequencer, params: WalkParams | None,
              stopping: bool, slow: bool = False
              ) -> tuple[Slot | None, GaitSequencer | None, str | None, Slowed | None]:
    """`plan_checked`, and with ``slow`` (a ``cmd_vel`` walk) a refused slot that does not
    stop planned again at each of `SLOWED_SHARES` of its stride and turn: ``(slot, seq,
    None, Slowed)`` for the first that passes, else the asked slot's refusal."""
    slot, seq, error = plan_checked(robot, copy.copy(trial), params, stopping)
    if error is None or not slow or stopping:
        return slot, seq, error, None
    def attempt(slower: WalkParams) -> tuple[Slot | None, GaitSequencer | None] | None:
        slot, seq, retry = plan_checked(robot, copy.copy(trial), slower, stopping)
        return (slot, seq) if retry is None else None

    found = first_slower(params if params is not None else trial.params, attempt)
    if found is None:
        return None, None, error, None
    share, (slot, seq) = found
    return slot, seq, None, Slowed(share, error)


def first_slower(asked: WalkParams, attempt: Callable[[WalkParams], T | None]
                 ) -> tuple[float, T] | None:
    """The first of `SLOWED_SHARES` at which ``attempt`` accepts ``asked`` with the stride and
    the turn per step times the share (heading, timing and heights unchanged: the same
    twist's direction, slower), with what it returned; None if it accepts none."""
    for share in SLOWED_SHARES:
        result = attempt(replace(asked, stride=asked.stride * share, turn=asked.turn * share))
        if result is not None:
            return share, result
    return None


def plan_checked(robot: RobotConfig, trial: GaitSequencer, params: WalkParams | None,
                 stopping: bool) -> tuple[Slot | None, GaitSequencer | None, str | None]:
    """Plan and check the next slot on ``trial`` (a copy of the walk's sequencer).

    A slot that does not stop is taken only if the first slot of a stop after it passes the
    check too (*rule*: a walk never enters a slot it cannot stop from; without it a stance
    foot could end a slot at its reach with the velocity out, and neither the next slot nor
    a stop could follow: HOLDING). Returns ``(slot, trial, None)`` or ``(None, None,
    reason)``; None slot: nothing left."""
    try:
        if params is not None:
            trial.set_params(params)
        slot = trial.next_slot(stopping=stopping)
        if slot is not None:
            check_trajectories(robot, slot.legs, f"the next ({slot.kind}) slot")
    except (GaitError, KinematicsError, TrajectoryError) as exc:
        return None, None, str(exc)
    if slot is not None and not stopping:
        try:
            after = copy.copy(trial).next_slot(stopping=True)
            if after is not None:
                check_trajectories(robot, after.legs, "the stop after it")
        except (GaitError, KinematicsError, TrajectoryError) as exc:
            return None, None, f"the next ({slot.kind}) slot could not be stopped from: {exc}"
    return slot, trial, None


@dataclass(frozen=True)
class AheadPlan:
    """The next slot planned ahead of its boundary, with the inputs it was planned from."""

    after: Slot | None
    pending: WalkParams | None
    stopping: bool
    slot: Slot | None
    seq: GaitSequencer | None
    error: str | None
    track: Track | None
    facts: SlotFacts | None = None  # what the footholds need of the slot (`slot_facts`)
    slowed: Slowed | None = None  # planned slower than asked (`plan_next`)

    def matches(self, after: Slot | None, pending: WalkParams | None, stopping: bool) -> bool:
        """True if planned after slot ``after`` with these parameters and stop flag."""
        return self.after is after and self.pending is pending and self.stopping == stopping


@dataclass(frozen=True)
class AheadJob:
    """Planning of the next slot ahead of its boundary, detached from the core: `run` uses
    only these fields (``seq`` is a private copy), so it may run without the caller's lock."""

    robot: RobotConfig
    seq: GaitSequencer
    after: Slot
    pending: WalkParams | None
    stopping: bool
    slow: bool = False  # a cmd_vel walk: a refused slot may be slowed (`plan_next`)

    def run(self) -> AheadPlan:
        """Plan, check and prepare the evaluator, the footholds' facts and the joint table
        (`JointTable`) of the next slot (~10-30 ms; a slowed slot up to three times that)."""
        slot, seq, error, slowed = plan_next(self.robot, self.seq, self.pending, self.stopping,
                                             self.slow)
        ready = slot is not None and error is None
        track = Track(slot.legs) if ready else None
        facts = slot_facts(slot, self.robot) if ready else None
        return AheadPlan(self.after, self.pending, self.stopping, slot, seq, error, track,
                         facts, slowed)
