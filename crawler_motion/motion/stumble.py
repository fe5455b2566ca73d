"""Stumble handling of a swinging foot (pure numpy): a foot that meets an obstacle before its
lowering segment is stopped, lifted higher and sent on again once (a C² re-plan of the rest of
its swing); a second hit ends the walk with the leg and the place instead of pushing on.

A **hit** is a foot contact (`FootContact.YES`) whose horizontal force (base_link: a step
face or a rock's flank pushes against the swing) reaches ``force`` [N] in `HIT_CONFIRM`
estimates in a row (each estimate counted once, however many ticks see it), while the leg
swings before its lowering segment, once the foot has been seen off the ground in this swing
with its planned z at least `ARM_HEIGHT` above its lift-off (a stance foot that happens to
read unloaded, or a foot still dragging off its foothold, is no hit, nor is a body that tips
onto a swinging foot: that load is vertical).

The **retry** (`replan_swing`) replaces the rest of the swing from the hit time ``t_h`` on with
four segments, each meeting the plan's state (position, velocity, acceleration) at its start:

1. **stop** (``stop_time``): every axis to rest ``v·T/2`` further (the quintic of
   `foothold.stop_quintic`: the plan's velocity and acceleration at ``t_h`` brought to 0);
2. **rise** (``rise``): rest to rest, straight up to ``lift`` above the highest point of the
   rest of the planned swing and ``retreat`` back along the swing (lift-off to touch-down);
3. **over** (``lift`` kept): rest to rest to above the planned touch-down point;
4. **lower**: from rest down to the plan's touch-down state (position, velocity,
   acceleration at the end of the swing), so the stance that follows is the plan's.

Rise and lower last ``min(lift_time, R / 3)`` each, R being the swing time left after the
stop; the over segment the rest. Where that catch-up would turn a joint faster than its limit
(the caller checks), the **vertical-only retry** (`lift_swing`) keeps the plan's horizontal
path and lifts the foot by the same top. A retried foot has **hit again** when, after its
rise and while its planned z is still above the z it first hit at, one contact estimate
reaches the hit force: what it hit is higher than the lift. A hit with less than
`MIN_RETRY_TIME` of its swing left cannot be retried, nor one whose retries both fail the
joint limits: like a second hit, they end the walk (the caller holds the pose).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crawler_motion.errors import ConfigError
from crawler_motion.model.yaml_values import number_in
from crawler_motion.motion.foothold import (
    TIME_EPS,
    lowering_start,
    polynomial,
    stop_quintic,
)
from crawler_motion.motion.trajectory import (
    Piecewise,
    Segment,
    rest_segment,
    restricted,
    sextic_coefficients,
)

#: Consecutive contact estimates at the stumble force that make a hit.
HIT_CONFIRM = 2
#: Swing time [s] a retry needs after the stop (rise, over and lower, 50 ms each at least).
MIN_RETRY_TIME = 0.15
#: Samples of the rest of the planned swing searched for its highest point.
APEX_SAMPLES = 64
#: Horizontal swing length [m] below which a hit has no swing direction to retreat along.
MIN_STRIDE = 1e-4


@dataclass(frozen=True)
class StumbleSettings:
    """``enabled`` (acts only with the foot contacts of the terrain-adaptive touch-down), the
    hit ``force`` [N], the extra ``lift`` above the planned swing [m], the ``retreat`` back
    along the swing [m], the longest ``lift_time`` of the rise and of the lowering [s] and the
    ``stop_time`` of the stop at the hit [s]."""

    enabled: bool = True
    force: float = 10.0
    lift: float = 0.015
    retreat: float = 0.0
    lift_time: float = 0.12
    stop_time: float = 0.04

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise ConfigError(f"stumble enabled must be true or false, got {self.enabled!r}")
        for name, lo, hi, unit in (("force", 0.0, 100.0, "N"), ("lift", 0.0, 0.05, "m"),
                                   ("retreat", 0.0, 0.03, "m"), ("lift_time", 0.05, 1.0, "s"),
                                   ("stop_time", 0.005, 0.5, "s")):
            number_in(getattr(self, name), f"stumble {name}", lo, hi, unit)


@dataclass(frozen=True)
class Retry:
    """A re-planned swing: the leg's new trajectory, the times [s] in slot time the rise ends
    (from then on a hit is a second hit) and the new lowering starts, and the top z [m]."""

    plan: Piecewise
    t_top: float
    t_lower: float
    z_top: float


def _stop_segment(p: np.ndarray, v: np.ndarray, a: np.ndarray, duration: float) -> Segment:
    """Every axis from ``p``, ``v``, ``a`` to rest (`foothold.stop_quintic`), as a sextic."""
    coeffs = [stop_quintic(float(p[k]), float(v[k]), float(a[k]), duration) for k in range(3)]
    end = np.array([polynomial(c, duration)[0] for c in coeffs])
    mid = np.array([polynomial(c, duration / 2.0)[0] for c in coeffs])
    zero = np.zeros(3)
    return Segment(sextic_coefficients(duration, p, v, a, end, zero, zero, mid), duration, "lift")


def _head(plan: Piecewise, t: float) -> list[Segment]:
    """The segments of ``plan`` before time ``t`` [s] (the one holding ``t`` cut there)."""
    out = []
    for seg, start in zip(plan.segments, plan.breaks[:-1], strict=True):
        if start + seg.duration <= t + TIME_EPS:
            out.append(seg)
        elif t - start > TIME_EPS:
            out.append(restricted(seg, 0.0, t - start))
    return out


def _tail(plan: Piecewise, t: float) -> list[Segment]:
    """The segments of ``plan`` from time ``t`` [s] (a junction) on."""
    return [seg for seg, start in zip(plan.segments, plan.breaks[:-1], strict=True)
            if start >= t - TIME_EPS]


def replan_swing(plan: Piecewise, swing_time: float, t_hit: float,
                 settings: StumbleSettings) -> Retry | None:
    """The leg trajectory ``plan`` (slot time from 0; its swing ends at ``swing_time`` [s])
    with the rest of its swing from ``t_hit`` [s] re-planned as in the module docstring (stop,
    rise and retreat, over, lower), or None if the hit is too late for it (less than
    `MIN_RETRY_TIME` left)."""
    s = settings
    left = swing_time - t_hit - s.stop_time
    if left < MIN_RETRY_TIME - TIME_EPS:
        return None
    rise = min(s.lift_time, left / 3.0)
    over = left - 2.0 * rise
    pos, vel, acc = (x[0] for x in plan.evaluate(t_hit))
    end_p, end_v, end_a = (x[0] for x in plan.evaluate(swing_time))
    z_top = _top(plan, swing_time, t_hit, s)
    stop = _stop_segment(pos, vel, acc, s.stop_time)
    top = stop.end.copy()
    stride = end_p[:2] - plan.evaluate(plan.t0)[0][0, :2]
    length = math.hypot(float(stride[0]), float(stride[1]))
    if length > MIN_STRIDE:
        top[:2] -= s.retreat * stride / length
    top[2] = z_top
    above = np.array([end_p[0], end_p[1], z_top])
    segments = [*_head(plan, t_hit), stop, rest_segment(stop.end, top, rise, "lift"),
                rest_segment(top, above, over, "arc"), _lower(above, end_p, end_v, end_a, rise),
                *_tail(plan, swing_time)]
    t_top = t_hit + s.stop_time + rise
    return Retry(Piecewise(segments, plan.t0), t_top, t_top + over, z_top)


def lift_swing(plan: Piecewise, swing_time: float, t_hit: float, settings: StumbleSettings
               ) -> Retry | None:
    """The vertical-only retry, for a hit too late for `replan_swing`'s catch-up (its joint
    rates beyond the limits): the foot
    keeps the plan's horizontal path; its z rises from the plan's state at ``t_hit`` [s] to
    rest at the top (`replan_swing`'s) within ``lift_time`` (at most a third of the swing
    left), stays there until the plan's lowering starts (or a third of the swing left before
    its end, if later) and lowers from rest to the plan's touch-down state; None if less than
    `MIN_RETRY_TIME` of the swing is left."""
    left = swing_time - t_hit
    if left < MIN_RETRY_TIME - TIME_EPS:
        return None
    rise = min(settings.lift_time, left / 3.0)
    t_down = min(max(lowering_start(plan, swing_time), t_hit + rise), swing_time - left / 3.0)
    z_top = _top(plan, swing_time, t_hit, settings)
    pos, vel, acc = (x[0] for x in plan.evaluate(t_hit))
    end_p, end_v, end_a = (x[0] for x in plan.evaluate(swing_time))
    mid = polynomial(stop_quintic(float(pos[2]), float(vel[2]), float(acc[2]), rise),
                     rise / 2.0)[0]
    top = np.array([z_top])
    up = sextic_coefficients(rise, pos[2:], vel[2:], acc[2:], top, np.zeros(1), np.zeros(1),
                             np.array([(mid + z_top) / 2.0]))
    vertical = [Segment(up, rise, "lift")]
    if t_down - t_hit - rise > TIME_EPS:
        vertical.append(rest_segment(top, top, t_down - t_hit - rise, "arc"))
    vertical.append(_lower(top, end_p[2:], end_v[2:], end_a[2:], swing_time - t_down))
    horizontal = [restricted(seg, max(0.0, t_hit - start), min(seg.duration,
                                                                swing_time - start)
                             - max(0.0, t_hit - start))
                  for seg, start in zip(plan.segments, plan.breaks[:-1], strict=True)
                  if start + seg.duration > t_hit + TIME_EPS and start < swing_time - TIME_EPS]
    segments = [*_head(plan, t_hit), *_merged(horizontal, vertical), *_tail(plan, swing_time)]
    return Retry(Piecewise(segments, plan.t0), t_hit + rise, t_down, z_top)


def _top(plan: Piecewise, swing_time: float, t_hit: float, settings: StumbleSettings
         ) -> float:
    """The retry's top z [m]: ``lift`` above the highest point of the rest of the swing."""
    pos = plan.evaluate(np.linspace(t_hit, swing_time, APEX_SAMPLES))[0][:, 2]
    return float(pos.max()) + settings.lift


def _lower(start: np.ndarray, end: np.ndarray, v_end: np.ndarray, a_end: np.ndarray,
           duration: float) -> Segment:
    """From rest at ``start`` to the state ``end``, ``v_end``, ``a_end`` (any dimension)."""
    zero = np.zeros_like(start)
    mid = (start + end) / 2.0 - 5.0 * duration * v_end / 32.0
    return Segment(sextic_coefficients(duration, start, zero, zero, end, v_end, a_end, mid),
                   duration, "lower")


def _merged(horizontal: list[Segment], vertical: list[Segment]) -> list[Segment]:
    """Segments with x, y of ``horizontal`` and z of ``vertical`` (both laid end to end over
    the same span), cut at the junctions of both; phases from ``vertical``."""
    def cuts(segs: list[Segment]) -> list[float]:
        return [float(x) for x in np.cumsum([seg.duration for seg in segs])]
    times = sorted(set(np.round(cuts(horizontal) + cuts(vertical), 12)))
    out, start = [], 0.0
    for end in times:
        if end - start <= TIME_EPS:
            continue
        rows = []
        for segs, axes in ((horizontal, slice(0, 2)), (vertical, slice(-1, None))):
            t0 = 0.0
            for seg in segs:
                if start < t0 + seg.duration - TIME_EPS:
                    part = restricted(seg, start - t0, end - start)
                    phase = seg.phase
                    break
                t0 += seg.duration
            coeffs = np.zeros((part.coeffs.shape[0], 7))
            coeffs[:, :part.coeffs.shape[1]] = part.coeffs
            rows.append(coeffs[axes])
        out.append(Segment(np.vstack(rows), end - start, phase))
        start = end
    return out


#: A swing watches for hits once its planned foot z is this far above its lift-off z [m] and
#: the foot reads off the ground (below it, a contact is the lift-off's own drag).
ARM_HEIGHT = 0.005


class HitWatch:
    """Per-leg hit detection of the swings of a slot, in slot time [s]: `begin` each swing,
    `update` every contact estimate; see the module docstring (a retried leg's second hit
    needs one estimate at the force, not `HIT_CONFIRM`: it is expected, and pushing on)."""

    def __init__(self, n_legs: int) -> None:
        self.n_legs = n_legs
        self.clear()

    def clear(self) -> None:
        """No leg swings."""
        n = self.n_legs
        self._window: list[tuple[float, float] | None] = [None] * n  # (from, to) [s]
        self._armed = [False] * n
        self._pressed = [0] * n
        self._above = [math.inf] * n  # a second hit needs the foot above this z [m]
        self._arm_z = [math.inf] * n  # arming needs the planned z above this [m]
        self._stamp = [math.nan] * n  # the estimate last counted
        self.retried = [False] * n

    def begin(self, i: int, t_lower: float, z_lift_off: float) -> None:
        """Leg ``i`` swings from slot time 0 and the planned foot z ``z_lift_off`` [m]; hits
        count until ``t_lower`` [s]."""
        self._window[i] = (0.0, t_lower)
        self._armed[i] = False
        self._pressed[i] = 0
        self._above[i] = -math.inf
        self._arm_z[i] = z_lift_off + ARM_HEIGHT
        self._stamp[i] = math.nan
        self.retried[i] = False

    def retry(self, i: int, retry: Retry, z_hit: float) -> None:
        """Leg ``i`` was re-planned after a hit at the planned foot z ``z_hit`` [m]: watch for
        the second hit from the end of its rise to the end of its swing."""
        self._window[i] = (retry.t_top, retry.plan.t_end)
        self._armed[i] = True
        self._pressed[i] = 0
        self._above[i] = z_hit
        self.retried[i] = True

    def update(self, t: float, touching: list[bool], forces: list[float], force: float,
               z: list[float], stamp: float) -> list[int]:
        """The legs hit at slot time ``t`` [s] from the contact estimate of ``stamp`` [s] (an
        estimate already counted is not counted again): the contacts, their horizontal forces
        [N], the planned foot z [m] (``force`` the hit force [N]); a leg reported stops
        watching until `begin` / `retry`."""
        hits = []
        for i, window in enumerate(self._window):
            if window is None:
                continue
            if t >= window[1] - TIME_EPS or (self.retried[i] and t >= window[0]
                                             and z[i] <= self._above[i]):
                self._window[i] = None  # a retried foot below its hit: it is landing
                continue
            if stamp == self._stamp[i]:
                continue
            self._stamp[i] = stamp
            if not touching[i]:
                self._armed[i] = self._armed[i] or z[i] >= self._arm_z[i]
                self._pressed[i] = 0
                continue
            if t < window[0] or not self._armed[i]:
                continue
            self._pressed[i] = self._pressed[i] + 1 if forces[i] >= force else 0
            if self._pressed[i] >= (1 if self.retried[i] else HIT_CONFIRM):
                self._window[i] = None
                hits.append(i)
        return hits
