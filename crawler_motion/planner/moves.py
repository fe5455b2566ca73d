"""Stand, sit and pose moves: rest-sextic joint-space moves from the measured pose to a fixed
pose, and body-pose moves (`pose_move.PoseMove`: every foot fixed on the ground) while
standing."""

from __future__ import annotations

import math

import numpy as np

from crawler_motion.errors import CommandError, ConfigError, KinematicsError, PoseError
from crawler_motion.model.config import Config, RobotConfig
from crawler_motion.model.kinematics import check_limits, inverse_kinematics
from crawler_motion.motion.body_pose import NEUTRAL, BodyPose
from crawler_motion.motion.fastpath import Track
from crawler_motion.motion.gait import standing_pose
from crawler_motion.motion.trajectory import REST_PEAK_SPEED, Piecewise, rest_segment
from crawler_motion.planner.context import JointTarget, PlannerContext
from crawler_motion.planner.pose_move import PoseMove
from crawler_motion.planner.state import ESTOP, MOVING, STANDING, WALK_STATES, PlannerState

#: Shortest stand / sit move [s].
MIN_MOVE_TIME = 1.0
#: Peak joint speed of a stand / sit move as a fraction of the joint's velocity limit.
MOVE_SPEED_FRACTION = 0.5
#: A measurement older than this [s] cannot start a stand / sit move.
MEASUREMENT_MAX_AGE = 1.0
#: Measured angles up to this far outside a limit [rad] start a move from the limit.
MEASURED_LIMIT_TOLERANCE = 0.02
#: Sitting: feet this fraction of the way from the coxa to the standing reach (tucked).
SIT_REACH_FRACTIONS: tuple[float, ...] = (0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
#: Margin [rad] a sitting pose keeps from every joint limit.
SIT_LIMIT_MARGIN = 0.05


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


def outside_tolerance(robot: RobotConfig, measured: np.ndarray) -> bool:
    """True if a measured angle [rad] lies beyond `MEASURED_LIMIT_TOLERANCE` of its limits."""
    lo, hi = robot.lower_limits(), robot.upper_limits()
    return bool(np.any((measured < lo - MEASURED_LIMIT_TOLERANCE)
                       | (measured > hi + MEASURED_LIMIT_TOLERANCE)))


class JointMove:
    """A stand / sit move in progress: from ``start`` to ``pose`` (``(n_legs, 3)`` [rad],
    ``start`` clipped into the limits) starting at ``t0`` [s], ending in ``end_state``;
    ``target`` names it ("stand" or "sit")."""

    def __init__(self, cfg: Config, start: np.ndarray, pose: np.ndarray, t0: float,
                 end_state: PlannerState, target: str) -> None:
        robot = cfg.robot
        start = np.clip(start, robot.lower_limits(), robot.upper_limits())
        self.duration = move_duration(cfg, start, pose)
        final = np.asarray(pose, dtype=float).reshape(-1)
        segment = rest_segment(start.reshape(-1), final, self.duration, target)
        self._track = Track([Piecewise([segment])], dims=final.size)
        self._lo = robot.lower_limits().reshape(-1).copy()
        self._hi = robot.upper_limits().reshape(-1).copy()
        self.t0 = float(t0)
        self.end_state = end_state
        self.final = final
        self.target = target

    def done(self, now: float) -> bool:
        """True from the end of the move on."""
        return now - self.t0 >= self._track.duration

    def at(self, now: float) -> JointTarget:
        """Joint targets at steady time ``now`` [s] (within the limits)."""
        pos, vel = self._track.evaluate(now - self.t0)
        return JointTarget(np.clip(np.array(pos), self._lo, self._hi), np.array(vel))


class MoveController:
    """Starts (or refuses) stand / sit moves from the latest measured pose and pose moves from
    the held pose, and evaluates the move in progress per tick, ending it in its end state via
    ``ctx`` (which also keeps the body pose, ``ctx.body_pose``).

    ``measurement_max_age`` [s] is the oldest measurement a move starts from.
    """

    def __init__(self, cfg: Config, ctx: PlannerContext, measurement_max_age: float) -> None:
        self.cfg = cfg
        self.ctx = ctx
        self.measurement_max_age = float(measurement_max_age)
        self.move: JointMove | PoseMove | None = None
        self._target = ""
        self._measured: np.ndarray | None = None
        self._measured_at = -math.inf

    @property
    def target(self) -> str:
        """What the current (or last) move does: "stand", "sit", "pose" ("" before the
        first)."""
        return self._target

    def clear(self) -> None:
        """Abandon the move in progress."""
        self.move = None

    def interrupt(self, at: float) -> JointMove | None:
        """Take the move in progress off at steady time ``at`` [s] (an interruption): a stand /
        sit move is returned, to be resumed; a pose move ends where its last target was, in
        STANDING at that pose (it never restarts by itself)."""
        move, self.move = self.move, None
        if isinstance(move, PoseMove):
            self.ctx.body_pose = move.current
            self.ctx.enter(STANDING, at)
            return None
        return move

    def set_measured(self, positions: np.ndarray, now: float) -> None:
        """The latest measured joint angles (12 or (n_legs, 3)) [rad], at steady time ``now``."""
        q = np.array(positions, dtype=float).reshape(self.cfg.robot.n_legs, 3)
        if not np.all(np.isfinite(q)):
            raise CommandError("measured joint angles contain NaN or inf")
        self._measured = q
        self._measured_at = float(now)

    def fresh_measured(self, now: float, since: float = -math.inf) -> np.ndarray | None:
        """The measured pose ``(n_legs, 3)`` [rad] if at most ``measurement_max_age`` old at
        ``now`` [s] and taken after ``since`` [s], else None."""
        if (self._measured is None or now - self._measured_at > self.measurement_max_age
                or self._measured_at <= since):
            return None
        return self._measured.copy()

    def resume(self, now: float, measured: np.ndarray, final: np.ndarray,
               end_state: PlannerState, what: str) -> JointMove:
        """Start a move from ``measured`` to ``final`` [rad] at ``now`` [s] regardless of the
        state (a resume after an interruption); it ends in ``end_state``."""
        move = JointMove(self.cfg, measured, np.reshape(final, (-1, 3)), now, end_state, what)
        self.move = move
        self._target = what
        self.ctx.enter(MOVING, now)
        self.ctx.journal.event("info", f"{what}: {move.duration:.2f} s joint move from the "
                                       f"measured pose")
        return move

    @staticmethod
    def _no_state(what: str) -> str:
        return (f"{what} refused: no measured joint_states yet; the move starts from the "
                f"measured pose")

    def waits_for_first_state(self, now: float, what: str) -> bool:
        """True when a ``what`` move at ``now`` [s] is refused only because no joint state
        has been measured yet (the planner holds a ``stand`` until one arrives)."""
        return self._measured is None and self._refusal(now, what) == self._no_state(what)

    def _refusal(self, now: float, what: str) -> str | None:
        """Why a ``what`` move cannot start at ``now`` [s], or None."""
        ctx = self.ctx
        if ctx.state == ESTOP:
            return f"{what} refused: e-stop latched; send reset, then stand"
        if ctx.state in WALK_STATES:
            return f"{what} refused while {ctx.state}: send stop and wait for STANDING"
        if ctx.paused:
            return f"{what} refused: {ctx.paused_reason()}"
        if ctx.state == MOVING and self.move is not None:
            return f"{what} refused: a {self._target} move is in progress; wait for it to end"
        if self._measured is None:
            return self._no_state(what)
        age = now - self._measured_at
        if age > self.measurement_max_age:
            return (f"{what} refused: the last joint_states is {age:.2f} s old (max "
                    f"{self.measurement_max_age:g} s); is the driver running?")
        if outside_tolerance(self.cfg.robot, self._measured):
            try:
                check_limits(self.cfg.robot, self._measured)
            except KinematicsError as exc:
                return f"{what} refused: measured {exc}; move the joint inside its limits first"
        return None

    def start(self, now: float, pose: np.ndarray, end_state: PlannerState, what: str) -> None:
        """Start the ``what`` move to ``pose`` [rad] at ``now`` [s]; refusals raise
        `CommandError`."""
        reason = self._refusal(now, what)
        if reason is not None:
            self.ctx.journal.refuse(reason, now)
        assert self._measured is not None
        move = JointMove(self.cfg, self._measured, pose, now, end_state, what)
        was = self.ctx.state
        self.move = move
        self._target = what
        self.ctx.body_pose = NEUTRAL
        self.ctx.enter(MOVING, now)
        self.ctx.journal.event("info", f"{what}: {move.duration:.2f} s joint move from {was}")

    def stand(self, now: float, height: float, stand_height: float, from_measured: bool
              ) -> None:
        """``stand`` at ``height`` [m] from the standing ``stand_height`` [m]: while STANDING
        posed (and not ``from_measured``: an interruption's resume was due) a pose move back
        to the neutral pose, every foot fixed; otherwise the joint move from the measured
        pose. Refusals raise `CommandError`."""
        ctx = self.ctx
        if ctx.state == STANDING and not ctx.body_pose.is_neutral and not from_measured:
            start = ctx.body_pose.rebased(stand_height, height)
            self._start_pose(now, start, NEUTRAL, height, "stand")
        else:
            self.start(now, standing_pose(self.cfg, height), STANDING, "stand")

    def pose(self, now: float, pose: BodyPose, stand_height: float) -> None:
        """Move the standing body to ``pose`` (at the standing ``stand_height`` [m]) from
        where it is, every foot fixed; refusals raise `CommandError`."""
        state = self.ctx.state
        busy = state == ESTOP or state in WALK_STATES or (
            state == MOVING and self.move is not None)
        if state != STANDING and not busy:  # (the others are refused with their reason)
            self.ctx.journal.refuse(f"pose refused in state {state}: the body pose is set "
                                    f"while STANDING; send stand first", now)
        self._start_pose(now, self.ctx.body_pose, pose, stand_height, "pose")

    def _start_pose(self, now: float, start: BodyPose, end: BodyPose, height: float,
                    what: str) -> None:
        ctx = self.ctx
        reason = self._refusal(now, what)
        if reason is not None:
            ctx.journal.refuse(reason, now)
        try:
            move = PoseMove(self.cfg, height, start, end, now, what)
        except PoseError as exc:
            ctx.journal.refuse(f"{what} refused: {exc}", now)
        ctx.body_pose = start
        ctx.last_target = ctx.hold  # the move starts at the held pose
        self.move = move
        self._target = what
        ctx.enter(MOVING, now)
        ctx.journal.event("info", f"{what}: {move.duration:.2f} s body move to "
                                  f"{end.described()}, every foot fixed")

    def tick(self, now: float) -> JointTarget | None:
        """Joint targets of the move at steady time ``now`` [s]; at its end the held pose."""
        move, ctx = self.move, self.ctx
        assert move is not None
        if move.done(now):
            ctx.hold = ctx.hold_pose(move.final)
            if isinstance(move, PoseMove):
                ctx.body_pose = move.end
            ctx.enter(move.end_state, now)
            self.move = None
            ctx.journal.event("info", f"{move.target} done: {ctx.state}")
            return ctx.hold
        try:
            target = move.at(now)
        except KinematicsError as exc:  # pragma: no cover - every sample 5 ms apart was checked
            assert ctx.last_target is not None  # set when a pose move starts
            ctx.hold = ctx.hold_pose(ctx.last_target.positions)
            self.interrupt(now)
            ctx.journal.event("error", f"{move.target} stopped at {now:.3f} s: {exc}")
            return ctx.hold
        if isinstance(move, PoseMove):
            ctx.body_pose = move.current
        ctx.last_target = target
        return target
