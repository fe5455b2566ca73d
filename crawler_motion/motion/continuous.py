"""Continuous-stance step option: the body never stops between steps (pure numpy).

The spec's step (`motion.trajectory.step_cycle`) stops the foot at the corners A and E
(v = a = 0), so with a rest-sextic stance the body comes to a halt at every lift-off and
touch-down. This module builds the alternative used by most legged-robot controllers:

- **stance** E->A at constant body speed: the foot moves back relative to the body at the
  constant velocity ``v_s = -stride / t_s`` (a straight line, a = 0);
- **swing** A->E with lift-off and touch-down velocities matched to it: at A and E the foot's
  horizontal velocity is ``v_s`` and its acceleration is zero. The body moves at
  ``-v_s = stride / t_s`` all the time, so relative to the ground the foot leaves and touches
  the seabed with zero velocity, and position, velocity and acceleration are continuous at
  every junction of the cycle (C^2), A and E included.

Construction (all segments are sextics from `trajectory.sextic_coefficients`):

- **horizontal** (x and y of base_link, i.e. along the stride vector): *one* sextic over the
  whole swing meeting position, velocity ``v_s`` and zero acceleration at A and E and the
  mid-time position ``(A + E) / 2``. The conditions are point-symmetric, so the sextic term
  vanishes and the horizontal motion is an odd quintic about mid-swing. It is then cut at the
  swing's B and D times: each of the lift / arc / lower segments gets the sextic fitted to the
  big sextic's own position, velocity and acceleration at its ends and its position at its
  mid-time, which is the same polynomial (the fit is unique), so B and D are C^2 exactly as
  the single polynomial is.
- **vertical** (z): exactly the lift / arc / lower sextics of the chosen profile (`rest` or
  `smooth`, `trajectory.swing_segments`): v = a = 0 at A and E (the stance is level), apex C
  at mid-arc, the profile's junction speeds at B and D.

Consequences (documented, tested):

- relative to the body the lift and lower are no longer vertical: the foot keeps drifting
  back after lift-off and forward before touch-down, so it passes beyond A and E. The
  overshoot past each end is a fraction of the stride that depends only on ``t_s / t_w``:
  22.9 % at 0.5, 9.7 % at 1 (the diagonal gait: 5.8 mm for the default 0.06 m stride),
  3.9 % at 2, 2.2 % at 3 (the wave gait); the workspace must allow it (the gait's checks
  do that for a planned walk);
- relative to the *ground* the horizontal motion is monotone: the foot's ground velocity
  along the stride is ``>= 0`` everywhere and zero only at A and E (the odd quintic's speed
  is smallest at the ends), so the foot never scuffs backwards;
- the quartic (``SwingShape.degree == 4``) cannot meet a = 0 at the ends and is refused.
"""

from __future__ import annotations

import math

import numpy as np

from crawler_motion.errors import TrajectoryError
from crawler_motion.motion.trajectory import (
    Piecewise,
    Segment,
    SwingShape,
    evaluate_polynomial,
    sextic_coefficients,
    swing_segments,
)

__all__ = [
    "body_velocity",
    "continuous_step_cycle",
    "continuous_swing_segments",
    "stance_velocity",
]


def _stride3(stride: np.ndarray) -> np.ndarray:
    arr = np.asarray(stride, dtype=float).reshape(-1)
    if arr.size not in (2, 3) or not np.all(np.isfinite(arr)):
        raise TrajectoryError(f"stride must be a finite ground-plane vector (2,) or (3,) [m], "
                              f"got {stride!r}")
    s = np.zeros(3)
    s[:2] = arr[:2]
    return s


def _duration(value: float, what: str) -> float:
    t = float(value)
    if not math.isfinite(t) or t <= 0.0:
        raise TrajectoryError(f"{what} must be a finite time > 0 s, got {value!r}")
    return t


def stance_velocity(stride: np.ndarray, stance_time: float) -> np.ndarray:
    """Foot velocity (3,) [m/s] relative to the body during the stance: ``-stride / t_s``."""
    return -_stride3(stride) / _duration(stance_time, "stance_time")


def body_velocity(stride: np.ndarray, stance_time: float) -> np.ndarray:
    """Body velocity (3,) [m/s] over the ground (base_link axes, no turning): ``stride / t_s``.

    A foot's velocity relative to the ground is its velocity in base_link plus this.
    """
    return _stride3(stride) / _duration(stance_time, "stance_time")


def continuous_swing_segments(a: np.ndarray, e: np.ndarray, shape: SwingShape,
                              velocity: np.ndarray, velocity_end: np.ndarray | None = None
                              ) -> list[Segment]:
    """Lift A->B, arc B->C->D, lower D->E with horizontal end velocity ``velocity`` [m/s].

    ``a`` (lift-off) and ``e`` (touch-down) are 3-vectors in base_link [m]; ``velocity`` is
    the foot's velocity at lift-off and ``velocity_end`` at touch-down (default: the same; the
    stance velocities, horizontal: their z is ignored).
    z follows ``shape.profile`` exactly as `trajectory.swing_segments`; x and y are one
    sextic over the whole swing (see the module docstring).
    """
    if shape.degree != 6:
        raise TrajectoryError(f"the continuous-stance step needs sextic segments (degree 6): a "
                              f"quartic cannot meet a = 0 at lift-off and touch-down, got "
                              f"degree {shape.degree}")
    t_w = _duration(shape.swing_time, "swing_time")
    a = np.asarray(a, dtype=float)
    e = np.asarray(e, dtype=float)
    v, w = np.zeros(3), np.zeros(3)
    v[:2] = np.asarray(velocity, dtype=float).reshape(-1)[:2]
    w[:2] = v[:2] if velocity_end is None else np.asarray(velocity_end,
                                                          dtype=float).reshape(-1)[:2]
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(w))):
        raise TrajectoryError(f"velocity must be finite, got {velocity!r}, {velocity_end!r}")
    vertical = swing_segments(a, e, shape)  # validates lift / arc; its z rows are kept
    zero = np.zeros(2)
    mid = (a[:2] + e[:2]) / 2 + 5.0 * t_w * (v[:2] - w[:2]) / 32.0  # the quintic's (glide)
    whole = sextic_coefficients(t_w, a[:2], v[:2], zero, e[:2], w[:2], zero, mid)
    segments = []
    start = 0.0
    for seg in vertical:
        end = start + seg.duration
        taus = np.array([start, end, start + seg.duration / 2])
        pos, vel, acc = evaluate_polynomial(whole, t_w, taus)  # (3 times, 2 coordinates)
        coeffs = seg.coeffs.copy()
        coeffs[:2] = sextic_coefficients(seg.duration, pos[0], vel[0], acc[0], pos[1], vel[1],
                                         acc[1], pos[2])
        segments.append(Segment(coeffs, seg.duration, seg.phase))
        start = end
    return segments


def continuous_step_cycle(center: np.ndarray, stride: np.ndarray, shape: SwingShape,
                          stance_time: float) -> Piecewise:
    """One steady-state cycle of one leg with a constant-speed stance, from lift-off A (t = 0).

    Same conventions as `trajectory.step_cycle`: ``center`` is the standing foot position
    (3,) [m], ``stride`` the ground-plane vector (2,) or (3,) from the rear end A to the front
    end E [m]; ``shape`` the swing (sextic only); ``stance_time`` [s]. Segments: lift, arc,
    lower, stance. During the stance the foot moves from E to A at ``stance_velocity``; the
    body moves at `body_velocity` throughout.
    """
    c = np.asarray(center, dtype=float).reshape(-1)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise TrajectoryError(f"center must be a finite 3-vector [m], got {center!r}")
    s = _stride3(stride)
    t_s = _duration(stance_time, "stance_time")
    v_s = -s / t_s
    a, e = c - s / 2, c + s / 2
    segments = continuous_swing_segments(a, e, shape, v_s)
    # Straight line at constant speed: the sextic of s(0) = E, v = v_s, a = 0 at both ends and
    # s(T/2) = (A + E) / 2, written in closed form (c0 = E, c1 = A - E in normalised time) so
    # that the velocity is exactly constant instead of constant to rounding.
    stance = np.zeros((3, 7))
    stance[:, 0] = e
    stance[:, 1] = a - e
    segments.append(Segment(stance, t_s, "stance"))
    return Piecewise(segments)
