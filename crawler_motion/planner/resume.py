"""Resuming after an interruption from the measured pose, never from the open-loop plan.

An interruption is anything after which the joints may not be where the planner last sent
them: a pause (a motor-manager fault), the driver enabling the motors again, or the planner's
own ticks stopping for longer than `FREEZE_GAP` (a starved or stopped process). A walk freezes
where it is (or at the slot boundary a pause held it at); a stand / sit move and a held pose
are remembered; a pose move ends where it was (STANDING at that pose: it does not go on by
itself). Once nothing pauses the planner and a measurement taken after the interruption
is there (publishing nothing until then), a rest-sextic
joint move (as ``stand``) brings the joints from the measured pose back to the held pose; the
walk then continues where it stopped, a move starts again from there.
"""

from __future__ import annotations

import math

import numpy as np

from crawler_motion.model.config import Config
from crawler_motion.planner.context import JointTarget, PlannerContext
from crawler_motion.planner.driver_view import DriverChange, DriverView
from crawler_motion.planner.moves import JointMove, MoveController
from crawler_motion.planner.state import HOLDING_STATES, IDLE, MOVING, WALK_STATES
from crawler_motion.planner.walk import WalkController

#: Ticks this far apart [s] mean the planner did not run: the next tick resumes.
FREEZE_GAP = 0.1
#: Planner states that send targets and so can be interrupted.
MOTION_STATES = WALK_STATES | HOLDING_STATES | {MOVING}


class Resumer:
    """Interruptions and the resume move of one planner (see the module docstring)."""

    def __init__(self, cfg: Config, ctx: PlannerContext, walk: WalkController,
                 moves: MoveController) -> None:
        self.cfg, self.ctx, self.walk, self.moves = cfg, ctx, walk, moves
        self.pending = ""  # why a resume is due ("" when none)
        self._move: JointMove | None = None  # the resume move of a walk
        self._interrupted: JointMove | None = None  # a stand / sit move interrupted
        self.resumes = 0
        self.interruptions = 0  # interruptions of a motion so far (a resume was due after each)
        self._epoch: int | None = None  # the driver's enable epoch last seen
        self._since = 0.0  # steady time of the interruption [s]

    @property
    def active(self) -> bool:
        """True while a resume is due or its move runs."""
        return bool(self.pending) or self._move is not None

    def clear(self) -> None:
        """Forget any resume (the motion ended)."""
        self.pending, self._move, self._interrupted = "", None, None

    def admit(self, kind: str, driver: DriverView, now: float) -> None:
        """Refuse (`CommandError`) a ``kind`` command the driver's state or a resume in
        progress does not allow (a stand / sit once started replaces a due resume: the caller
        then calls `clear`)."""
        journal = self.ctx.journal
        if kind in ("stand", "sit", "walk", "pose") and driver.ending:
            journal.refuse(f"{kind} refused: {driver.why()}; run crawler-motion console "
                           f"recover first", now)
        if kind in ("walk", "pose") and self.active and not self.ctx.paused:
            journal.refuse(f"{kind} refused: resuming from the measured pose; retry when it "
                           f"is done", now)

    def set_paused(self, paused: bool, now: float, reason: str) -> None:
        """Pause or resume at ``now`` [s]; a pause of a move or a held pose interrupts it
        (a walk runs to its slot end, then holds: `before_tick`)."""
        was = self.ctx.paused
        self.ctx.set_paused(paused, now, reason)
        if paused and not was and self.ctx.state not in WALK_STATES:
            self.interrupt(now, f"pause: {reason or 'motor manager fault'}")

    def on_driver(self, driver: DriverView, change: DriverChange, now: float) -> None:
        """After a driver report: a driver that stopped following or restarted ends the
        motion (cleared by the caller) into IDLE; a new enable epoch interrupts it."""
        assert driver.report is not None
        epoch, self._epoch = self._epoch, driver.report.enable_epoch
        if change in (DriverChange.ENDED, DriverChange.RESTARTED):
            if self.ctx.state in MOTION_STATES:
                self.end(now, driver.why() if change is DriverChange.ENDED
                         else "the driver restarted")
        elif epoch is not None and epoch != self._epoch:
            self.interrupt(now, "driver re-enabled")

    def before_tick(self, last: float, now: float, rate_hz: float) -> None:
        """Ticks from ``last`` to ``now`` [s] more than `FREEZE_GAP` (and 3 periods) apart
        interrupt at ``last``; a walk held at a slot boundary by a pause waits for a resume."""
        gap = now - last  # infinite before the first tick: nothing was interrupted
        if math.isfinite(gap) and gap > max(FREEZE_GAP, 3.0 / rate_hz):
            self.interrupt(last, f"no tick for {gap:.3f} s")
            # the joints moved on meanwhile: a measurement from the last period or later
            self._since = max(last, now - 1.0 / rate_hz)
        if self.ctx.state in WALK_STATES and self.walk.waiting and not self.active:
            self.interrupt(now, "pause")

    def end(self, now: float, why: str) -> None:
        """The driver stopped following: the motion (already cleared) ends into IDLE."""
        ctx = self.ctx
        was = ctx.state
        self.clear()
        ctx.hold = None
        ctx.last_target = None
        ctx.enter(IDLE, now)
        ctx.journal.event("error", f"{was} ended: {why}; nothing moves until a new stand "
                                   f"(crawler-motion console recover, then stand)")

    def interrupt(self, at: float, why: str) -> None:
        """The joints may have left the last target at steady time ``at`` [s]."""
        ctx = self.ctx
        if ctx.state not in MOTION_STATES:
            return
        if ctx.state in WALK_STATES:
            self._move = None
            self.walk.freeze(at)
        elif ctx.state == MOVING and self.moves.move is not None:
            if ctx.last_target is not None:
                ctx.hold = ctx.hold_pose(ctx.last_target.positions)
            self._interrupted = self.moves.interrupt(at)  # None: a pose move, now STANDING
        if not self.pending:
            self.interruptions += 1
            ctx.journal.event("warn", f"interrupted ({why}): holding; resuming from the "
                                      f"measured pose when it clears")
        self.pending = why
        self._since = at
        ctx.journal.touch(at)

    def tick(self, now: float) -> JointTarget | None:
        """The target of a due resume at ``now`` [s] (the held pose while paused, nothing
        while no fresh measurement is there); the caller ticks normally once inactive."""
        ctx = self.ctx
        if self.pending:
            if ctx.paused:
                return ctx.hold
            measured = self.moves.fresh_measured(now, self._since)
            if measured is None:  # one taken after the interruption
                return None  # never the held pose: the joints may be elsewhere
            self._start(now, measured)
            if ctx.state not in WALK_STATES:
                return self.moves.tick(now)
        move = self._move
        assert move is not None
        if not move.done(now):
            target = move.at(now)
            ctx.last_target = target
            return target
        self._move = None
        ctx.hold = ctx.hold_pose(move.final)
        ctx.last_target = ctx.hold
        ctx.journal.event("info", "resumed: walk continues")
        if not self.walk.thaw(now):
            return ctx.hold
        return self.walk.tick(now, float("inf"))

    def _start(self, now: float, measured: np.ndarray) -> None:
        ctx, why = self.ctx, self.pending
        self.pending = ""
        self.resumes += 1
        what = f"resume after {why}"
        if ctx.state in WALK_STATES:
            assert ctx.hold is not None
            self._move = JointMove(self.cfg, measured, ctx.hold.positions.reshape(-1, 3), now,
                                   ctx.state, what)
            ctx.journal.event("info", f"{what}: {self._move.duration:.2f} s joint move from "
                                      f"the measured pose, then the walk continues")
        elif self._interrupted is not None:
            old, self._interrupted = self._interrupted, None
            self.moves.resume(now, measured, old.final, old.end_state, old.target)
        else:
            assert ctx.hold is not None
            self.moves.resume(now, measured, ctx.hold.positions, ctx.state, what)
        ctx.journal.touch(now)
