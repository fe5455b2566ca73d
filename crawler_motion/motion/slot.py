"""One slot of a walk: its foot trajectories from the gait's offsets (pure numpy).

`SlotBuilder` turns the sequencer's decision for a slot (the swinging group, where it lands,
how far the body moves) into trajectories, carrying from one slot to the next what makes them
join: the foot centres, the touch-down points (the foot's roll, `contact`), the body's sway
(`sway`) and, for the continuous stance, the feet's velocities.

Time profiles of the body within a slot (`StanceProfile`):

- ``rest``: the study's: every stance segment is a rest sextic, so the body starts and stops
  in every swing and every transfer (v = a = 0 at each lift-off and touch-down);
- ``continuous``: the body keeps moving: stance feet glide at constant velocity in steady
  slots, ramp up over the start half steps and down over the stop ones (quintics with a = 0 at
  the slot ends: C²), and every swing leaves and lands with the stance feet's velocity
  (`continuous.continuous_swing_segments`), i.e. at zero velocity relative to the ground.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

from crawler_motion.errors import GaitError, KinematicsError
from crawler_motion.model.config import Config, RobotConfig
from crawler_motion.model.kinematics import inverse_kinematics
from crawler_motion.motion.contact import rolled_centres
from crawler_motion.motion.continuous import continuous_swing_segments
from crawler_motion.motion.sway import convex_hull, line_sways, support_margin, sway_target
from crawler_motion.motion.trajectory import (
    Piecewise,
    Segment,
    SwingShape,
    glide_segment,
    minus_path,
    minus_segments,
    rest_segment,
    swing_segments,
)
from crawler_motion.motion.walk_options import is_crawl
from crawler_motion.motion.walk_params import WalkParams
from crawler_motion.motion.zmp import (
    FALLBACK_SCALES,
    PREVIEW,
    SwayPlan,
    ZmpWeights,
    plan_slot_sway,
)

#: Shortest dwell that counts [s] (below it: rounding of the slot's time split).
DWELL_EPS = 1e-12
#: Rounding allowance of the stability margin check [m].
MARGIN_TOLERANCE = 1e-9
#: Reach kept by a foot target at the ends of a swing and of a transfer when the body moves
#: along its support line [m] (the foot's roll and the rest of the slot: a few mm).
REACH_MARGIN = 0.005
#: Shares of the way from the nearest points of the support lines to the sways that move the
#: body along them, tried in order (`SlotBuilder._line_sways`); if none fits, the nearest
#: points (the sway without a ``sway_weight``).
LINE_SWAY_SHARES = (1.0, 0.75, 0.5, 0.25)
#: Where a steady walk lands a swinging foot: this share of its stride vector ahead of its
#: standing point (`gait.GaitSequencer`).
STEADY_TARGET = 0.5
#: A check of a slot's legs (robot, legs, what) that raises GaitError: `gait.check_trajectories`.
SlotCheck = Callable[[RobotConfig, Sequence[Any], str], None]


class StanceProfile(str, Enum):
    """How the body moves within a slot (see the module docstring)."""

    REST = "rest"
    CONTINUOUS = "continuous"


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
    #: The contact points' trajectories (the planned ground points; ``legs`` adds the roll).
    contacts: tuple[Piecewise, ...] = ()
    #: The body's sway (x, y, 0) [m] (`crawler_motion.motion.sway`; zero unless the walk
    #: sways): every foot target is its planned point minus the sway.
    sway: Piecewise | None = None


@dataclass(frozen=True)
class SlotPlan:
    """What the sequencer decided for one slot: the swinging ``group`` (empty: every foot
    down), the group after it, the feet's offsets ``(n_legs, 2)`` [m] at the slot's start, at
    the swing's end and at its end, its duration and swing time [s], the body's rate (share of
    the steady speed) at its end (continuous stance) and whether it ends the walk."""

    kind: str
    group: tuple[int, ...]
    following: tuple[int, ...]
    offsets: tuple[np.ndarray, np.ndarray, np.ndarray]
    duration: float
    swing_time: float
    rate_end: float
    final: bool
    sways: bool

    @property
    def dwell(self) -> float:
        """Time with every foot down after the swing [s] (0 below rounding)."""
        dwell = self.duration - self.swing_time
        return dwell if dwell > DWELL_EPS else 0.0


class SlotBuilder:
    """Builds slots one after the other, joining each to the last (see the module docstring)."""

    def __init__(self, cfg: Config, check: SlotCheck | None = None) -> None:
        self.cfg = cfg
        self.robot = cfg.robot
        #: Checks a slot's legs against the limits (`gait.check_trajectories`; raises
        #: GaitError): a slot whose body moves along its support lines and fails it is built
        #: again with the nearest points of the lines.
        self._check = check
        self.reset(self.robot.standing_feet(None))

    def reset(self, standing: np.ndarray) -> None:
        """Start a walk from the standing feet ``standing`` ``(n_legs, 3)`` [m]."""
        self._touch = standing  # foot centres at their last touch-down [m]
        self._centres = standing  # foot centre targets at the end of the last slot [m]
        self._sway = np.zeros(2)  # body sway at the end of the last slot [m]
        self._velocity = np.zeros((self.robot.n_legs, 3))  # centres' velocities then [m/s]
        #: The ZMP sway's state (position, velocity, acceleration ``(3, 2)``) at the end of
        #: the last slot (`crawler_motion.motion.zmp`; zero for other gaits).
        self._zmp_state = np.zeros((3, 2))

    def build(self, plan: SlotPlan, p: WalkParams, stride: np.ndarray, speed: float) -> Slot:
        """The slot of ``plan`` with parameters ``p``, per-leg stride vectors ``stride``
        ``(n_legs, 2)`` [m] and ``speed``: the stance feet's steady travel per second as a
        share of their stride [1/s] (continuous stance)."""
        if p.gait in self.cfg.gait.zmp_gaits and plan.group and not plan.sways:
            return self._build_zmp(plan, p, stride, speed)
        slot, state = self._build(plan, p, stride, speed, LINE_SWAY_SHARES)
        rest = LINE_SWAY_SHARES[LINE_SWAY_SHARES.index(state[-1]) + 1:] if state[-1] else None
        shares = [] if rest is None else [*rest, 0.0]
        while shares and self._check is not None:
            try:
                self._check(self.robot, slot.legs, "the slot")
                break
            except GaitError:  # e.g. a joint rate: less of the way along the lines
                slot, state = self._build(plan, p, stride, speed, (shares.pop(0),))
        self._touch, self._centres, self._sway, self._velocity, _ = state
        return slot

    def _build_zmp(self, plan: SlotPlan, p: WalkParams, stride: np.ndarray, speed: float
                   ) -> Slot:
        """The slot of a gait planned from the zero-moment point (`crawler_motion.motion.zmp`):
        the walk's slot without sway, minus the sway that keeps the ZMP on the support line.
        If the joint limits or rates refuse it, the sway is planned again smaller (the sway
        terms' weights times each of `zmp.FALLBACK_SCALES`, each still C² from the last
        slot); the smallest is kept, and the walk's own limit check refuses it if it still
        does not fit (as any walk beyond the limits)."""
        plain, state = self._build(plan, p, stride, speed, (0.0,))
        medium = self.cfg.medium
        omega2 = medium.omega2(float(p.body_height))  # type: ignore[arg-type]
        stance = [i for i in range(self.robot.n_legs) if i not in plan.group]
        breaks = plain.legs[plan.group[0]].breaks
        knots = np.unique(np.concatenate((breaks, (breaks[:-1] + breaks[1:]) / 2)))
        last = int(np.argmin(np.abs(knots - plan.duration)))
        center = self.robot.standing_feet(p.body_height)[:, :2]
        velocity = -stride * speed  # the stance feet's steady velocity in the plan frame
        landing = list(plan.group)
        landed = center[landing] + plan.offsets[2][landing]
        steady = center[stance] + STEADY_TARGET * stride[stance]
        ahead = [(landed, velocity[landing]), (steady, velocity[stance])][:PREVIEW]
        base = ZmpWeights()
        for scale in FALLBACK_SCALES:
            weights = ZmpWeights(base.line, base.sway * scale, base.accel * scale)
            sway = plan_slot_sway(plain.contacts, stance, knots, plan.swing_time,
                                  self._zmp_state, plan.final, omega2, medium.zmp_shift,
                                  weights, ahead)
            slot = self._swayed(plain, sway, last)
            try:
                if self._check is not None:
                    self._check(self.robot, slot.legs, "the slot")
            except GaitError:
                continue
            break
        self._touch, self._centres, self._sway, self._velocity, _ = state
        self._zmp_state = sway.states[last]
        return slot

    @staticmethod
    def _swayed(plain: Slot, sway: SwayPlan, upto: int) -> Slot:
        """``plain`` (a slot without sway) seen from a body that sways by the first ``upto``
        intervals of ``sway``."""
        path = sway.segments(upto)
        legs = tuple(Piecewise(minus_segments(leg.segments, path)) for leg in plain.legs)
        contacts = tuple(Piecewise(minus_segments(c.segments, path)) for c in plain.contacts)
        return Slot(kind=plain.kind, group=plain.group, offsets_start=plain.offsets_start,
                    offsets_end=plain.offsets_end, legs=legs, duration=plain.duration,
                    swing_time=plain.swing_time, params=plain.params, contacts=contacts,
                    sway=Piecewise(path))

    def _build(self, plan: SlotPlan, p: WalkParams, stride: np.ndarray, speed: float,
               shares: tuple[float, ...]) -> tuple[Slot, tuple[Any, ...]]:
        """`build` without keeping its state: the slot and the builder's state after it
        (touch-downs, centres, sway, velocities, and the share of the way along the support
        lines taken, of ``shares``: 0 for the nearest points or a gait without lines)."""
        robot = self.robot
        center = robot.standing_feet(p.body_height)
        swinging = np.isin(np.arange(robot.n_legs), plan.group)
        ground = [center.copy() for _ in range(3)]  # slot start, swing end, slot end
        for g, off in zip(ground, plan.offsets, strict=True):
            g[:, :2] += off
        sway, along = self._sway_targets(plan, p, swinging, ground, shares)
        for g, s in zip(ground, sway, strict=True):
            g[:, :2] -= s
        touch = np.where(swinging[:, None], ground[1], self._touch)
        centres = [self._centres] + [g.copy() if plan.final else rolled_centres(robot, g, touch)
                                     for g in ground[1:]]
        velocity_end = np.zeros_like(self._velocity)
        if p.stance_profile == StanceProfile.CONTINUOUS.value:
            velocity_end[:, :2] = -stride * speed * plan.rate_end
        sway3 = [np.append(s, 0.0) for s in sway]
        dwell = plan.dwell
        sway_path = ([rest_segment(sway3[0], sway3[1], plan.swing_time, "sway")]
                     if plan.swing_time > 0 else [])
        sway_path += [rest_segment(sway3[1], sway3[2], dwell, "sway")] if dwell else []
        legs, contacts = [], []
        for i in range(robot.n_legs):
            for points, out in ((centres, legs), (ground, contacts)):
                out.append(Piecewise(self._leg(i, points, swinging[i], plan, p, sway3,
                                               sway_path, velocity_end[i])))
        slot = Slot(kind=plan.kind, group=plan.group, offsets_start=plan.offsets[0],
                    offsets_end=plan.offsets[2], legs=tuple(legs), duration=plan.duration,
                    swing_time=plan.swing_time, params=p, contacts=tuple(contacts),
                    sway=Piecewise(sway_path))
        if is_crawl(self.cfg, p.gait):
            check_margin(slot, float(p.margin), self.cfg)  # type: ignore[arg-type]
        last = 2 if dwell else 1
        return slot, (touch, centres[last], sway[last], velocity_end, along)

    def transfer_travel(self, plan: SlotPlan, p: WalkParams) -> float:
        """Largest horizontal travel [m] of a contact point relative to the body over the
        transfer of ``plan`` (the planned body motion plus the change of the sway): the body's
        motion over the ground that the all-feet-down time has to carry. Nothing is built."""
        center = self.robot.standing_feet(p.body_height)
        swinging = np.isin(np.arange(self.robot.n_legs), plan.group)
        ground = [center.copy() for _ in range(3)]
        for g, off in zip(ground, plan.offsets, strict=True):
            g[:, :2] += off
        sway, _ = self._sway_targets(plan, p, swinging, ground)
        travel = (plan.offsets[2] - plan.offsets[1]) - (sway[2] - sway[1])
        return float(np.max(np.linalg.norm(travel, axis=-1)))

    def _leg(self, i: int, points: list[np.ndarray], swinging: bool, plan: SlotPlan,
             p: WalkParams, sway: list[np.ndarray], sway_path: list[Segment],
             velocity_end: np.ndarray) -> list[Segment]:
        """Segments of leg ``i`` through ``points`` (slot start, swing end, slot end)."""
        a, mid, fin = (pt[i] for pt in points)
        v0, t_w, dwell = self._velocity[i], plan.swing_time, plan.dwell
        segments: list[Segment] = []
        shape = SwingShape(p.lift, p.arc, t_w, self.cfg.gait.profiles[p.profile]) if (
            swinging) else None
        if shape is not None and p.stance_profile == StanceProfile.CONTINUOUS.value:
            segments = continuous_swing_segments(a, mid, shape, v0, velocity_end)
        elif shape is not None and plan.sways:  # the swing in the world, seen from the body
            segments = minus_path(swing_segments(a + sway[0], mid + sway[1], shape),
                                  sway_path[0])
        elif shape is not None:
            segments = swing_segments(a, mid, shape)
        elif t_w > 0.0:
            v_mid = np.zeros(3) if dwell else velocity_end
            segments = [glide_segment(a, mid, t_w, v0, v_mid, "stance")]
        if dwell:
            segments.append(rest_segment(mid, fin, dwell, "stance"))
        return segments

    def _sway_targets(self, plan: SlotPlan, p: WalkParams, swinging: np.ndarray,
                      ground: list[np.ndarray],
                      shares: tuple[float, ...] = LINE_SWAY_SHARES
                      ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], float]:
        """Sway [m] at the slot's start, the swing's end and the slot's end (`motion.sway`),
        and the share of the way along the support lines taken (a gait with a
        ``sway_weight``: the first of ``shares`` within reach; 0: the nearest points)."""
        if not plan.sways:
            return (np.zeros(2), np.zeros(2), np.zeros(2)), 0.0
        margin = float(p.margin) if is_crawl(self.cfg, p.gait) else 0.0  # type: ignore[arg-type]
        following = np.isin(np.arange(self.robot.n_legs), plan.following)
        weight = self.cfg.gait.sway_weights.get(p.gait)
        if weight is not None and swinging.any() and any(shares):  # move along the lines
            return self._line_sways(plan, swinging, following, ground, weight, shares)
        s_mid = (self._sway if not swinging.any() else
                 sway_target([ground[1][~swinging, :2]], margin))
        s_fin = np.zeros(2) if plan.final else sway_target([ground[2][~following, :2]], margin)
        for value in (s_mid, s_fin):
            if value is None:
                raise GaitError(f"the {p.gait} walk cannot keep the body centre {margin:g} m "
                                f"inside its support triangles: use a smaller margin or "
                                f"stride, or a wider stance")
        return (self._sway, s_mid, s_fin), 0.0  # type: ignore[return-value]

    def _line_sways(self, plan: SlotPlan, swinging: np.ndarray, following: np.ndarray,
                    ground: list[np.ndarray], weight: float, shares: tuple[float, ...]
                    ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], float]:
        """Sways of a gait of pairs that moves the body along its support lines
        (`sway.line_sways`), taken from the nearest points of the lines (the sway without
        ``weight``) towards them only as far as every foot target at the swing's and the
        slot's end keeps `REACH_MARGIN` of reach (the largest of `LINE_SWAY_SHARES` that
        does), so the walk reaches whatever it reaches without it."""
        line = np.resize(convex_hull(ground[1][~swinging, :2]), (2, 2))
        following_line = np.zeros((2, 2)) if plan.final else np.resize(
            convex_hull(ground[2][~following, :2]), (2, 2))
        near_fin = np.zeros(2) if plan.final else sway_target([following_line], 0.0)
        near = (sway_target([line], 0.0), near_fin)
        travel = np.mean(plan.offsets[2][~following] - plan.offsets[1][~following], axis=0)
        best = line_sways(line, following_line, travel, weight)
        for share in shares:
            mid, fin = (n + share * (b - n) for n, b in zip(near, best, strict=True))
            if share and self._reachable(ground[1], mid) and self._reachable(ground[2], fin):
                return (self._sway, mid, fin), share
        return (self._sway, near[0], near[1]), 0.0

    def _reachable(self, ground: np.ndarray, sway: np.ndarray) -> bool:
        """True when every foot at ``ground`` ``(n_legs, 3)`` [m] seen from a body swayed by
        ``sway`` [m], pushed `REACH_MARGIN` further out from its hip, is within its leg's
        workspace and joint limits (the one IK)."""
        feet = ground.copy()
        feet[:, :2] -= sway
        out = feet[:, :2] - self.robot.hips[:, :2]
        norm = np.maximum(np.linalg.norm(out, axis=-1, keepdims=True), 1e-12)
        feet[:, :2] += REACH_MARGIN * out / norm
        try:
            inverse_kinematics(self.robot, feet)
        except KinematicsError:
            return False
        return True


def check_margin(slot: Slot, margin: float, cfg: Config, samples: int = 41) -> None:
    """Check that the body centre (base_link origin) stays ``margin`` [m] inside the support
    polygon of the stance feet's contact points at every sample of ``slot`` (the swinging
    group counts as lifted over its whole swing, lift-off and touch-down included).

    Raises `GaitError` naming the swinging leg, the time in the slot and the margin found.
    """
    robot = cfg.robot
    parts = [(np.linspace(0.0, slot.swing_time, samples), slot.group)] if slot.swing_time else []
    if slot.duration - slot.swing_time > DWELL_EPS:
        parts.append((np.linspace(slot.swing_time, slot.duration, samples), ()))
    for times, lifted in parts:
        stance = [i for i in range(robot.n_legs) if i not in lifted]
        points = np.stack([slot.contacts[i].evaluate(times)[0][:, :2] for i in stance], axis=1)
        found = np.array([support_margin(pt) for pt in points])
        k = int(np.argmin(found))
        if found[k] < margin - MARGIN_TOLERANCE:
            what = ", ".join(robot.legs[i].upper() for i in lifted) or "no leg"
            raise GaitError(f"the walk cannot keep its stability margin {margin * 1e3:.1f} mm: "
                            f"with {what} lifted the body centre is {found[k] * 1e3:.1f} mm "
                            f"inside the support at t = {times[k]:.3f} s of a {slot.kind} "
                            f"slot; use a shorter stride or turn, a longer transfer "
                            f"(stance_time) or a smaller margin")


