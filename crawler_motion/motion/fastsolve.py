"""`FastKinematics.solve` in one pass per leg, for the common case of a control tick.

`nominal_solve`: the closed-form IK and the joint rates of nominal legs, operation for
operation as `FastKinematics.inverse` and `FastKinematics.velocities` (the same numbers);
`calibrated_solve`: each calibrated leg's warm-started refinement and the rates through its
last Jacobian, as `FastKinematics.solve` takes them. Both return None when a leg leaves that
case (out of reach or of the limits, near a singularity, no warm start, wrong sizes): the
caller then takes the general path, which decides and raises as before.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from crawler_motion.model import kinematics

if TYPE_CHECKING:  # pragma: no cover
    from crawler_motion.motion.fastchain import ScalarLeg
    from crawler_motion.motion.fastpath import FastKinematics

_PI = math.pi
_TWO_PI = 2.0 * math.pi


def wrap(angle: float) -> float:
    """Wrap to (-pi, pi] exactly like `kinematics._wrap`."""
    return _PI - (_PI - angle) % _TWO_PI


def nominal_solve(kin: FastKinematics, feet: Sequence[float], foot_velocity: Sequence[float]
             ) -> tuple[list[float], list[float]] | None:
    """`FastKinematics.inverse` then `velocities` of nominal legs in one pass, operation for
    operation (same numbers); None when a leg leaves the fast path (out of reach or of the
    limits, near a singularity, wrong sizes): the caller then takes the two calls."""
    n = 3 * kin.n_legs
    if len(feet) != n or len(foot_velocity) != n:
        return None
    d_hi, d_lo, l2sq, l3sq, den, _, _, inside = kin._lim
    lo0, lo1, lo2, hi0, hi1, hi2 = inside
    l1, l2, l3 = kin.l1, kin.l2, kin.l3
    axis, singular = kinematics.AXIS_EPS, kinematics.SINGULAR_EPS
    q: list[float] = []
    qd: list[float] = []
    j = 0
    for hx, hy, hz, yaw0, sign in kin._legs:
        qx, qy, w = feet[j] - hx, feet[j + 1] - hy, feet[j + 2] - hz
        r = math.hypot(qx, qy)
        u = r - l1
        d2 = u * u + w * w
        d = math.sqrt(d2)
        if not (d_lo <= d <= d_hi and r >= axis):  # also NaN / inf
            return None
        ck = (d2 - l2sq - l3sq) / den
        knee = sign * math.acos(-1.0 if ck < -1.0 else (1.0 if ck > 1.0 else ck))
        sk = math.sin(knee)
        shoulder = wrap(math.atan2(w, u) + math.atan2(l3 * sk, l2 + l3 * math.cos(knee)))
        root = wrap(math.atan2(qy, qx) - yaw0)
        if not (lo0 <= root <= hi0 and lo1 <= shoulder <= hi1 and lo2 <= knee <= hi2):
            return None
        tibia = shoulder - knee
        s2, c2 = math.sin(shoulder), math.cos(shoulder)
        s23, c23 = math.sin(tibia), math.cos(tibia)
        rr = l1 + (l2 * c2 + l3 * c23)
        det = l2 * l3 * sk
        if not (abs(rr) >= axis and abs(det) >= singular):
            return None
        yaw = yaw0 + root
        cy, sy = math.cos(yaw), math.sin(yaw)
        vx, vy, w_dot = foot_velocity[j], foot_velocity[j + 1], foot_velocity[j + 2]
        r_dot = cy * vx + sy * vy
        j11, j12 = -l2 * s2 - l3 * s23, l3 * s23
        j21, j22 = l2 * c2 + l3 * c23, -l3 * c23
        q += (root, shoulder, knee)
        qd += ((-sy * vx + cy * vy) / rr, (j22 * r_dot - j12 * w_dot) / det,
               (-j21 * r_dot + j11 * w_dot) / det)
        j += 3
    return q, qd


def calibrated_solve(kin: FastKinematics, chains: Sequence[ScalarLeg], feet: Sequence[float],
                     foot_velocity: Sequence[float]) -> tuple[list[float], list[float]] | None:
    """Joint angles [rad] and rates [rad/s] of calibrated legs from each leg's warm start
    (`ScalarLeg.warm`, then `ScalarLeg.rates_last`), inside the limits; None otherwise (the
    legs before the one that left keep their new solution, as in `FastKinematics.inverse`)."""
    n = 3 * kin.n_legs
    if len(feet) != n or len(foot_velocity) != n:
        return None
    lo0, lo1, lo2, hi0, hi1, hi2 = kin._lim[7]
    kept = kin._kept
    q: list[float] = []
    qd: list[float] = []
    for i, chain in enumerate(chains):
        j = 3 * i
        angles = chain.warm(feet[j], feet[j + 1], feet[j + 2])
        if angles is None:
            return None
        a0, a1, a2 = angles
        if not (lo0 <= a0 <= hi0 and lo1 <= a1 <= hi1 and lo2 <= a2 <= hi2):
            return None
        kept[i] = angles
        rates = chain.rates_last(foot_velocity[j], foot_velocity[j + 1], foot_velocity[j + 2])
        if rates is None:
            return None
        q += angles
        qd += rates
    return q, qd
