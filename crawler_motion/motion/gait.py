"""Gait planning: phase tables, half-step start/stop, straight, sideways and turning walks.

A gait is a table of *groups* of legs that swing together, in order; a **step** is one gait
cycle in which every group swings once, each in its own **slot** (swing time, then an optional
dwell with every foot on the ground). The body moves during every slot with a rest sextic, so
every stance foot moves back by the same fraction ``b`` of its own stride vector and lift-off
and touch-down happen with v = a = 0 (the spec's corners A and E).

Foot offsets are ``(n_legs, 2)`` ground-plane vectors [m] from each leg's standing position;
foot trajectories are ``(n_legs, 3)`` positions in base_link, one row per leg in config order.
Starting and stopping take ``n_groups - 1`` half-speed slots (for the diagonal gait exactly
the spec's half step: the first pair swings from the stride middle to the front end).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from crawler_motion.errors import GaitError, KinematicsError
from crawler_motion.model.config import Config, GaitConfig, RobotConfig
from crawler_motion.model.kinematics import inverse_kinematics, joint_velocities
from crawler_motion.motion.trajectory import (
    Piecewise,
    Segment,
    SwingShape,
    rest_segment,
    swing_segments,
)
from crawler_motion.motion.walk_options import (
    OPTIONS,
    clearance_error,
    stance_time_error,
    stance_time_range,
)

#: Sampling period used to check a planned walk against the workspace and the limits [s].
CHECK_PERIOD = 0.005
#: Relative tolerance of the joint velocity check of a planned walk (rounding only).
VELOCITY_EPS = 1e-9
#: Smallest arc/lift ratio for profiles with a junction speed at B (below it the arc dips under
#: B's height: with the shipped smooth profile the bound is 0.0245).
MIN_ARC_RATIO = 0.05


@dataclass(frozen=True)
class WalkParams:
    """Parameters of a walk. Lengths in m, angles in rad, times in s."""

    gait: str = "diagonal"
    profile: str = "smooth"
    stride: float = 0.06  # foot travel relative to the body during one stance [m]
    heading: float = 0.0  # direction of travel in base_link [rad] (0 forward, pi/2 left)
    turn: float = 0.0  # body yaw per step (one gait cycle) [rad], + counter-clockwise
    lift: float = 0.01
    arc: float = 0.01
    swing_time: float = 0.6
    stance_time: float | None = None  # None: (groups - 1) x swing_time
    body_height: float | None = None  # None: the configured standing height

    @classmethod
    def defaults(cls, gait_cfg: GaitConfig, **overrides: object) -> WalkParams:
        """Walk parameters from the config defaults, with ``overrides``."""
        base = cls(gait=gait_cfg.gait, profile=gait_cfg.profile, stride=gait_cfg.stride,
                   lift=gait_cfg.lift, arc=gait_cfg.arc, swing_time=gait_cfg.swing_time,
                   stance_time=None)
        return replace(base, **overrides)  # type: ignore[arg-type]


def validate_params(params: WalkParams, cfg: Config) -> WalkParams:
    """Check ranges and consistency; return params with ``stance_time`` resolved.

    Raises `GaitError` naming the field, its value and the allowed range.
    """
    g = cfg.gait
    if params.gait not in g.gaits:
        raise GaitError(f"gait '{params.gait}' unknown; choose one of {sorted(g.gaits)}")
    if params.profile not in g.profiles:
        raise GaitError(f"profile '{params.profile}' unknown; choose one of {sorted(g.profiles)}")
    for name in ("stride", "heading", "turn", "lift", "arc", "swing_time"):
        value = getattr(params, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
                value):
            raise GaitError(f"{name} must be a finite number, got {value!r}")

    def in_range(name: str, value: float, lo: float, hi: float, unit: str) -> None:
        if not lo <= value <= hi:
            raise GaitError(f"{name} = {value} {unit} is outside [{lo}, {hi}] {unit}")

    for name in ("stride", "turn", "lift", "arc"):
        in_range(name, getattr(params, name), *OPTIONS[name].range(cfg), OPTIONS[name].unit)
    clearance = clearance_error(cfg, params.lift, params.arc)
    if clearance is not None:
        raise GaitError(clearance)
    if params.profile in g.profiles and g.profiles[params.profile].v_b > 0 and (
            params.arc < MIN_ARC_RATIO * params.lift):
        raise GaitError(f"arc = {params.arc} m: the {params.profile} profile reaches B still "
                        f"rising and needs arc >= {MIN_ARC_RATIO} x lift = "
                        f"{MIN_ARC_RATIO * params.lift:.4g} m to stay above B on the arc")
    in_range("swing_time", params.swing_time, *OPTIONS["swing_time"].range(cfg), "s")
    stance = stance_time_range(cfg, params.gait, params.swing_time)[0] if (
        params.stance_time is None) else params.stance_time
    if isinstance(stance, bool) or not isinstance(stance, (int, float)) or not math.isfinite(
            stance):
        raise GaitError(f"stance_time must be a finite number, got {stance!r}")
    stance_error = stance_time_error(cfg, params.gait, params.swing_time, stance)
    if stance_error is not None:
        raise GaitError(stance_error)
    height = cfg.robot.body_height if params.body_height is None else params.body_height
    lo, hi = OPTIONS["body_height"].range(cfg)
    if not (isinstance(height, (int, float)) and math.isfinite(height) and lo <= height <= hi):
        raise GaitError(f"body_height = {height} m is outside [{lo}, {hi}] m")
    return replace(params, stance_time=float(stance), body_height=float(height))


@dataclass(frozen=True)
class Slot:
    """One slot of a walk: ``group`` swings, everybody else (and the group after touch-down,
    during the dwell) pushes the body. ``legs`` holds one trajectory per leg, in slot time."""

    kind: str  # "start", "steady", "stop"
    group: tuple[int, ...]
    offsets_start: np.ndarray  # (n_legs, 2) [m]
    offsets_end: np.ndarray  # (n_legs, 2) [m]
    legs: tuple[Piecewise, ...]
    duration: float
    swing_time: float
    params: WalkParams


class GaitSequencer:
    """Produces the slots of a walk one at a time (online use by the planner node).

    The sequencer starts standing; call `next_slot` with ``stopping`` False to walk and True
    to stop into standing. `standing` is True when every foot is back at its standing position.
    """

    def __init__(self, cfg: Config, params: WalkParams) -> None:
        self.cfg = cfg
        self.robot: RobotConfig = cfg.robot
        self.params = validate_params(params, cfg)
        self.offsets = np.zeros((self.robot.n_legs, 2))
        self.phase = "standing"  # standing -> start -> steady -> stop -> standing
        self._group_index = 0  # next group to swing (index into the gait table)
        self._count = 0  # slots done in the current phase
        self._slot_params = self.params  # parameters of the last planned slot

    @property
    def n_groups(self) -> int:
        """Number of swing groups of the current gait."""
        return len(self.cfg.gait.gaits[self.params.gait])

    @property
    def standing(self) -> bool:
        """True when the walk has not started or has finished."""
        return self.phase == "standing"

    def set_params(self, params: WalkParams) -> None:
        """New parameters, effective at the next slot. A gait change only while standing.

        A stop in progress (or starting at the next slot) finishes with the parameters of the
        last slot walked: its half steps assume the offsets that slot left.
        """
        new = validate_params(params, self.cfg)
        if new.gait != self.params.gait and not self.standing:
            raise GaitError("the gait can only change while standing; stop first")
        if new.body_height != self.params.body_height and not self.standing:
            raise GaitError("the body height can only change while standing; stop first")
        self.params = new

    def stride_vectors(self, params: WalkParams | None = None) -> np.ndarray:
        """Per-leg stride vectors ``(n_legs, 2)`` [m]: foot travel during one stance."""
        p = self.params if params is None else params
        _, b, _ = self._fractions(p)  # b: stride fraction per slot
        phi = p.turn / (len(self.cfg.gait.gaits[p.gait]) * b)
        feet = self.robot.standing_feet(p.body_height)[:, :2]
        tangent = np.stack((-feet[:, 1], feet[:, 0]), axis=-1)
        heading = np.array([math.cos(p.heading), math.sin(p.heading)])
        return p.stride * heading + phi * tangent

    def _fractions(self, p: WalkParams) -> tuple[float, float, float]:
        """Slot duration [s], stride fraction per slot ``b`` and its dwell part ``e``."""
        n = len(self.cfg.gait.gaits[p.gait])
        stance = float(p.stance_time)  # type: ignore[arg-type]
        slot = (p.swing_time + stance) / n
        b = slot / stance
        dwell = slot - p.swing_time
        return slot, b, b * dwell / slot

    def next_slot(self, stopping: bool = False) -> Slot | None:
        """Plan the next slot; None when standing and ``stopping`` (nothing left to do)."""
        p = self.params
        n = self.n_groups
        if self.phase == "standing":
            if stopping:
                return None
            self.phase, self._count, self._group_index = "start", 0, 0
        if self.phase == "steady" and stopping:
            self.phase, self._count = "stop", 0
        if self.phase == "stop":
            p = self._slot_params
        slot_time, b, e = self._fractions(p)
        stride = self.stride_vectors(p)
        k = self._count
        if self.phase == "start":
            beta = 1.0 / (2 * (n - 1))
            tau = 0.5 - e + beta * e / b - (n - 2 - k) * (b - beta)
            target, inc = tau, beta
        elif self.phase == "steady":
            target, inc = 0.5, b
        else:  # stop: the group that swung last must reach 0 over n - 1 slots
            beta = (0.5 - e) / (n - 1)
            target, inc = beta * e / b + (n - 2 - k) * beta, beta
        groups = self.cfg.gait.gaits[p.gait]
        group = tuple(self.robot.legs.index(leg) for leg in groups[self._group_index])
        slot = self._build(group, target, inc, stride, slot_time, p)
        kind = self.phase
        self.offsets = slot.offsets_end
        self._slot_params = p
        self._group_index = (self._group_index + 1) % n
        self._count += 1
        if self.phase == "start" and self._count == n - 1:
            self.phase, self._count = "steady", 0
        elif self.phase == "stop" and self._count == n - 1:
            self.phase, self._count = "standing", 0
            self._group_index = 0
        return replace(slot, kind=kind)

    def _build(self, group: tuple[int, ...], target: float, inc: float, stride: np.ndarray,
               slot_time: float, p: WalkParams) -> Slot:
        robot = self.robot
        center = robot.standing_feet(p.body_height)
        swing_time = p.swing_time
        dwell = slot_time - swing_time
        inc_swing = inc * swing_time / slot_time
        inc_dwell = inc - inc_swing
        shape = SwingShape(p.lift, p.arc, swing_time, self.cfg.gait.profiles[p.profile])
        start = self.offsets.copy()
        end = np.empty_like(start)
        legs: list[Piecewise] = []
        for i in range(robot.n_legs):
            a = center[i].copy()
            a[:2] += start[i]
            segments: list[Segment]
            if i in group:
                touch = target * stride[i]
                e_pt = center[i].copy()
                e_pt[:2] += touch
                segments = swing_segments(a, e_pt, shape)
                mid = e_pt
                after = touch - inc_dwell * stride[i]
            else:
                after_swing = start[i] - inc_swing * stride[i]
                mid = center[i].copy()
                mid[:2] += after_swing
                segments = [rest_segment(a, mid, swing_time, "stance")]
                after = after_swing - inc_dwell * stride[i]
            if dwell > 1e-12:
                fin = center[i].copy()
                fin[:2] += after
                segments.append(rest_segment(mid, fin, dwell, "stance"))
            end[i] = after
            legs.append(Piecewise(segments))
        return Slot(kind="", group=group, offsets_start=start, offsets_end=end,
                    legs=tuple(legs), duration=slot_time, swing_time=swing_time, params=p)


@dataclass
class WalkPlan:
    """A finite walk: slots laid end to end from t = 0, every leg as one `Piecewise`."""

    slots: list[Slot]
    legs: tuple[Piecewise, ...]
    starts: np.ndarray  # start time of each slot [s]
    robot: RobotConfig

    @property
    def duration(self) -> float:
        """Total duration [s]."""
        return float(self.legs[0].t_end)

    def evaluate(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Foot position, velocity, acceleration ``(len(t), n_legs, 3)`` at times ``t`` [s]."""
        results = [leg.evaluate(t) for leg in self.legs]
        return tuple(np.stack([r[k] for r in results], axis=1) for k in range(3))  # type: ignore

    def joints(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles [rad] and rates [rad/s], ``(len(t), n_legs, 3)``."""
        pos, vel, _ = self.evaluate(t)
        q = inverse_kinematics(self.robot, pos)
        return q, joint_velocities(self.robot, q, vel)

    def slot_index(self, t: float) -> int:
        """Index of the slot active at ``t``."""
        return int(np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0,
                           len(self.slots) - 1))


def check_trajectories(robot: RobotConfig, legs: tuple[Piecewise, ...], what: str) -> None:
    """Sample every leg (every CHECK_PERIOD and every junction), run IK with the position
    limits and check the joint rates against the velocity limits.

    Raises `GaitError` (with the kinematics reason, or the joint, rate and limit, and the
    time) if any sample fails.
    """
    t0, t1 = legs[0].t0, legs[0].t_end
    n = max(2, math.ceil((t1 - t0) / CHECK_PERIOD) + 1)
    times = np.unique(np.concatenate([np.linspace(t0, t1, n)] + [leg.breaks for leg in legs]))
    states = [leg.evaluate(times) for leg in legs]
    feet = np.stack([p for p, _, _ in states], axis=1)
    try:
        q = inverse_kinematics(robot, feet)
        rates = np.abs(joint_velocities(robot, q, np.stack([v for _, v, _ in states], axis=1)))
    except KinematicsError as exc:
        msg = str(exc)
        sample = exc.sample
        if sample:  # the message names the sample; name its time instead
            msg = msg.replace(f" at sample {sample}", f" at t = {times[sample[0]]:.3f} s", 1)
        raise GaitError(f"{what} cannot be executed: {msg}") from exc
    over = rates / np.broadcast_to(robot.velocity, rates.shape[-1:])
    worst = np.unravel_index(int(np.argmax(over)), over.shape)
    if over[worst] > 1.0 + VELOCITY_EPS:
        k, leg, joint = (int(i) for i in worst)
        name = robot.joint_names[3 * leg + joint]
        raise GaitError(f"{what} cannot be executed: {name} would turn at "
                        f"{rates[worst]:.2f} rad/s at t = {times[k]:.3f} s, above its velocity "
                        f"limit {float(np.broadcast_to(robot.velocity, (3,))[joint]):g} rad/s; "
                        f"use a longer swing_time, or a shorter stride, lift or arc")


def iter_walk(cfg: Config, params: WalkParams, steps: int) -> Iterator[Slot]:
    """The slots of a walk of ``steps`` full gait cycles, half steps in and out included."""
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise GaitError(f"steps must be an integer >= 1, got {steps!r}")
    seq = GaitSequencer(cfg, params)
    n = seq.n_groups
    total_steady = steps * n
    count = 0
    while True:
        stopping = seq.phase == "steady" and count >= total_steady
        slot = seq.next_slot(stopping=stopping)
        if slot is None:
            return
        if slot.kind == "steady":
            count += 1
        yield slot
        if seq.standing:
            return


def plan_walk(cfg: Config, params: WalkParams, steps: int) -> WalkPlan:
    """Plan a whole walk and check every foot target before anything moves.

    Raises `GaitError` if any part of the walk leaves the workspace or the joint limits: a
    walk that cannot be executed is refused as a whole.
    """
    slots = list(iter_walk(cfg, params, steps))
    starts = np.cumsum([0.0] + [s.duration for s in slots])[:-1]
    legs = []
    for i in range(cfg.robot.n_legs):
        segments = [seg for slot in slots for seg in slot.legs[i].segments]
        legs.append(Piecewise(segments))
    plan = WalkPlan(slots=slots, legs=tuple(legs), starts=starts, robot=cfg.robot)
    check_trajectories(cfg.robot, plan.legs, "the walk")
    return plan


def standing_pose(cfg: Config, body_height: float | None = None) -> np.ndarray:
    """Standing joint angles ``(n_legs, 3)`` [rad] at ``body_height`` (default: configured)."""
    return inverse_kinematics(cfg.robot, cfg.robot.standing_feet(body_height))
