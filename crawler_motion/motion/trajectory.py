"""Piecewise polynomial foot trajectories: sextic segments (and the study's quartic).

A segment is a polynomial in normalised time ``u = tau / T`` (``u`` in [0, 1]) fitted to
boundary conditions; coordinates are the last axis, so a foot segment has coefficients shaped
``(3, degree + 1)`` (x, y, z in base_link [m]) and a joint-space move ``(n, degree + 1)``.

One leg's step (see the spec): lift A->B (vertical), arc B->C->D (horizontal A->E with apex C),
lower D->E (vertical), stance E->A (straight, on the ground). Profiles:

- ``rest``: every junction v = a = 0 (the study's first design);
- ``smooth``: v != 0, a = 0 at B and D, continuous through the swing; lift faster than lower.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from crawler_motion.errors import TrajectoryError
from crawler_motion.model.gait_config import ProfileConfig

PHASES: tuple[str, ...] = ("lift", "arc", "lower", "stance")


def _inverse(rows: list[list[float]]) -> np.ndarray:
    return np.linalg.inv(np.array(rows, dtype=float))


# Sextic, normalised time: c0..c2 come from the start; c3..c6 solve s(1), s'(1), s''(1), s(1/2).
_SEXTIC_INV = _inverse([
    [1, 1, 1, 1],
    [3, 4, 5, 6],
    [6, 12, 20, 30],
    [1 / 8, 1 / 16, 1 / 32, 1 / 64],
])
# Quartic: c0, c1 from the start; c2..c4 solve s(1), s'(1), s(1/2).
_QUARTIC_INV = _inverse([
    [1, 1, 1],
    [2, 3, 4],
    [1 / 4, 1 / 8, 1 / 16],
])


def sextic_coefficients(duration: float, s0: np.ndarray, v0: np.ndarray, a0: np.ndarray,
                        s1: np.ndarray, v1: np.ndarray, a1: np.ndarray, s_mid: np.ndarray
                        ) -> np.ndarray:
    """Coefficients ``(..., 7)`` in normalised time of the sextic meeting the 7 constraints.

    Positions in m, velocities in m/s, accelerations in m/s^2 (any consistent units); inputs
    broadcast against each other. ``s_mid`` is the position at ``duration / 2``.
    """
    t = _check_duration(duration)
    s0, v0, a0, s1, v1, a1, s_mid = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (s0, v0, a0, s1, v1, a1, s_mid)))
    c0, c1, c2 = s0, v0 * t, a0 * t * t / 2.0
    rhs = np.stack((
        s1 - c0 - c1 - c2,
        v1 * t - c1 - 2 * c2,
        a1 * t * t - 2 * c2,
        s_mid - c0 - c1 / 2 - c2 / 4,
    ), axis=-1)
    out = np.empty((*rhs.shape[:-1], 7))
    out[..., 0], out[..., 1], out[..., 2] = c0, c1, c2
    out[..., 3:] = rhs @ _SEXTIC_INV.T
    return out


def quartic_coefficients(duration: float, s0: np.ndarray, v0: np.ndarray, s1: np.ndarray,
                         v1: np.ndarray, s_mid: np.ndarray) -> np.ndarray:
    """Coefficients ``(..., 5)`` in normalised time of the study's quartic (5 constraints)."""
    t = _check_duration(duration)
    s0, v0, s1, v1, s_mid = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (s0, v0, s1, v1, s_mid)))
    c0, c1 = s0, v0 * t
    rhs = np.stack((s1 - c0 - c1, v1 * t - c1, s_mid - c0 - c1 / 2), axis=-1)
    high = rhs @ _QUARTIC_INV.T
    return np.concatenate((np.stack((c0, c1), axis=-1), high), axis=-1)


def _check_duration(duration: float) -> float:
    t = float(duration)
    if not np.isfinite(t) or t <= 0.0:
        raise TrajectoryError(f"segment duration must be a finite time > 0 s, got {duration!r}")
    return t


def evaluate_polynomial(coeffs: np.ndarray, duration: float | np.ndarray,
                        tau: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration of a normalised-time polynomial at ``tau`` [s].

    ``coeffs`` is ``(..., degree + 1)``; the result has shape ``tau.shape + coeffs.shape[:-1]``.
    ``duration`` may be an array broadcasting against ``tau[..., None]`` (one per sample).
    """
    c = np.asarray(coeffs, dtype=float)
    u = np.asarray(tau, dtype=float)[..., None] / duration if c.ndim > 1 else (
        np.asarray(tau, dtype=float) / duration)
    deg = c.shape[-1] - 1
    pos = np.zeros(np.broadcast_shapes(np.shape(u), c.shape[:-1]))
    vel = np.zeros_like(pos)
    acc = np.zeros_like(pos)
    for i in range(deg, -1, -1):
        acc = acc * u + 2 * vel
        vel = vel * u + pos
        pos = pos * u + c[..., i]
    return pos, vel / duration, acc / duration**2


@dataclass(frozen=True)
class Segment:
    """One polynomial piece: ``coeffs`` ``(dims, degree + 1)`` in normalised time."""

    coeffs: np.ndarray
    duration: float
    phase: str = ""

    def evaluate(self, tau: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration ``(len(tau), dims)`` at segment time ``tau`` [s]."""
        return evaluate_polynomial(self.coeffs, self.duration, tau)

    @property
    def start(self) -> np.ndarray:
        """Position at tau = 0."""
        return self.coeffs[:, 0].copy()

    @property
    def end(self) -> np.ndarray:
        """Position at tau = duration."""
        return self.coeffs.sum(axis=-1)


class Piecewise:
    """A sequence of segments in time, starting at ``t0`` [s]; evaluation is vectorised."""

    def __init__(self, segments: Sequence[Segment], t0: float = 0.0) -> None:
        if not segments:
            raise TrajectoryError("a piecewise trajectory needs at least one segment")
        dims = {seg.coeffs.shape for seg in segments}
        degree = max(seg.coeffs.shape[-1] for seg in segments) - 1
        if len({shape[0] for shape in dims}) != 1:
            raise TrajectoryError(f"segments differ in dimension: {sorted(dims)}")
        self.segments: tuple[Segment, ...] = tuple(segments)
        self.durations = np.array([seg.duration for seg in segments])
        self.breaks = t0 + np.concatenate(([0.0], np.cumsum(self.durations)))
        self.phases: tuple[str, ...] = tuple(seg.phase for seg in segments)
        coeffs = np.zeros((len(segments), next(iter(dims))[0], degree + 1))
        for k, seg in enumerate(segments):  # lower degrees padded with zeros
            coeffs[k, :, :seg.coeffs.shape[-1]] = seg.coeffs
        self.coeffs = coeffs  # (n_segments, dims, degree + 1)

    @property
    def t0(self) -> float:
        """Start time [s]."""
        return float(self.breaks[0])

    @property
    def t_end(self) -> float:
        """End time [s]."""
        return float(self.breaks[-1])

    @property
    def duration(self) -> float:
        """Total duration [s]."""
        return float(self.breaks[-1] - self.breaks[0])

    def index(self, t: np.ndarray | float) -> np.ndarray:
        """Segment index for each time; times outside the span map to the first/last segment."""
        idx = np.searchsorted(self.breaks, t, side="right") - 1
        return np.clip(idx, 0, len(self.segments) - 1)

    def evaluate(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration ``(len(t), dims)`` at absolute times ``t`` [s].

        Times before ``t0`` or after ``t_end`` hold the end state (zero velocity/acceleration
        is not implied: the end segment is evaluated at its boundary).
        """
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        idx = self.index(tt)
        duration = self.durations[idx]
        tau = np.clip(tt - self.breaks[idx], 0.0, duration)
        return evaluate_polynomial(self.coeffs[idx], duration[:, None], tau)

    def phase_at(self, t: np.ndarray | float) -> list[str]:
        """Phase label of the segment active at each time."""
        return [self.phases[i] for i in self.index(np.atleast_1d(t))]

    def shifted(self, dt: float) -> Piecewise:
        """The same trajectory starting ``dt`` seconds later."""
        return Piecewise(self.segments, self.t0 + dt)


#: Peak speed of a `rest_segment` in units of distance / duration (at mid-time: its
#: symmetric sextic is the quintic ``10 u^3 - 15 u^4 + 6 u^5``).
REST_PEAK_SPEED = 1.875


def rest_segment(start: np.ndarray, end: np.ndarray, duration: float, phase: str = ""
                 ) -> Segment:
    """Straight sextic from ``start`` to ``end`` with v = a = 0 at both ends (any dimension)."""
    s0 = np.asarray(start, dtype=float)
    s1 = np.asarray(end, dtype=float)
    zero = np.zeros_like(s0)
    coeffs = sextic_coefficients(duration, s0, zero, zero, s1, zero, zero, (s0 + s1) / 2)
    return Segment(coeffs, float(duration), phase)


def glide_segment(start: np.ndarray, end: np.ndarray, duration: float, v_start: np.ndarray,
                  v_end: np.ndarray, phase: str = "") -> Segment:
    """Straight quintic (stored as a sextic) from ``start`` to ``end`` with velocities
    ``v_start``, ``v_end`` [m/s] and a = 0 at both ends; `rest_segment` is the case v = 0.
    (The quintic's mid-time position is ``(s0 + s1) / 2 + 5 T (v0 - v1) / 32``.)"""
    s0, s1 = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    v0, v1 = np.asarray(v_start, dtype=float), np.asarray(v_end, dtype=float)
    zero = np.zeros_like(s0)
    mid = (s0 + s1) / 2 + 5.0 * float(duration) * (v0 - v1) / 32.0
    coeffs = sextic_coefficients(duration, s0, v0, zero, s1, v1, zero, mid)
    return Segment(coeffs, float(duration), phase)


@dataclass(frozen=True)
class SwingShape:
    """Geometry and timing of one swing: heights in m, time in s."""

    lift: float  # A->B rise [m]
    arc: float  # apex C above B [m]
    swing_time: float  # A->E [s]
    profile: ProfileConfig
    degree: int = 6  # 6 = sextic, 4 = the study's quartic (v = 0 junctions only)


#: By coefficient count n, over the grid (k, j) of `restricted`'s change of variable: where
#: j <= k, the exponents max(k - j, 0) and j; and the binomials C(k, j) (0 above k).
_POWERS = {n: (kk >= jj, np.maximum(kk - jj, 0), jj) for n, (kk, jj) in (
    (n, np.meshgrid(np.arange(n), np.arange(n), indexing="ij")) for n in range(1, 9))}
_BINOMIAL = {n: np.array([[math.comb(k, j) if j <= k else 0 for j in range(n)]
                          for k in range(n)], dtype=float) for n in range(1, 9)}


def restricted(segment: Segment, start: float, duration: float) -> Segment:
    """The part of ``segment`` from ``start`` [s] lasting ``duration`` [s], as a segment of
    its own (same polynomial, re-parametrised: ``p(u0 + (u1 - u0) v)``, binomial expansion)."""
    u0, width = start / segment.duration, duration / segment.duration
    c = segment.coeffs
    n = c.shape[-1]
    # (u0 + width v)^k = sum_j C(k, j) u0^(k-j) width^j v^j
    below, k_minus_j, j = _POWERS[n]
    change = np.where(below, _BINOMIAL[n] * float(u0) ** k_minus_j * float(width) ** j, 0.0)
    return Segment(c @ change, _check_duration(duration), segment.phase)


def minus_path(segments: Sequence[Segment], path: Segment) -> list[Segment]:
    """``segments`` (laid end to end over ``path``'s duration) minus ``path``: e.g. a foot's
    path in the world seen from a body that moves by ``path`` [m]."""
    out, t = [], 0.0
    for seg in segments:
        part = restricted(path, t, seg.duration).coeffs
        width = max(part.shape[-1], seg.coeffs.shape[-1])
        diff = np.zeros((*seg.coeffs.shape[:-1], width))
        diff[..., :seg.coeffs.shape[-1]] += seg.coeffs
        diff[..., :part.shape[-1]] -= part
        out.append(Segment(diff, seg.duration, seg.phase))
        t += seg.duration
    return out


#: Breakpoints closer than this are one [s] (`minus_segments`).
BREAK_EPS = 1e-9


def minus_segments(segments: Sequence[Segment], path: Sequence[Segment]) -> list[Segment]:
    """``segments`` minus ``path``, both laid end to end from 0 over the same time, split at
    the breakpoints of both (each piece keeps the phase of its part of ``segments``): e.g. a
    foot's planned path seen from a body that sways by ``path`` [m]."""
    def ends(parts: Sequence[Segment]) -> np.ndarray:
        return np.cumsum([0.0] + [seg.duration for seg in parts])

    mine, theirs = ends(segments), ends(path)
    if abs(mine[-1] - theirs[-1]) > 1e-6:
        raise TrajectoryError(f"cannot subtract a path of {theirs[-1]:g} s from segments of "
                              f"{mine[-1]:g} s")
    breaks = [0.0]
    for t in sorted(np.concatenate((mine[1:], theirs[1:]))):
        if t - breaks[-1] > BREAK_EPS:
            breaks.append(float(t))
    breaks[-1] = float(mine[-1])
    out = []
    for t0, t1 in pairwise(breaks):
        mid = (t0 + t1) / 2
        i = min(int(np.searchsorted(mine, mid)) - 1, len(segments) - 1)
        j = min(int(np.searchsorted(theirs, mid)) - 1, len(path) - 1)
        own = restricted(segments[i], t0 - mine[i], t1 - t0)
        out.extend(minus_path([own], restricted(path[j], t0 - theirs[j], t1 - t0)))
    return out


def swing_segments(a: np.ndarray, e: np.ndarray, shape: SwingShape) -> list[Segment]:
    """Lift A->B, arc B->C->D and lower D->E from lift-off ``a`` to touch-down ``e`` [m].

    ``a`` and ``e`` are 3-vectors in base_link; the stride direction is ``e - a`` projected
    on the ground plane (any heading). Junction speeds at B and D are ``profile.v_b`` and
    ``profile.v_d`` times the mean vertical speed of the lift and lower segments.
    """
    a = np.asarray(a, dtype=float)
    e = np.asarray(e, dtype=float)
    if shape.lift <= 0 or shape.arc < 0:
        raise TrajectoryError(f"need lift > 0 and arc >= 0 m, got {shape.lift}, {shape.arc}")
    prof = shape.profile
    t_lift = prof.lift_fraction * shape.swing_time
    t_arc = prof.arc_fraction * shape.swing_time
    t_lower = prof.lower_fraction * shape.swing_time
    b = a + np.array([0.0, 0.0, shape.lift])
    d = e + np.array([0.0, 0.0, shape.lift])
    v_b = np.array([0.0, 0.0, prof.v_b * shape.lift / t_lift])
    v_d = np.array([0.0, 0.0, -prof.v_d * shape.lift / t_lower])
    zero = np.zeros(3)
    apex = (b + d) / 2 + np.array([0.0, 0.0, shape.arc])
    if shape.degree == 6:
        lift = sextic_coefficients(t_lift, a, zero, zero, b, v_b, zero, (a + b) / 2)
        arc = sextic_coefficients(t_arc, b, v_b, zero, d, v_d, zero, apex)
        lower = sextic_coefficients(t_lower, d, v_d, zero, e, zero, zero, (d + e) / 2)
    elif shape.degree == 4:
        lift = quartic_coefficients(t_lift, a, zero, b, v_b, (a + b) / 2)
        arc = quartic_coefficients(t_arc, b, v_b, d, v_d, apex)
        lower = quartic_coefficients(t_lower, d, v_d, e, zero, (d + e) / 2)
    else:
        raise TrajectoryError(f"degree must be 6 (sextic) or 4 (quartic), got {shape.degree}")
    return [Segment(lift, t_lift, "lift"), Segment(arc, t_arc, "arc"),
            Segment(lower, t_lower, "lower")]


def step_cycle(center: np.ndarray, stride: np.ndarray, shape: SwingShape, stance_time: float
               ) -> Piecewise:
    """One steady-state cycle of one leg, starting at lift-off A (t = 0).

    ``center`` is the standing foot position (3,) [m]; ``stride`` the ground-plane vector
    (2,) or (3,) from the rear end A to the front end E [m].
    """
    c = np.asarray(center, dtype=float)
    s = np.zeros(3)
    s[: len(stride)] = np.asarray(stride, dtype=float)[:3]
    s[2] = 0.0
    a, e = c - s / 2, c + s / 2
    segments = swing_segments(a, e, shape)
    segments.append(rest_segment(e, a, stance_time, "stance"))
    return Piecewise(segments)
