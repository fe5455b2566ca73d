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

import copy
import itertools
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from crawler_motion.errors import GaitError, KinematicsError
from crawler_motion.model.config import Config, RobotConfig
from crawler_motion.model.kinematics import inverse_kinematics, joint_velocities
from crawler_motion.motion.slot import Slot, SlotBuilder, SlotPlan
from crawler_motion.motion.sway import creep_order
from crawler_motion.motion.trajectory import Piecewise
from crawler_motion.motion.walk_options import MIN_TRANSFER_TIME, is_crawl, sways
from crawler_motion.motion.walk_params import WalkParams, validate_params
from crawler_motion.motion.zmp import SETTLE_TIME

__all__ = ["CHECK_PERIOD", "GaitSequencer", "Slot", "SlotPlan", "WalkParams", "WalkPlan",
           "check_trajectories", "iter_walk", "plan_walk", "standing_pose", "transfer_rate",
           "validate_params"]

#: Sampling period used to check a planned walk against the workspace and the limits [s].
CHECK_PERIOD = 0.005
#: Relative tolerance of the joint velocity check of a planned walk (rounding only).
VELOCITY_EPS = 1e-9
#: Added to the body's travel in every transfer before the transfer is sized [m]: a transfer
#: that barely moves the body still gets time to settle the feet that just landed.
TRANSFER_FLOOR = 0.001


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
        self._group_index = 0  # next group to swing (index into `_order`)
        self._order = tuple(range(self.n_groups))  # swing order of the walk (gait table indices)
        self._count = 0  # slots done in the current phase
        self._slot_params = self.params  # parameters of the last planned slot
        self._builder = SlotBuilder(cfg, check_trajectories)  # joins the slots' trajectories
        self._rate: tuple[object, float] = ((), 0.0)  # (walk key, transfer rate [s/m^0.5])

    def __copy__(self) -> GaitSequencer:
        """A copy that plans on without touching this one (the planner tries the next slot on
        a copy): the slot builder's state is copied too (its arrays are replaced, never
        changed in place)."""
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        new._builder = copy.copy(self._builder)
        return new

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
            self._order = self._swing_order(p)
            self._builder.reset(self.robot.standing_feet(p.body_height))
            if self._sways(p):  # sway over the first support before a foot lifts
                slot_time, _, _ = self._fractions(p)
                zero = np.zeros_like(self.offsets)
                return self._builder.build(self._timed(SlotPlan(
                    "start", (), self._group(0), (zero, zero, zero), slot_time - p.swing_time,
                    0.0, 0.0, False, True), p), p, self.stride_vectors(p), 0.0)
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
            target, inc, rate = tau, beta, (k + 1) / (n - 1)
        elif self.phase == "steady":
            target, inc, rate = 0.5, b, 1.0
        else:  # stop: the group that swung last must reach 0 over n - 1 slots
            beta = (0.5 - e) / (n - 1)
            target, inc = beta * e / b + (n - 2 - k) * beta, beta
            rate = 1.0 - (k + 1) / (n - 1)
        group = self._group(self._group_index)
        swinging = np.isin(np.arange(self.robot.n_legs), group)
        inc_swing = inc * p.swing_time / slot_time
        start = self.offsets.copy()
        mid = np.where(swinging[:, None], target * stride, start - inc_swing * stride)
        plan = self._timed(SlotPlan(
            self.phase, group, self._group(self._group_index + 1),
            (start, mid, mid - (inc - inc_swing) * stride), slot_time, p.swing_time, rate,
            self.phase == "stop" and k == n - 2, self._sways(p)), p)
        if plan.final and p.gait in self.cfg.gait.zmp_gaits and not plan.sways:
            plan = replace(plan, duration=plan.duration + SETTLE_TIME)  # the sway ends standing
        slot = self._builder.build(plan, p, stride, 1.0 / float(p.stance_time))  # type: ignore[arg-type]
        self.offsets = slot.offsets_end
        self._slot_params = p
        self._group_index = (self._group_index + 1) % n
        self._count += 1
        if self.phase == "start" and self._count == n - 1:
            self.phase, self._count = "steady", 0
        elif self.phase == "stop" and self._count == n - 1:
            self.phase, self._count = "standing", 0
            self._group_index = 0
        return slot

    def _group(self, index: int) -> tuple[int, ...]:
        """Leg indices of the ``index``-th group of the walk's swing order."""
        names = self.cfg.gait.gaits[self.params.gait][self._order[index % self.n_groups]]
        return tuple(self.robot.legs.index(leg) for leg in names)

    def _timed(self, plan: SlotPlan, p: WalkParams) -> SlotPlan:
        """``plan`` with its transfer sized to the body's travel over the ground in it, for a
        crawl (unchanged otherwise: the diagonal gait's transfers travel alike): ``max(
        MIN_TRANSFER_TIME, rate x sqrt(travel + TRANSFER_FLOOR))`` with the walk's
        `_transfer_rate`, so every transfer of a steady cycle asks about the same peak
        acceleration of the body (travel / time²) and the cycle lasts as long as with equal
        transfers."""
        if not (plan.sways and is_crawl(self.cfg, p.gait)):
            return plan
        travel = self._builder.transfer_travel(plan, p)
        transfer = max(MIN_TRANSFER_TIME,
                       self._transfer_rate(p) * math.sqrt(travel + TRANSFER_FLOOR))
        return replace(plan, duration=plan.swing_time + transfer)

    def _transfer_rate(self, p: WalkParams) -> float:
        """Transfer time per square root of travel [s/m^0.5] of the walk: the one that sizes
        the transfers of a steady cycle (`_timed`) to the walk's total transfer time,
        ``groups x (slot time - swing time)`` (cached per parameters and swing order)."""
        key = (p, self._order)
        if self._rate[0] == key:
            return self._rate[1]
        n = self.n_groups
        slot_time, b, _ = self._fractions(p)
        stride = self.stride_vectors(p)
        inc_swing = b * p.swing_time / slot_time
        offsets = np.zeros_like(self.offsets)
        weights = []
        for k in range(2 * n):  # the steady offsets, reached after one cycle from any start
            swinging = np.isin(np.arange(self.robot.n_legs), self._group(k))
            mid = np.where(swinging[:, None], 0.5 * stride, offsets - inc_swing * stride)
            end = mid - (b - inc_swing) * stride
            if k >= n:
                plan = SlotPlan("steady", self._group(k), self._group(k + 1),
                                (offsets, mid, end), slot_time, p.swing_time, 1.0, False, True)
                weights.append(math.sqrt(self._builder.transfer_travel(plan, p)
                                         + TRANSFER_FLOOR))
            offsets = end
        rate = transfer_rate(weights, n * (slot_time - p.swing_time))
        self._rate = (key, rate)
        return rate

    def _sways(self, p: WalkParams) -> bool:
        """True when the walk sways its body (`walk_options.sways`)."""
        return sways(self.cfg, p.gait, p.swing_time, float(p.stance_time))  # type: ignore[arg-type]

    def _swing_order(self, p: WalkParams) -> tuple[int, ...]:
        """The gait table's order; for a crawl gait walking (not only turning) the creep
        order of `sway.creep_order` for the direction of travel; for a crawl turning on the
        spot the order (first group first) whose steady transfers move the body least, i.e.
        with the largest `_transfer_rate` (going round the body in the turn's sense: the table
        order made every transfer cross a support diagonal, 26-51 mm of sway each)."""
        n = len(self.cfg.gait.gaits[p.gait])
        if not is_crawl(self.cfg, p.gait):
            return tuple(range(n))
        if p.stride == 0.0:
            best, rate = tuple(range(n)), -1.0
            for rest in itertools.permutations(range(1, n)):
                self._order = (0, *rest)
                try:
                    found = self._transfer_rate(p)
                except GaitError:  # no sway keeps the margin: refused when the slot is built
                    continue
                if found > rate:
                    best, rate = self._order, found
            return best
        legs = creep_order(self.robot.standing_feet(p.body_height)[:, :2], p.heading)
        table = [self.robot.legs.index(g[0]) for g in self.cfg.gait.gaits[p.gait]]
        return tuple(table.index(leg) for leg in legs)


def transfer_rate(weights: Sequence[float], total: float) -> float:
    """The rate ``r`` with ``sum(max(MIN_TRANSFER_TIME, r x w)) == total`` [s] for the
    positive ``weights`` (0 when every transfer is at its shortest)."""
    floor = MIN_TRANSFER_TIME
    clamped: set[int] = set()
    while True:
        free = sum(w for i, w in enumerate(weights) if i not in clamped)
        if free <= 0.0:
            return 0.0
        rate = max(0.0, total - floor * len(clamped)) / free
        short = {i for i, w in enumerate(weights) if rate * w < floor}
        if short <= clamped:
            return rate
        clamped |= short


@dataclass
class WalkPlan:
    """A finite walk: slots laid end to end from t = 0, every leg as one `Piecewise`."""

    slots: list[Slot]
    legs: tuple[Piecewise, ...]
    starts: np.ndarray  # start time of each slot [s]
    robot: RobotConfig
    contacts: tuple[Piecewise, ...] = ()  # the planned contact points (`Slot.contacts`)
    sway: Piecewise | None = None  # the body's sway (`Slot.sway`)

    @property
    def duration(self) -> float:
        """Total duration [s]."""
        return float(self.legs[0].t_end)

    def evaluate(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Foot position, velocity, acceleration ``(len(t), n_legs, 3)`` at times ``t`` [s]."""
        results = [leg.evaluate(t) for leg in self.legs]
        return tuple(np.stack([r[k] for r in results], axis=1) for k in range(3))  # type: ignore

    def contact_points(self, t: np.ndarray | float) -> np.ndarray:
        """Planned contact points ``(len(t), n_legs, 3)`` [m] (the foot centres without the
        roll of `crawler_motion.motion.contact`): the points stance feet keep on the ground."""
        return np.stack([leg.evaluate(t)[0] for leg in self.contacts], axis=1)

    def joints(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles [rad] and rates [rad/s], ``(len(t), n_legs, 3)``."""
        pos, vel, _ = self.evaluate(t)
        q = inverse_kinematics(self.robot, pos)
        return q, joint_velocities(self.robot, q, vel)

    def slot_index(self, t: float) -> int:
        """Index of the slot active at ``t``."""
        return int(np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0,
                           len(self.slots) - 1))


class SampledPath(Protocol):
    """What `check_trajectories` samples: a `Piecewise`, or any path with the same reading
    interface (e.g. a body-pose move's foot paths)."""

    @property
    def t0(self) -> float: ...  # start time [s]

    @property
    def t_end(self) -> float: ...  # end time [s]

    @property
    def breaks(self) -> np.ndarray: ...  # junction times [s]

    def evaluate(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ...  # position [m], velocity [m/s], acceleration [m/s²]


def check_trajectories(robot: RobotConfig, legs: Sequence[SampledPath], what: str) -> None:
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
    def joined(part: str) -> tuple[Piecewise, ...]:
        return tuple(Piecewise([seg for slot in slots for seg in getattr(slot, part)[i].segments])
                     for i in range(cfg.robot.n_legs))

    plan = WalkPlan(slots=slots, legs=joined("legs"), starts=starts, robot=cfg.robot,
                    contacts=joined("contacts"),
                    sway=Piecewise([seg for slot in slots for seg in slot.sway.segments]))
    check_trajectories(cfg.robot, plan.legs, "the walk")
    return plan


def standing_pose(cfg: Config, body_height: float | None = None) -> np.ndarray:
    """Standing joint angles ``(n_legs, 3)`` [rad] at ``body_height`` (default: configured)."""
    return inverse_kinematics(cfg.robot, cfg.robot.standing_feet(body_height))
