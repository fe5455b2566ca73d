"""The planner's state machine and per-tick joint targets (pure: no rclpy).

`PlannerCore` is driven by a monotonic time argument ``now`` [s] (steady clock in the node), so
it is deterministic to test. States::

    IDLE --stand--> MOVING --> STANDING --walk / cmd_vel--> WALKING --stop--> STOPPING --> STANDING
    IDLE / STANDING --sit--> MOVING --> SITTING --stand--> MOVING --> STANDING
    any --estop--> ESTOP (latched) --reset--> IDLE (publish nothing until a new stand)
    WALKING / STOPPING --a slot that cannot even stop--> HOLDING (holds the pose; stand or sit)

``MOVING`` is the joint-space move of ``stand`` / ``sit`` (``status()["target"]`` says which).
``paused`` (a motor-manager fault) is a flag, not a state: while it is set no new gait slot
starts (the current slot finishes, then the pose is held at the slot boundary) and no walk or
move is accepted. Every refusal raises `CommandError`, leaves the state unchanged and is
reported in `status` and `pop_events`.

Per tick the active gait slot is evaluated from coefficients prepared when the slot starts
(`_Track`: one small mat-vec), then turned into joint angles and rates by
`kinematics.inverse_kinematics` (which checks the limits) and `kinematics.joint_velocities`.
"""

from __future__ import annotations

import copy
import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass, replace
from itertools import pairwise
from typing import Any, NoReturn

import numpy as np

from crawler_motion.errors import (
    CommandError,
    ConfigError,
    GaitError,
    KinematicsError,
    TrajectoryError,
)
from crawler_motion.model.config import Config, RobotConfig
from crawler_motion.model.kinematics import check_limits, inverse_kinematics
from crawler_motion.motion.fastpath import FastKinematics
from crawler_motion.motion.gait import (
    GaitSequencer,
    Slot,
    WalkParams,
    check_trajectories,
    plan_walk,
    standing_pose,
    validate_params,
)
from crawler_motion.motion.trajectory import Piecewise, rest_segment
from crawler_motion.planner.commands import (
    Command,
    finite_float,
    is_zero_twist,
    parse_gait_command,
    twist_to_params,
)

IDLE = "IDLE"
MOVING = "MOVING"
STANDING = "STANDING"
WALKING = "WALKING"
STOPPING = "STOPPING"
SITTING = "SITTING"
HOLDING = "HOLDING"
ESTOP = "ESTOP"
STATES: tuple[str, ...] = (IDLE, MOVING, STANDING, WALKING, STOPPING, SITTING, HOLDING, ESTOP)

#: Shortest stand / sit move [s].
MIN_MOVE_TIME = 1.0
#: Peak joint speed of a stand / sit move as a fraction of the joint's velocity limit.
MOVE_SPEED_FRACTION = 0.5
#: Peak speed of a rest sextic (v = a = 0 at both ends) in units of distance / duration.
REST_PEAK_SPEED = 1.875
#: A measurement older than this [s] cannot start a stand / sit move.
MEASUREMENT_MAX_AGE = 1.0
#: `PlannerCore.plan_ahead(now)` plans the next slot at most this long before its boundary [s].
PLAN_AHEAD_HORIZON = 0.2
#: Measured angles up to this far outside a limit [rad] start a move from the limit.
MEASURED_LIMIT_TOLERANCE = 0.02
#: A finite walk is checked up front with `plan_walk` for at most this many steps: the steady
#: state of a walk with fixed parameters is periodic with one step, so a longer walk consists
#: of the same slots (checked again, one by one, before each starts).
UPFRONT_CHECK_STEPS = 3
#: Up-front check results remembered (by walk parameters and steps).
UPFRONT_CACHE_SIZE = 64
#: Sitting: feet this fraction of the way from the coxa to the standing reach (tucked).
SIT_REACH_FRACTIONS: tuple[float, ...] = (0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
#: Margin [rad] a sitting pose keeps from every joint limit.
SIT_LIMIT_MARGIN = 0.05


@dataclass(frozen=True, slots=True)
class JointTarget:
    """Joint positions [rad] and velocities [rad/s], ``(12,)`` each, in joint-name order."""

    positions: np.ndarray
    velocities: np.ndarray


class _Track:
    """Rows of piecewise polynomials re-expressed on one common time grid.

    Every interval between the breakpoints of all rows holds a ``(2 rows, 7)`` matrix: the
    position and velocity polynomials of every row in the interval's normalised time
    ``v = (tau - start) / length``. Evaluation is one `bisect`, one `np.power` and one
    `np.dot` into preallocated buffers: no per-tick allocation except the result views.
    """

    __slots__ = ("_exps", "_inv_len", "_mats", "_out", "_pw", "_starts", "duration", "rows")
    DEGREE = 6

    def __init__(self, pieces: Sequence[Piecewise]) -> None:
        width = self.DEGREE + 1
        t0 = pieces[0].t0
        raw = np.unique(np.concatenate([p.breaks - p.t0 for p in pieces]))
        breaks = [float(raw[0])]
        for b in raw[1:]:
            if b - breaks[-1] > 1e-12:
                breaks.append(float(b))
        self.duration = breaks[-1]
        self.rows = sum(p.coeffs.shape[1] for p in pieces)
        starts, inv_len, mats = [], [], []
        j = np.arange(width)
        for s, e in pairwise(breaks):
            length = e - s
            blocks = []
            for p in pieces:
                k = int(p.index(t0 + (s + e) / 2))
                seg_t0 = float(p.breaks[k]) - t0
                dur = float(p.durations[k])
                c = p.segments[k].coeffs
                if c.shape[1] > width:
                    raise TrajectoryError(f"segment of degree {c.shape[1] - 1} > {self.DEGREE}")
                c = np.pad(c, ((0, 0), (0, width - c.shape[1])))
                a = (s - seg_t0) / dur
                h = length / dur
                # g_j = sum_i c_i binom(i, j) a^(i - j) h^j  (u = a + h v)
                basis = np.zeros((width, width))
                for i in range(width):
                    for jj in range(i + 1):
                        basis[i, jj] = math.comb(i, jj) * a ** (i - jj) * h ** jj
                blocks.append(c @ basis)
            g = np.concatenate(blocks)  # (rows, width)
            vel = np.zeros_like(g)
            vel[:, :-1] = g[:, 1:] * j[1:] / length
            starts.append(s)
            inv_len.append(1.0 / length)
            mats.append(np.ascontiguousarray(np.concatenate((g, vel))))
        self._starts = starts
        self._inv_len = inv_len
        self._mats = mats
        self._exps = np.arange(width, dtype=float)
        self._pw = np.empty(width)
        self._out = np.empty(2 * self.rows)

    def evaluate(self, tau: float) -> np.ndarray:
        """Positions then velocities ``(2 rows,)`` at ``tau`` [s] (clamped to the span).

        Returns an internal buffer, overwritten by the next call.
        """
        i = bisect_right(self._starts, tau) - 1
        if i < 0:
            i = 0
        v = (tau - self._starts[i]) * self._inv_len[i]
        v = 0.0 if v < 0.0 else (1.0 if v > 1.0 else v)
        np.power(v, self._exps, out=self._pw)
        np.dot(self._mats[i], self._pw, out=self._out)
        return self._out


@dataclass(frozen=True)
class _Ahead:
    """The next slot planned ahead of its boundary, with the inputs it was planned from."""

    after: Slot | None
    pending: WalkParams | None
    stopping: bool
    slot: Slot | None
    seq: GaitSequencer | None
    error: str | None
    track: _Track | None

    def matches(self, after: Slot | None, pending: WalkParams | None, stopping: bool) -> bool:
        """True if planned after slot ``after`` with these parameters and stop flag."""
        return self.after is after and self.pending is pending and self.stopping == stopping


def _plan_next(robot: RobotConfig, trial: GaitSequencer, params: WalkParams | None,
               stopping: bool) -> tuple[Slot | None, GaitSequencer | None, str | None]:
    """Plan and check the next slot on ``trial`` (a copy of the walk's sequencer).

    Returns ``(slot, trial, None)`` or ``(None, None, reason)``; None slot: nothing left."""
    try:
        if params is not None:
            trial.set_params(params)
        slot = trial.next_slot(stopping=stopping)
        if slot is not None:
            check_trajectories(robot, slot.legs, f"the next ({slot.kind}) slot")
    except (GaitError, KinematicsError, TrajectoryError) as exc:
        return None, None, str(exc)
    return slot, trial, None


@dataclass(frozen=True)
class AheadJob:
    """Planning of the next slot ahead of its boundary, detached from the core: `run` uses
    only these fields (``seq`` is a private copy), so it may run without the caller's lock."""

    robot: RobotConfig
    seq: GaitSequencer
    after: Slot
    pending: WalkParams | None
    stopping: bool

    def run(self) -> _Ahead:
        """Plan, check and prepare the evaluator of the next slot (~2-4 ms)."""
        slot, seq, error = _plan_next(self.robot, self.seq, self.pending, self.stopping)
        track = _Track(slot.legs) if slot is not None and error is None else None
        return _Ahead(self.after, self.pending, self.stopping, slot, seq, error, track)


def sitting_pose(cfg: Config) -> np.ndarray:
    """Sitting joint angles ``(n_legs, 3)`` [rad]: body at the minimum height, legs tucked.

    Feet along each leg's neutral direction, as close to the coxa as `SIT_REACH_FRACTIONS`
    allows with every joint at least `SIT_LIMIT_MARGIN` inside its limits.
    """
    robot = cfg.robot
    height = robot.body_height_range[0]
    for fraction in SIT_REACH_FRACTIONS:
        reach = robot.l1 + fraction * (robot.reach - robot.l1)
        feet = robot.hips.copy()
        feet[:, 0] += reach * np.cos(robot.neutral_yaw)
        feet[:, 1] += reach * np.sin(robot.neutral_yaw)
        feet[:, 2] = robot.hips[:, 2] - height
        try:
            q = inverse_kinematics(robot, feet)
        except KinematicsError:
            continue
        if np.all(q >= robot.lower + SIT_LIMIT_MARGIN) and np.all(
                q <= robot.upper - SIT_LIMIT_MARGIN):
            return q
    raise ConfigError(f"no sitting pose at body height {height} m with the legs tucked lies "
                      f"{SIT_LIMIT_MARGIN} rad inside the joint limits; check robot.yaml")


def move_duration(cfg: Config, start: np.ndarray, end: np.ndarray) -> float:
    """Duration [s] of a rest-sextic joint move keeping every joint at or below
    `MOVE_SPEED_FRACTION` of its velocity limit, at least `MIN_MOVE_TIME`."""
    distance = np.abs(np.asarray(end, dtype=float) - np.asarray(start, dtype=float))
    limit = MOVE_SPEED_FRACTION * cfg.robot.velocity
    return max(MIN_MOVE_TIME, float(np.max(REST_PEAK_SPEED * distance / limit)))


class PlannerCore:
    """Planner state machine; see the module docstring.

    ``rate_hz`` is the tick rate the caller intends (used to count late ticks);
    ``defaults`` the walk parameters of a new walk (gait defaults; config defaults if None);
    ``cmd_vel_timeout`` [s] stops a cmd_vel-started walk when twists stop arriving.
    """

    def __init__(self, cfg: Config, rate_hz: float = 100.0, *,
                 defaults: WalkParams | None = None, cmd_vel_timeout: float = 0.5,
                 measurement_max_age: float = MEASUREMENT_MAX_AGE) -> None:
        self.cfg = cfg
        self.robot = cfg.robot
        self._fast_kin = FastKinematics(cfg.robot)
        self.n_joints = 3 * self.robot.n_legs
        self.rate_hz = rate_hz
        self.set_rate(rate_hz)
        self.set_cmd_vel_timeout(cmd_vel_timeout)
        self.measurement_max_age = float(measurement_max_age)
        self.defaults = WalkParams.defaults(cfg.gait)
        self.set_defaults(defaults if defaults is not None else self.defaults)
        self.sitting = sitting_pose(cfg)
        self.state = IDLE
        self.paused = False
        self.pause_reason = ""
        self._zero = np.zeros(self.n_joints)
        self._zero.setflags(write=False)
        self._lo = self.robot.lower_limits().reshape(-1).copy()
        self._hi = self.robot.upper_limits().reshape(-1).copy()
        self._measured: np.ndarray | None = None
        self._measured_at = -math.inf
        self._stand_height = self.robot.body_height
        self._hold: JointTarget | None = None
        self._last_target: JointTarget | None = None
        # joint-space move
        self._move: _Track | None = None
        self._move_t0 = 0.0
        self._move_end_state = STANDING
        self._move_final = self._zero
        self._move_target = ""
        # walk
        self._seq: GaitSequencer | None = None
        self._slot: Slot | None = None
        self._slot_t0 = 0.0
        self._track: _Track | None = None
        self._params: WalkParams | None = None
        self._pending: WalkParams | None = None
        self._pending_steps: tuple[int | None] | None = None
        self._stop_requested = False
        self._steps_total: int | None = None
        self._steady_planned = 0
        self._steady_done = 0
        self._walk_groups = 1  # groups of the gait of the current / last walk
        self._source: str | None = None
        self._waiting = False
        self._last_twist = -math.inf
        # status
        self._now = -math.inf
        self._last_tick = -math.inf
        self._stamp = 0.0
        self._revision = 0
        self._refusals = 0
        self._late_ticks = 0
        self._last_refusal: str | None = None
        self._last_event: str | None = None
        self._events: list[tuple[str, str]] = []
        self._upfront: dict[tuple[WalkParams, int], str | None] = {}
        self._ahead: _Ahead | None = None

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
        """The latest measured joint angles (12 or (n_legs, 3)) [rad], at steady time ``now``."""
        q = np.array(positions, dtype=float).reshape(self.robot.n_legs, 3)
        if not np.all(np.isfinite(q)):
            raise CommandError("measured joint angles contain NaN or inf")
        self._measured = q
        self._measured_at = float(now)

    def set_paused(self, paused: bool, now: float, reason: str = "") -> None:
        """Pause (motor-manager fault) or resume; see the module docstring."""
        paused = bool(paused)
        if paused == self.paused and (not paused or reason == self.pause_reason):
            return
        was = self.paused
        self.paused = paused
        self.pause_reason = reason if paused else ""
        self._touch(now)
        if paused and not was:
            self._event("warn", f"paused: motor manager fault ({reason or 'no reason given'}); "
                                f"no new gait slot starts until it clears")
        elif not paused:
            self._event("info", "pause cleared: motor manager OK again")

    def submit(self, text: str, now: float) -> Command:
        """Parse and execute one ``gait_command`` JSON text; refusals raise `CommandError`."""
        try:
            cmd = parse_gait_command(text, self.cfg)
        except CommandError as exc:
            self._refuse(str(exc), now)
        self.command(cmd, now)
        return cmd

    def record_refusal(self, reason: str, now: float) -> None:
        """Record a refusal decided elsewhere (e.g. a bad parameter set) in the status."""
        self._last_refusal = reason
        self._refusals += 1
        self._touch(now)
        self._event("warn", f"refused: {reason}")

    def command(self, cmd: Command, now: float) -> None:
        """Execute a parsed command at ``now``; refusals raise `CommandError`."""
        now = self._clock(now)
        if cmd.kind == "estop":
            self.estop(now)
        elif cmd.kind == "reset":
            self._reset(now)
        elif cmd.kind == "stop":
            self._stop(now)
        elif cmd.kind == "stand":
            height = self.defaults.body_height if cmd.body_height is None else cmd.body_height
            pose = standing_pose(self.cfg, height)
            self._start_move(now, pose, STANDING, "stand", height)
        elif cmd.kind == "sit":
            self._start_move(now, self.sitting, SITTING, "sit", None)
        elif cmd.kind == "walk":
            self._walk(cmd, now)
        else:  # pragma: no cover - parse_gait_command only builds known kinds
            self._refuse(f"unknown command {cmd.kind!r}", now)

    def estop(self, now: float | None = None) -> None:
        """Latch ESTOP: from the next tick on no motion targets (tick returns None)."""
        now = self._clock(max(self._now, 0.0) if now is None else now)
        was = self.state
        self._clear_motion()
        self._hold = None
        self._last_target = None
        self.state = ESTOP
        self._touch(now)
        self._event("error", f"e-stop latched (was {was}); send reset, then stand")

    def on_twist(self, vx: float, vy: float, wz: float, now: float) -> None:
        """A ``cmd_vel`` twist (m/s, m/s, rad/s); refusals raise `CommandError`.

        STANDING + non-zero: start an until-stopped walk; WALKING (cmd_vel walk) + non-zero:
        new parameters at the next slot; + zero: stop. A zero twist otherwise does nothing.
        """
        now = self._clock(now)
        for name, value in (("linear.x", vx), ("linear.y", vy), ("angular.z", wz)):
            if finite_float(value) is None:
                self._refuse(f"cmd_vel {name} must be a finite number, got {value!r:.40}", now)
        zero = is_zero_twist(vx, vy, wz)
        if self.state == WALKING and self._source == "cmd_vel":
            if zero:
                self._last_twist = now
                self._request_stop(now, "zero cmd_vel: stopping into standing")
                return
            base = self._pending or self._params
            assert base is not None
            try:
                params = twist_to_params(vx, vy, wz, self.cfg, base)
            except CommandError as exc:
                self._refuse(str(exc), now)
            self._last_twist = now
            if params != (self._pending or self._params):
                self._pending = params
            return
        if zero:
            return
        if self.state != STANDING:
            hint = ("send stop first" if self.state == WALKING
                    else "wait for STANDING" if self.state in (STOPPING, MOVING)
                    else "send stand first")
            self._refuse(f"cmd_vel ignored in state {self.state}: {hint}", now)
        if self.paused:
            self._refuse(self._paused_reason(), now)
        base = replace(self.defaults, body_height=self._stand_height)
        try:
            params = twist_to_params(vx, vy, wz, self.cfg, base)
        except CommandError as exc:
            self._refuse(str(exc), now)
        self._check_upfront(params, 1, now)
        self._start_walk(params, None, "cmd_vel", now)
        self._last_twist = now

    # ---------------------------------------------------------------- output
    def tick(self, now: float) -> JointTarget | None:
        """Joint targets at steady time ``now`` [s]; None in IDLE and ESTOP (publish nothing)."""
        now = self._clock(now)
        if now - self._last_tick > 1.5 / self.rate_hz and self._last_tick > -math.inf:
            self._late_ticks += 1
        self._last_tick = now
        state = self.state
        if state in (STANDING, SITTING, HOLDING):
            return self._hold
        if state in (WALKING, STOPPING):
            try:
                return self._tick_walk(now)
            except (KinematicsError, GaitError, TrajectoryError) as exc:  # pragma: no cover
                self._enter_holding(now, f"tick at {now:.3f} s failed: {exc}")
                return self._hold
        if state == MOVING:
            return self._tick_move(now)
        return None

    def plan_ahead(self, now: float | None = None) -> bool:
        """Plan and check the next slot now, ahead of its boundary; True if it planned.

        Call it between ticks: the tick at the boundary then only switches slots, and the
        ~2-4 ms of solving and checking stay off the tick. The plan is used only if its inputs
        (current slot, new walk parameters, stop request) are unchanged at the boundary;
        otherwise the tick plans as before. With ``now`` [s], nothing is planned earlier than
        `PLAN_AHEAD_HORIZON` before the boundary, so a stream of changing twists is not
        re-planned on every tick. Same as ``store_ahead(ahead_job(now).run())``, the split
        a multi-threaded caller uses to plan without holding its lock.
        """
        job = self.ahead_job(now)
        if job is None:
            return False
        self.store_ahead(job.run())
        return True

    def ahead_job(self, now: float | None = None) -> AheadJob | None:
        """The inputs of planning the next slot ahead (a private copy), or None if there is
        nothing to plan yet (see `plan_ahead`). `AheadJob.run` touches no state of the core."""
        if (self.state not in (WALKING, STOPPING) or self._waiting or self._seq is None
                or self._slot is None or self._seq.standing):
            return None
        if now is not None and (self._slot_t0 + self._slot.duration - float(now)
                                > PLAN_AHEAD_HORIZON):
            return None
        stopping, pending = self._next_inputs()
        if self._ahead is not None and self._ahead.matches(self._slot, pending, stopping):
            return None
        return AheadJob(self.robot, copy.copy(self._seq), self._slot, pending, stopping)

    def store_ahead(self, ahead: _Ahead) -> bool:
        """Keep a plan made by `AheadJob.run`; False (dropped) if the slot it follows is no
        longer the current one. It is used at the boundary only if its inputs still match."""
        if ahead.after is None or ahead.after is not self._slot:
            return False
        self._ahead = ahead
        return True

    def status(self) -> dict[str, Any]:
        """State, gait, profile, step k of N (k full gait cycles done), pause, last refusal."""
        params = self._params if self._params is not None else self.defaults
        return {
            "state": self.state,
            "target": self._move_target if self.state == MOVING else None,
            "gait": params.gait,
            "profile": params.profile,
            "step": self._steady_done // self._walk_groups,
            "steps": self._steps_total,
            "source": self._source,
            "phase": self._seq.phase if self._seq is not None else None,
            "paused": self.paused,
            "pause_reason": self.pause_reason or None,
            "body_height": self._stand_height,
            "last_refusal": self._last_refusal,
            "refusals": self._refusals,
            "last_event": self._last_event,
            "late_ticks": self._late_ticks,
            "revision": self._revision,
            "stamp": self._stamp,
        }

    @property
    def revision(self) -> int:
        """Incremented on every change of `status` (except ``late_ticks``)."""
        return self._revision

    @property
    def walk_params(self) -> WalkParams | None:
        """Parameters of the slot being walked (None when not walking)."""
        return self._params

    def pop_events(self) -> list[tuple[str, str]]:
        """Events since the last call, as ``(level, message)``; level info, warn or error."""
        events, self._events = self._events, []
        return events

    # ---------------------------------------------------------------- internals
    def _clock(self, now: float) -> float:
        now = float(now)
        if not math.isfinite(now):
            raise ValueError(f"time must be finite, got {now!r}")
        if now < self._now:  # a monotonic clock never goes back; hold the latest
            now = self._now
        self._now = now
        return now

    def _touch(self, now: float) -> None:
        self._revision += 1
        self._stamp = float(now)

    def _event(self, level: str, message: str) -> None:
        self._last_event = message
        self._events.append((level, message))
        del self._events[:-100]

    def _refuse(self, reason: str, now: float) -> NoReturn:
        self.record_refusal(reason, now)
        raise CommandError(reason)

    def _paused_reason(self) -> str:
        return (f"paused: motor manager fault ({self.pause_reason or 'no reason given'}); "
                f"retry when it clears")

    def _clear_motion(self) -> None:
        self._move = None
        self._seq = None
        self._slot = None
        self._track = None
        self._params = None
        self._pending = None
        self._pending_steps = None
        self._stop_requested = False
        self._waiting = False
        self._ahead = None

    def _hold_pose(self, positions: np.ndarray) -> JointTarget:
        pos = np.array(positions, dtype=float).reshape(self.n_joints)
        pos.setflags(write=False)
        return JointTarget(pos, self._zero)

    # stand / sit ------------------------------------------------------------
    def _start_move(self, now: float, pose: np.ndarray, end_state: str, what: str,
                    height: float | None) -> None:
        if self.state == ESTOP:
            self._refuse(f"{what} refused: e-stop latched; send reset, then stand", now)
        if self.state in (WALKING, STOPPING):
            self._refuse(f"{what} refused while {self.state}: send stop and wait for STANDING",
                         now)
        if self.state == MOVING:
            self._refuse(f"{what} refused: a {self._move_target} move is in progress; wait for "
                         f"it to end", now)
        if self.paused:
            self._refuse(f"{what} refused: {self._paused_reason()}", now)
        if self._measured is None:
            self._refuse(f"{what} refused: no measured joint_states yet; the move starts from "
                         f"the measured pose", now)
        age = now - self._measured_at
        if age > self.measurement_max_age:
            self._refuse(f"{what} refused: the last joint_states is {age:.2f} s old (max "
                         f"{self.measurement_max_age:g} s); is the driver running?", now)
        start = self._measured
        lo, hi = self.robot.lower_limits(), self.robot.upper_limits()
        outside = (start < lo - MEASURED_LIMIT_TOLERANCE) | (start > hi + MEASURED_LIMIT_TOLERANCE)
        if np.any(outside):
            try:
                check_limits(self.robot, start)
            except KinematicsError as exc:
                self._refuse(f"{what} refused: measured {exc}; move the joint inside its "
                             f"limits first", now)
        start = np.clip(start, lo, hi)
        duration = move_duration(self.cfg, start, pose)
        segment = rest_segment(start.reshape(-1), np.asarray(pose).reshape(-1), duration, what)
        was = self.state
        self._clear_motion()
        self._move = _Track([Piecewise([segment])])
        self._move_t0 = now
        self._move_end_state = end_state
        self._move_final = np.array(pose, dtype=float).reshape(-1)
        self._move_target = what
        if height is not None:
            self._stand_height = float(height)
        self.state = MOVING
        self._touch(now)
        self._event("info", f"{what}: {duration:.2f} s joint move from {was}")

    def _tick_move(self, now: float) -> JointTarget:
        assert self._move is not None
        tau = now - self._move_t0
        if tau >= self._move.duration:
            self._hold = self._hold_pose(self._move_final)
            self.state = self._move_end_state
            self._move = None
            self._touch(now)
            self._event("info", f"{self._move_target} done: {self.state}")
            return self._hold
        out = self._move.evaluate(tau)
        n = self.n_joints
        pos = np.clip(out[:n], self._lo, self._hi)
        target = JointTarget(pos, out[n:].copy())
        self._last_target = target
        return target

    # walk ---------------------------------------------------------------------
    def _check_upfront(self, params: WalkParams, steps: int, now: float) -> None:
        """`plan_walk` check (tens of ms), cached: a joystick held still repeats its twist."""
        key = (params, min(steps, UPFRONT_CHECK_STEPS))
        if key not in self._upfront:
            try:
                plan_walk(self.cfg, params, key[1])
                self._upfront[key] = None
            except (GaitError, KinematicsError, TrajectoryError) as exc:
                self._upfront[key] = str(exc)
            if len(self._upfront) > UPFRONT_CACHE_SIZE:
                del self._upfront[next(iter(self._upfront))]
        error = self._upfront[key]
        if error is not None:
            self._refuse(f"walk refused as a whole: {error}", now)

    def _walk(self, cmd: Command, now: float) -> None:
        state = self.state
        if state not in (STANDING, WALKING):
            hint = {ESTOP: "e-stop latched; send reset, then stand",
                    STOPPING: "stopping; wait for STANDING",
                    MOVING: f"a {self._move_target} move is in progress; wait for it to end"}
            self._refuse(f"walk refused in state {state}: "
                         f"{hint.get(state, 'send stand first')}", now)
        if state == STANDING:
            if self.paused:
                self._refuse(f"walk refused: {self._paused_reason()}", now)
            base = replace(self.defaults, body_height=self._stand_height)
        else:
            base = self._pending or self._params
            assert base is not None
        params = self._apply(cmd, base, now)
        if state == WALKING:
            assert self._params is not None
            if params.gait != self._params.gait:
                self._refuse(f"walk refused: the gait can only change while standing "
                             f"({self._params.gait} -> {params.gait}); send stop first", now)
        self._check_upfront(params, cmd.steps or 1, now)
        if state == STANDING:
            self._start_walk(params, cmd.steps, "command", now)
            return
        self._pending = params
        self._pending_steps = (cmd.steps,)
        self._source = "command"
        self._touch(now)
        self._event("info", f"walk parameters change at the next slot boundary "
                            f"({cmd.steps or 'until stopped'} steps)")

    def _apply(self, cmd: Command, base: WalkParams, now: float) -> WalkParams:
        try:
            return cmd.apply(base, self.cfg)
        except CommandError as exc:
            self._refuse(str(exc), now)

    def _start_walk(self, params: WalkParams, steps: int | None, source: str, now: float
                    ) -> None:
        seq = GaitSequencer(self.cfg, params)
        try:
            slot = seq.next_slot(stopping=False)
            assert slot is not None
            check_trajectories(self.robot, slot.legs, "the first slot")
        except (GaitError, KinematicsError, TrajectoryError) as exc:
            self._refuse(f"walk refused: {exc}", now)
        self._clear_motion()
        self._seq = seq
        self._params = params
        self._steps_total = steps
        self._steady_planned = 0
        self._steady_done = 0
        self._walk_groups = seq.n_groups
        self._source = source
        self.state = WALKING
        self._commit(slot, seq, now)
        self._event("info", f"walk ({source}): {params.gait}/{params.profile}, stride "
                            f"{params.stride:g} m, heading {params.heading:g} rad, turn "
                            f"{params.turn:g} rad/step, "
                            f"{steps if steps is not None else 'until stopped'} steps")

    def _commit(self, slot: Slot, seq: GaitSequencer, t0: float,
                track: _Track | None = None) -> None:
        self._seq = seq
        self._slot = slot
        self._slot_t0 = t0
        self._track = track if track is not None else _Track(slot.legs)
        self._ahead = None
        self._params = slot.params
        if slot.kind == "steady":
            self._steady_planned += 1
        self._touch(t0)

    def _request_stop(self, now: float, why: str) -> None:
        if self.state != WALKING:
            return
        self.state = STOPPING
        self._stop_requested = True
        self._pending = None
        self._pending_steps = None
        self._touch(now)
        self._event("info", why)

    def _stop(self, now: float) -> None:
        if self.state == MOVING:
            self._refuse(f"stop refused: a {self._move_target} move cannot be interrupted "
                         f"(estop can); wait for it to end", now)
        self._request_stop(now, "stop: finishing the slot, then half steps into standing")

    def _reset(self, now: float) -> None:
        if self.state != ESTOP:
            self._refuse(f"reset refused: it clears a latched e-stop, and the state is "
                         f"{self.state}", now)
        self.state = IDLE
        self._touch(now)
        self._event("info", "e-stop reset: IDLE; send stand")

    def _try_slot(self, params: WalkParams | None, stopping: bool
                  ) -> tuple[Slot | None, GaitSequencer | None, str | None]:
        assert self._seq is not None
        return _plan_next(self.robot, copy.copy(self._seq), params, stopping)

    def _plan_slot(self, t0: float) -> bool:
        """Plan, check and start the next slot at ``t0``; False if none started."""
        assert self._seq is not None
        if self._pending_steps is not None:
            self._steps_total = self._pending_steps[0]
            self._steady_planned = 0
            self._steady_done = 0
            self._pending_steps = None
        stopping, pending = self._next_inputs()
        self._pending = None
        ahead, self._ahead = self._ahead, None
        track = None
        if ahead is not None and ahead.matches(self._slot, pending, stopping):
            slot, seq, error, track = ahead.slot, ahead.seq, ahead.error, ahead.track
        else:
            slot, seq, error = self._try_slot(pending, stopping)
        if error is not None:
            track = None
            self._event("error", f"slot check failed: {error}; stopping into standing")
            slot, seq, error = self._try_slot(None, True)
            if error is not None:
                self._enter_holding(t0, f"cannot stop either ({error})", self._slot_end_pose())
                return False
            stopping = True
            self._stop_requested = True
        if slot is None or seq is None:  # already standing: nothing left to walk
            self._finish_walk(t0)
            return False
        if stopping and self.state == WALKING:
            self.state = STOPPING
        self._commit(slot, seq, t0, track)
        return True

    def _next_inputs(self) -> tuple[bool, WalkParams | None]:
        """(stopping, new parameters) of the next slot as things stand (mutates nothing)."""
        assert self._seq is not None
        if self._pending_steps is not None:
            steps_total, steady_planned = self._pending_steps[0], 0
        else:
            steps_total, steady_planned = self._steps_total, self._steady_planned
        stopping = self._stop_requested or (
            steps_total is not None and self._seq.phase == "steady"
            and steady_planned >= steps_total * self._seq.n_groups)
        return stopping, (None if stopping else self._pending)

    def _slot_end_pose(self) -> np.ndarray:
        assert self._track is not None
        out = self._track.evaluate(self._track.duration)
        return inverse_kinematics(self.robot, out[:self.n_joints].reshape(-1, 3))

    def _finish_walk(self, now: float) -> None:
        self._hold = self._hold_pose(self._slot_end_pose())
        self._clear_motion()
        self.state = STANDING
        self._touch(now)
        self._event("info", "walk done: STANDING")

    def _enter_holding(self, now: float, why: str, pose: np.ndarray | None = None) -> None:
        if pose is None:
            last = self._last_target if self._last_target is not None else self._hold
            assert last is not None
            pose = last.positions
        self._hold = self._hold_pose(pose)
        self._clear_motion()
        self.state = HOLDING
        self._touch(now)
        self._event("error", f"holding the pose: {why}; send stand (or sit) to recover")

    def _tick_walk(self, now: float) -> JointTarget | None:
        assert self._slot is not None and self._seq is not None
        if (self.state == WALKING and self._source == "cmd_vel"
                and now - self._last_twist > self.cmd_vel_timeout):
            self._request_stop(now, f"cmd_vel timeout ({self.cmd_vel_timeout:g} s without a "
                                    f"twist): stopping into standing")
        if self._waiting:
            if self.paused:
                return self._hold
            self._waiting = False
            if not self._plan_slot(now):
                return self._hold
        end = self._slot_t0 + self._slot.duration
        while now >= end:
            slot = self._slot
            if slot.kind == "steady":
                self._steady_done += 1
                self._touch(end)
            if self._seq.standing:
                self._finish_walk(end)
                return self._hold
            if self.paused:
                self._hold = self._hold_pose(self._slot_end_pose())
                self._waiting = True
                self._touch(end)
                self._event("warn", "paused at a slot boundary: holding until the fault "
                                    "clears")
                return self._hold
            if not self._plan_slot(end):
                return self._hold
            end = self._slot_t0 + self._slot.duration
        assert self._track is not None
        out = self._track.evaluate(now - self._slot_t0)
        n = self.n_joints
        try:  # plain-float IK + Jacobian: same numbers and errors as the numpy functions
            values = out.tolist()
            q, qd = self._fast_kin.solve(values[:n], values[n:])
        except KinematicsError as exc:
            self._enter_holding(now, f"tick at {now:.3f} s failed: {exc}")
            return self._hold
        target = JointTarget(np.array(q), np.array(qd))
        self._last_target = target
        return target
