"""The planner's state machine behind one public API (pure: no rclpy).

`PlannerCore` is driven by a monotonic time argument ``now`` [s] (steady clock in the node), so
it is deterministic to test; its states and transitions are `state.PlannerState`. It composes
`moves.MoveController` (stand, sit, pose), `walk.WalkController` (the gait slots of a walk, planned
ahead by `next_slot.AheadJob`), `requests.WalkRequests` (walk commands and twists, a new walk
checked as a whole by `upfront.UpfrontCheck`) and `context.PlannerContext` (state, held pose,
pause flag, status journal).

``paused`` (a motor-manager fault) is a flag, not a state: while it is set no new gait slot
starts (the current slot finishes, then the pose is held at the slot boundary) and no walk or
move is accepted. Every refusal raises `CommandError`, leaves the state unchanged and is
reported in `status` and `pop_events`. One exception: a ``stand`` that only lacks the first
measured joint state is held (`held_stand`) and starts when the state arrives.

Per tick the active gait slot is evaluated by `fastpath.Track` (prepared when the slot is
planned) and turned into joint angles and rates by `fastpath.FastKinematics.solve` (the
closed-form IK with the limit check and the Jacobian, in plain floats).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from crawler_motion.errors import (
    CommandError,
    ConfigError,
    GaitError,
    KinematicsError,
    TrajectoryError,
)
from crawler_motion.model.config import Config
from crawler_motion.motion.gait import WalkParams, validate_params
from crawler_motion.planner.commands import Command, parse_gait_command
from crawler_motion.planner.contacts import ContactMonitor
from crawler_motion.planner.context import JointTarget, PlannerContext
from crawler_motion.planner.driver_view import DriverChange, DriverReport, DriverView
from crawler_motion.planner.held_stand import HeldStand
from crawler_motion.planner.moves import MEASUREMENT_MAX_AGE, MoveController, sitting_pose
from crawler_motion.planner.next_slot import AheadJob, AheadPlan
from crawler_motion.planner.readouts import CoreReadouts
from crawler_motion.planner.requests import WalkRequests
from crawler_motion.planner.resume import Resumer
from crawler_motion.planner.state import (
    ESTOP,
    HOLDING_STATES,
    IDLE,
    MOVING,
    SITTING,
    WALK_STATES,
)
from crawler_motion.planner.status_report import planner_status
from crawler_motion.planner.walk import WalkController

__all__ = ["JointTarget", "PlannerCore"]


class PlannerCore(CoreReadouts):
    """Planner state machine; see the module docstring.

    ``rate_hz`` is the tick rate the caller intends (used to count late ticks);
    ``defaults`` the walk parameters of a new walk (gait defaults; config defaults if None);
    ``cmd_vel_timeout`` [s] stops a cmd_vel-started walk when twists stop arriving;
    ``measurement_max_age`` [s] is the oldest measurement a stand / sit move starts from.
    """

    def __init__(self, cfg: Config, rate_hz: float = 100.0, *,
                 defaults: WalkParams | None = None, cmd_vel_timeout: float = 0.5,
                 measurement_max_age: float = MEASUREMENT_MAX_AGE) -> None:
        self.cfg = cfg
        self.robot = cfg.robot
        self.n_joints = 3 * self.robot.n_legs
        self.rate_hz = rate_hz
        self.set_rate(rate_hz)
        self.set_cmd_vel_timeout(cmd_vel_timeout)
        self.defaults = WalkParams.defaults(cfg.gait)
        self.set_defaults(defaults if defaults is not None else self.defaults)
        self.sitting = sitting_pose(cfg)
        self.ctx = PlannerContext(self.n_joints)
        self.walk = WalkController(cfg, self.ctx)
        self.requests = WalkRequests(cfg, self.ctx, self.walk)
        self.moves = MoveController(cfg, self.ctx, measurement_max_age)
        self.resumer = Resumer(cfg, self.ctx, self.walk, self.moves)
        self.driver = DriverView()
        # fed by the node with the joint states; read by the walk's touch-down
        self.contacts = self.walk.foothold.monitor = ContactMonitor(self.robot)
        self._stand_height = self.robot.body_height
        self.held_stand = HeldStand()  # a stand sent before the first measured state
        self._now = -math.inf
        self._last_tick = -math.inf
        self._late_ticks = 0

    # ---------------------------------------------------------------- settings
    def set_rate(self, rate_hz: float) -> None:
        """The intended tick rate [Hz] (late-tick accounting only)."""
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ConfigError(f"rate must be a finite frequency > 0 Hz, got {rate_hz!r}")
        self.rate_hz = float(rate_hz)

    def set_cmd_vel_timeout(self, timeout: float) -> None:
        """Seconds without a twist after which a cmd_vel walk stops into standing."""
        if not (math.isfinite(timeout) and timeout > 0):
            raise ConfigError(f"cmd_vel_timeout must be a finite time > 0 s, got {timeout!r}")
        self.cmd_vel_timeout = float(timeout)

    def set_defaults(self, params: WalkParams) -> None:
        """Walk parameters of the next walk started from standing (and the default height of
        ``stand``); a walk in progress keeps its parameters."""
        try:
            self.defaults = validate_params(params, self.cfg)
        except GaitError as exc:
            raise ConfigError(f"gait defaults: {exc}") from exc

    # ---------------------------------------------------------------- inputs
    def set_measured(self, positions: np.ndarray, now: float) -> None:
        """The latest measured joint angles (12 or (n_legs, 3)) [rad], at steady time ``now``;
        a held ``stand`` starts from them."""
        self.moves.set_measured(positions, now)
        height = self.held_stand.take(now, self.ctx.journal)
        if height is not None:
            try:
                self.command(Command("stand", body_height=height), now)
            except CommandError:
                pass  # refused now for another reason: recorded in the status

    def set_paused(self, paused: bool, now: float, reason: str = "") -> None:
        """Pause (motor-manager fault) or resume; see the module docstring. A pause of a
        move or a held pose interrupts it (`resume.Resumer`); a walk runs to its slot end."""
        self.resumer.set_paused(paused, now, reason)

    def on_driver(self, report: DriverReport, now: float) -> None:
        """A ``driver_status`` report: a driver that stopped following (e-stop, watchdog,
        deactivated, disabled) ends the motion into IDLE; a new enable epoch interrupts it, so
        it resumes from the measured pose."""
        change = self.driver.update(report)
        if change in (DriverChange.ENDED, DriverChange.RESTARTED):
            self._clear_motion()
        self.resumer.on_driver(self.driver, change, self._clock(now))

    def submit(self, text: str, now: float) -> Command:
        """Parse and execute one ``gait_command`` JSON text; refusals raise `CommandError`."""
        try:
            cmd = parse_gait_command(text, self.cfg)
        except CommandError as exc:
            self.ctx.journal.refuse(str(exc), now)
        self.command(cmd, now)
        return cmd

    def upfront_job(self, text: str | None = None,
                    twist: tuple[float, float, float] | None = None
                    ) -> Callable[[], object] | None:
        """The up-front check of the walk a gait command ``text`` or a ``twist`` would start
        (`upfront.UpfrontCheck`, tens of ms), as a job the caller may run without its lock
        before submitting it (it fills the check's cache); None when there is none."""
        return self.requests.upfront_job(text, twist, self._base())

    def record_refusal(self, reason: str, now: float) -> None:
        """Record a refusal decided elsewhere (e.g. a bad parameter set) in the status."""
        self.ctx.journal.record_refusal(reason, now)

    def command(self, cmd: Command, now: float) -> None:
        """Execute a parsed command at ``now``; refusals raise `CommandError`."""
        now = self._clock(now)
        self.held_stand.clear()  # the newest command replaces a held stand
        self.resumer.admit(cmd.kind, self.driver, now)
        if cmd.kind == "stand" and self.moves.waits_for_first_state(now, "stand"):
            height = self.defaults.body_height if cmd.body_height is None else cmd.body_height
            self.held_stand.hold(float(height), now, self.ctx.journal)  # type: ignore[arg-type]
            return
        if cmd.kind == "estop":
            self.estop(now)
        elif cmd.kind == "reset":
            self._reset(now)
        elif cmd.kind == "stop":
            self._stop(now)
        elif cmd.kind == "stand":
            height = self.defaults.body_height if cmd.body_height is None else cmd.body_height
            self.moves.stand(now, height, self._stand_height, self.resumer.active)
            self.walk.clear()
            self.resumer.clear()  # the stand replaces a due resume
            self._stand_height = float(height)
        elif cmd.kind == "sit":
            self.moves.start(now, self.sitting, SITTING, "sit")
            self.walk.clear()
            self.resumer.clear()
        elif cmd.kind == "pose":
            assert cmd.pose is not None
            self.moves.pose(now, cmd.pose, self._stand_height)
        elif cmd.kind == "walk":
            self.requests.walk(cmd, self._base(), self.moves.target, now)
        else:  # pragma: no cover - parse_gait_command only builds known kinds
            self.ctx.journal.refuse(f"unknown command {cmd.kind!r}", now)

    def estop(self, now: float | None = None) -> None:
        """Latch ESTOP: from the next tick on no motion targets (tick returns None)."""
        now = self._clock(max(self._now, 0.0) if now is None else now)
        was = self.ctx.state
        self._clear_motion()
        self.ctx.hold = None
        self.ctx.last_target = None
        self.ctx.enter(ESTOP, now)
        self.ctx.journal.event("error", f"e-stop latched (was {was}); send reset, then stand")

    def on_twist(self, vx: float, vy: float, wz: float, now: float) -> None:
        """A ``cmd_vel`` twist (m/s, m/s, rad/s); refusals raise `CommandError`.

        STANDING + non-zero: start an until-stopped walk; WALKING (cmd_vel walk) + non-zero:
        new parameters at the next slot; + zero: stop. A zero twist otherwise does nothing.
        """
        now = self._clock(now)
        try:
            self.requests.twist(vx, vy, wz, self._base(), now, self.resumer.active)
        except CommandError:
            self.ctx.journal.twist_refusals += 1  # a console tells them from its command's
            raise

    # ---------------------------------------------------------------- output
    def tick(self, now: float) -> JointTarget | None:
        """Joint targets at steady time ``now`` [s]; None in IDLE and ESTOP (publish nothing)."""
        now = self._clock(now)
        if now - self._last_tick > 1.5 / self.rate_hz and self._last_tick > -math.inf:
            self._late_ticks += 1
        self.resumer.before_tick(self._last_tick, now, self.rate_hz)
        self._last_tick = now
        self.held_stand.expire(now, self.ctx.journal)
        state = self.ctx.state
        if self.resumer.active:
            return self.resumer.tick(now)
        if state in HOLDING_STATES:
            return self.ctx.hold
        if state in WALK_STATES:
            try:
                return self.walk.tick(now, self.cmd_vel_timeout)
            except (KinematicsError, GaitError, TrajectoryError) as exc:  # pragma: no cover
                self.walk.enter_holding(now, f"tick at {now:.3f} s failed: {exc}")
                return self.ctx.hold
        if state == MOVING:
            return self.moves.tick(now)
        return None

    def plan_ahead(self, now: float | None = None) -> bool:
        """Plan and check the next slot now, ahead of its boundary; True if it planned.

        Call it between ticks: the tick at the boundary then only switches slots, and the
        ~2-10 ms of solving and checking stay off the tick. The plan is used only if its
        inputs (current slot, new walk parameters, stop request) are unchanged at the boundary;
        otherwise the tick plans as before. With ``now`` [s], nothing is planned earlier than
        `next_slot.PLAN_AHEAD_HORIZON` before the boundary; a twist arriving within it is kept
        for the slot after (`slot_inputs.SlotInputs`), so only a stop or a walk command makes
        the plan stale. This runs the planning in the caller's thread; it is the
        same as ``store_ahead(ahead_job(now).run())``, the split a multi-threaded caller uses
        to plan in another thread without holding its lock.
        """
        job = self.ahead_job(now)
        if job is None:
            return False
        self.store_ahead(job.run())
        return True

    def ahead_job(self, now: float | None = None) -> AheadJob | None:
        """The inputs of planning the next slot ahead (a private copy), or None if there is
        nothing to plan yet (see `plan_ahead`). `AheadJob.run` touches no state of the core."""
        return self.walk.ahead_job(now)

    def store_ahead(self, ahead: AheadPlan) -> bool:
        """Keep a plan made by `AheadJob.run`; False (dropped) if the slot it follows is no
        longer the current one. It is used at the boundary only if its inputs still match."""
        return self.walk.store_ahead(ahead)

    def status(self) -> dict[str, Any]:
        """State, gait, profile, step k of N, pause, resume, driver, last refusal
        (`status_report.planner_status`)."""
        return planner_status(self, self._late_ticks, self._stand_height)

    # ---------------------------------------------------------------- internals
    def _clock(self, now: float) -> float:
        now = float(now)
        if not math.isfinite(now):
            raise ValueError(f"time must be finite, got {now!r}")
        if now < self._now:  # a monotonic clock never goes back; hold the latest
            now = self._now
        self._now = now
        return now

    def _base(self) -> WalkParams:
        """Parameters a walk started from standing now would use."""
        return replace(self.defaults, body_height=self._stand_height)

    def _clear_motion(self) -> None:
        self.moves.clear()
        self.walk.clear()
        self.resumer.clear()

    def _stop(self, now: float) -> None:
        if self.ctx.state == MOVING:
            self.ctx.journal.refuse(f"stop refused: a {self.moves.target} move cannot be "
                                    f"interrupted (estop can); wait for it to end", now)
        self.walk.request_stop(now, "stop: finishing the slot, then half steps into standing")

    def _reset(self, now: float) -> None:
        if self.ctx.state != ESTOP:
            self.ctx.journal.refuse(f"reset refused: it clears a latched e-stop, and the "
                                    f"state is {self.ctx.state}", now)
        self.ctx.enter(IDLE, now)
        self.ctx.journal.event("info", "e-stop reset: IDLE; send stand")
