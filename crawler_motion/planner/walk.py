"""The walk in progress: gait slots committed, planned, finished and stopped, per tick."""

from __future__ import annotations

import copy
import math

import numpy as np

from crawler_motion.errors import GaitError, KinematicsError, TrajectoryError
from crawler_motion.model.config import Config
from crawler_motion.motion.fastpath import FastKinematics, Track
from crawler_motion.motion.gait import GaitSequencer, Slot, WalkParams
from crawler_motion.planner.context import JointTarget, PlannerContext
from crawler_motion.planner.footholds import Footholds, SlotFacts
from crawler_motion.planner.next_slot import (
    PLAN_AHEAD_HORIZON,
    AheadJob,
    AheadPlan,
    Slowed,
    plan_next,
)
from crawler_motion.planner.slot_inputs import SlotInputs
from crawler_motion.planner.state import HOLDING, STANDING, STOPPING, WALK_STATES, WALKING
from crawler_motion.planner.upfront import FirstSlot, first_slot


def described(params: WalkParams, steps: int | None, source: str) -> str:
    """The log line of a walk that starts."""
    return (f"walk ({source}): {params.gait}/{params.profile}, stride {params.stride:g} m, "
            f"heading {params.heading:g} rad, turn {params.turn:g} rad/step, "
            f"{steps if steps is not None else 'until stopped'} steps")


class WalkController:
    """Slots of the current walk: starts, commits, plans (or takes a plan made ahead),
    evaluates per tick and ends the walk into STANDING or HOLDING via ``ctx``."""

    def __init__(self, cfg: Config, ctx: PlannerContext) -> None:
        self.cfg = cfg
        self.robot = cfg.robot
        self.ctx = ctx
        self._kin = FastKinematics(cfg.robot)
        self.seq: GaitSequencer | None = None
        self.slot: Slot | None = None
        self.slot_t0 = 0.0
        self.track: Track | None = None
        self.params: WalkParams | None = None
        self.inputs = SlotInputs()  # what the next slot is planned from
        self.stop_requested = False
        self.steps_total: int | None = None
        self.steady_planned = self.steady_done = 0
        self.groups = 1  # groups of the gait of the current / last walk
        self.source: str | None = None
        self.waiting = False
        self.frozen_at: float | None = None  # steady time [s] a walk froze mid-slot
        self.last_twist = -math.inf
        self.ahead: AheadPlan | None = None
        self.foothold = Footholds(cfg.robot)  # per-leg touch-down offsets

    def clear(self) -> None:
        """Forget the walk in progress (status counters stay for the status)."""
        self.seq = self.slot = self.track = self.params = None
        self.frozen_at = self.ahead = None
        self.inputs.clear()
        self.ctx.journal.end_slowed()
        self.stop_requested = self.waiting = False

    def freeze(self, at: float) -> None:
        """Hold the last target from steady time ``at`` [s] until `thaw` (the clock stops)."""
        ctx = self.ctx
        if self.waiting:
            return  # already holding at a slot boundary
        last = ctx.last_target if ctx.last_target is not None else ctx.hold
        if last is not None:
            ctx.hold = ctx.hold_pose(last.positions)
        self.waiting = True
        self.frozen_at = float(at)

    def thaw(self, now: float) -> bool:
        """Continue a frozen or held walk at ``now`` [s]; False if no slot follows."""
        self.waiting = False
        if self.frozen_at is not None:
            self.slot_t0 += now - self.frozen_at
            self.frozen_at = None
            return True
        return self._plan_slot(now)

    def start(self, params: WalkParams, steps: int | None, source: str, now: float,
              first: FirstSlot | None = None) -> None:
        """Start walking from STANDING at ``now`` [s] (with ``first``, its first slot planned
        ahead, else planned now); refusals raise `CommandError`."""
        try:
            first = first or first_slot(self.cfg, params)
        except (GaitError, KinematicsError, TrajectoryError) as exc:
            self.ctx.journal.refuse(f"walk refused: {exc}", now)
        seq = first.seq
        self.clear()
        self.seq, self.params, self.steps_total = seq, params, steps
        self.steady_planned = self.steady_done = 0
        self.groups = seq.n_groups
        self.source = source
        self.inputs.asked = params
        self.ctx.state = WALKING
        self.foothold.start(self.ctx.hold)
        self._commit(first.slot, seq, now, first.track, first.facts)
        self.ctx.journal.event("info", described(params, steps, source))

    def _commit(self, slot: Slot, seq: GaitSequencer, t0: float, track: Track | None = None,
                facts: SlotFacts | None = None) -> None:
        self.seq = seq
        self.slot = slot
        self.slot_t0 = t0
        self.track = track if track is not None else Track(slot.legs)
        self.ahead = None
        self.params = slot.params
        self.foothold.begin_slot(slot, facts)
        if slot.kind == "steady":
            self.steady_planned += 1
        self.ctx.journal.touch(t0)

    def request_stop(self, now: float, why: str) -> None:
        """While WALKING: finish the slot, then stop into standing (STOPPING)."""
        if self.ctx.state != WALKING:
            return
        self.ctx.state = STOPPING
        self.stop_requested = True
        self.inputs.clear()
        self.ctx.journal.touch(now)
        self.ctx.journal.event("info", why)

    def take_twist(self, params: WalkParams, now: float) -> None:
        """A ``cmd_vel`` twist's parameters at ``now`` [s] (`SlotInputs.take_twist`)."""
        ahead = self.slot is not None and not self.waiting
        to_boundary = self.slot_t0 + self.slot.duration - now if ahead else math.inf
        self.inputs.take_twist(params, self.params, to_boundary)

    def _try_slot(self, params: WalkParams | None, stopping: bool
                  ) -> tuple[Slot | None, GaitSequencer | None, str | None, Slowed | None]:
        assert self.seq is not None
        return plan_next(self.robot, self.seq, params, stopping, self.source == "cmd_vel")

    def _plan_slot(self, t0: float) -> bool:
        """Plan, check and start the next slot at ``t0``; False if none started."""
        assert self.seq is not None
        steps, self.inputs.steps = self.inputs.steps, None
        if steps is not None:  # a new step budget
            self.steps_total, self.steady_planned, self.steady_done = steps[0], 0, 0
        stopping, pending = self.next_inputs()
        self.inputs.advance(stopping)
        ahead, self.ahead = self.ahead, None
        track = facts = None
        if ahead is not None and ahead.matches(self.slot, pending, stopping):
            slot, seq, error, track = ahead.slot, ahead.seq, ahead.error, ahead.track
            facts, slowed = ahead.facts, ahead.slowed
        else:
            slot, seq, error, slowed = self._try_slot(pending, stopping)
        if not stopping and error is None:
            self.ctx.journal.slowed(slowed, t0)
        if error is not None:
            track = facts = None
            self.ctx.journal.event("error", f"slot check failed: {error}; stopping into "
                                            f"standing")
            slot, seq, error, _ = self._try_slot(None, True)
            if error is not None:
                self.enter_holding(t0, f"cannot stop either ({error})", self._slot_end_pose())
                return False
            stopping = True
            self.stop_requested = True
        if slot is None or seq is None:  # already standing: nothing left to walk
            self._finish(t0)
            return False
        if stopping and self.ctx.state == WALKING:
            self.ctx.state = STOPPING
        self._commit(slot, seq, t0, track, facts)
        return True

    def next_inputs(self) -> tuple[bool, WalkParams | None]:
        """(stopping, new parameters) of the next slot as things stand (mutates nothing)."""
        assert self.seq is not None
        if self.inputs.steps is not None:
            steps_total, steady_planned = self.inputs.steps[0], 0
        else:
            steps_total, steady_planned = self.steps_total, self.steady_planned
        stopping = self.stop_requested or (
            steps_total is not None and self.seq.phase == "steady"
            and steady_planned >= steps_total * self.seq.n_groups)
        return stopping, (None if stopping else self.inputs.next(self.params))

    def _slot_end_pose(self) -> np.ndarray:
        assert self.track is not None
        return self.foothold.end_pose(self.track)

    def _finish(self, now: float) -> None:
        self.ctx.hold = self.ctx.hold_pose(self._slot_end_pose())
        self.clear()
        self.ctx.enter(STANDING, now)
        self.ctx.journal.event("info", "walk done: STANDING")

    def enter_holding(self, now: float, why: str, pose: np.ndarray | None = None) -> None:
        """Hold ``pose`` [rad] (default: the last target) in HOLDING, the walk abandoned."""
        ctx = self.ctx
        if pose is None:
            last = ctx.last_target if ctx.last_target is not None else ctx.hold
            assert last is not None
            pose = last.positions
        ctx.hold = ctx.hold_pose(pose)
        self.clear()
        ctx.enter(HOLDING, now)
        ctx.journal.event("error", f"holding the pose: {why}; send stand (or sit) to recover")

    def _boundaries(self, now: float) -> bool:
        """Cross every slot boundary up to ``now``; False if the walk no longer moves."""
        assert self.slot is not None and self.seq is not None
        ctx = self.ctx
        end = self.slot_t0 + self.slot.duration
        while now >= end:
            if self.slot.kind == "steady":
                self.steady_done += 1
                ctx.journal.touch(end)
            if self.seq.standing:
                self._finish(end)
                return False
            if ctx.paused:
                ctx.hold = ctx.hold_pose(self._slot_end_pose())
                self.waiting = True
                ctx.journal.touch(end)
                ctx.journal.event("warn", "paused at a slot boundary: holding until the fault "
                                          "clears")
                return False
            if not self._plan_slot(end):
                return False
            end = self.slot_t0 + self.slot.duration
        return True

    def tick(self, now: float, cmd_vel_timeout: float) -> JointTarget | None:
        """Joint targets at steady time ``now`` [s]; a cmd_vel walk stops after
        ``cmd_vel_timeout`` [s] without a twist."""
        ctx = self.ctx
        if (ctx.state == WALKING and self.source == "cmd_vel"
                and now - self.last_twist > cmd_vel_timeout):
            self.request_stop(now, f"cmd_vel timeout ({cmd_vel_timeout:g} s without a "
                                   f"twist): stopping into standing")
        if self.waiting:  # the planner core resumes it from the measured pose (`thaw`)
            return ctx.hold
        slot = self.slot
        if (slot is None or now >= self.slot_t0 + slot.duration) and not self._boundaries(now):
            return ctx.hold  # (within the slot: no boundary to cross, no call)
        assert self.track is not None
        try:  # plain-float IK + Jacobian: same numbers and errors as the numpy functions
            q, qd = self.foothold.targets(self.track, self._kin, now, self.slot_t0)
        except KinematicsError as exc:
            self.enter_holding(now, f"tick at {now:.3f} s failed: {exc}")
            return ctx.hold
        target = JointTarget(q, qd)  # lists: arrays only if asked for
        ctx.last_target = target
        if self.foothold.failure:  # no ground under a foot, or a second hit: hold
            self.enter_holding(now, self.foothold.failure, self.foothold.failure_pose)
            return ctx.hold
        return target

    def ahead_job(self, now: float | None) -> AheadJob | None:
        """The inputs of planning the next slot ahead, or None if there is nothing to plan
        yet (not walking, waiting, standing, a plan already matching, or with ``now`` [s]
        more than `PLAN_AHEAD_HORIZON` before the boundary)."""
        if (self.ctx.state not in WALK_STATES or self.waiting or self.seq is None
                or self.slot is None or self.seq.standing):
            return None
        if now is not None and (self.slot_t0 + self.slot.duration - float(now)
                                > PLAN_AHEAD_HORIZON):
            return None
        stopping, pending = self.next_inputs()
        if self.ahead is not None and self.ahead.matches(self.slot, pending, stopping):
            return None
        return AheadJob(self.robot, copy.copy(self.seq), self.slot, pending, stopping,
                        self.source == "cmd_vel")

    def store_ahead(self, ahead: AheadPlan) -> bool:
        """Keep a plan made by `AheadJob.run`; False (dropped) if the slot it follows is no
        longer the current one."""
        if ahead.after is None or ahead.after is not self.slot:
            return False
        self.ahead = ahead
        return True
