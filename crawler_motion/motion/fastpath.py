"""Per-tick fast path: trajectories, IK and joint rates of one instant in plain floats.

The public numpy API (`Piecewise.evaluate`, `kinematics.inverse_kinematics`,
`kinematics.joint_velocities`) is vectorised for batches and is the reference; for one time
instant its cost is dominated by numpy's per-call overhead (dozens of ufunc calls on 12
numbers). This module computes the same numbers for one instant with `math` on Python floats,
and is what the planner's tick runs wherever the slot's `jointtable.JointTable` does not serve
it (feet moved off the blind plan, or a cell the table left to it):

- `Track` holds rows of `Piecewise` trajectories (a gait slot's feet, or a joint-space move)
  as tuples of coefficients and the active segment of each (found again with `bisect` only


- `FastKinematics` is the closed-form IK and the analytic Jacobian inverse of
  `crawler_motion.model.kinematics`, operation for operation, for all legs; with calibrated
  legs the Newton refinement of `fastchain.ScalarLeg` (the float form of
  `crawler_motion.model.calibrated`) starts from the leg's last solution, or from the closed
  form when there is none or it misses, and the Jacobian of its last evaluation gives the
  joint rates at the angles `inverse` returned;
- `joint_targets` chains them: one call per control tick.

Nominal legs: results equal the numpy path to rounding (tested to 1e-12 over whole walks).
Calibrated legs: the feet land within `fastchain.STEP_BOUND` (1e-8 m) of the target (the
reference's within `calibrated.IK_ACCEPT`, 1e-7 m); joint rates are the reference's at the
returned angles to ~1e-4 of their size (their Jacobian is taken up to a last Newton step
away; see `fastchain`). Errors are identical by construction: whenever a fast check finds a
target outside the workspace, an angle outside the joint limits or a singular Jacobian, the
numpy function is called on the same input and raises its own `UnreachableError` /
`JointLimitError` / `KinematicsError` (should it not raise, a disagreement within rounding at
a boundary, its result is returned).

Flat vectors are leg-major, as ``array.reshape(-1)`` of the ``(n_legs, 3)`` arrays: positions
``x, y, z`` [m] / velocities [m/s] per leg, joints ``root, shoulder, knee`` [rad] / [rad/s].
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence

import numpy as np

from crawler_motion.errors import KinematicsError, TrajectoryError
from crawler_motion.model import kinematics
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.leg_geometry import joint_frames
from crawler_motion.motion.fastchain import ScalarLeg
from crawler_motion.motion.fastsolve import calibrated_solve, nominal_solve, wrap
from crawler_motion.motion.trajectory import Piecewise

__all__ = ["DEGREE", "FastKinematics", "Track", "joint_targets"]

_PI = math.pi
#: Highest polynomial degree a `Track` evaluates (sextic; lower degrees are zero-padded).
DEGREE = 6

#: One segment of one row set: start [s], duration [s], end [s], rows of the 7 coefficients
#: of the position and the 6 of the velocity.
_Segment = tuple[float, float, float, tuple[tuple[float, ...], ...]]


def _segments(pw: Piecewise, dims: int) -> tuple[list[float], tuple[_Segment, ...]]:
    """Breakpoints [s] and float segments of ``pw``; refuses other dimensions / degrees."""
    shapes = {seg.coeffs.shape for seg in pw.segments}
    if any(shape[0] != dims or shape[1] > DEGREE + 1 for shape in shapes):
        raise TrajectoryError(f"Track needs {dims}-D trajectories of degree <= {DEGREE}, "
                              f"got coefficients {sorted(shapes)}")
    coeffs = np.zeros((len(pw.segments), dims, DEGREE + 1))
    for k, seg in enumerate(pw.segments):
        coeffs[k, :, :seg.coeffs.shape[1]] = seg.coeffs
    breaks = [float(b) for b in pw.breaks]
    durations = [float(x) for x in pw.durations]
    # each row: the 7 coefficients of p(u), then the 6 of p'(u) / duration (planned once)
    return breaks, tuple(
        (breaks[k], durations[k], breaks[k + 1],
         tuple((*(float(x) for x in row),
                *(float(n * row[n] / durations[k]) for n in range(1, DEGREE + 1)))
               for row in coeffs[k]))
        for k in range(len(pw.segments)))


class Track:
    """Position and velocity of several `Piecewise` trajectories at one time, flat.

    ``pieces`` are ``dims``-dimensional trajectories (one per leg with ``dims`` 3, e.g.
    `gait.Slot.legs`; or one joint-space move of all joints). Semantics of
    `Piecewise.evaluate`: times before the start or after the end hold the first / last
    segment evaluated at its boundary. Keeps the active segment of each piece, so consecutive
    calls with increasing times cost one comparison per piece.
    """

    __slots__ = ("_active", "_pieces", "duration", "n_pieces", "t0", "t_end")

    def __init__(self, pieces: Sequence[Piecewise], dims: int = 3) -> None:
        if not pieces:
            raise TrajectoryError("Track needs at least one trajectory")
        self.n_pieces = len(pieces)
        self._pieces = [_segments(pw, dims) for pw in pieces]
        self._active = [segments[0] for _, segments in self._pieces]
        self.t0 = min(b[0] for b, _ in self._pieces)
        self.t_end = max(b[-1] for b, _ in self._pieces)
        self.duration = self.t_end - self.t0

    def _segment(self, piece: int, t: float) -> _Segment:
        breaks, segments = self._pieces[piece]
        k = bisect_right(breaks, t) - 1
        last = len(segments) - 1
        seg = segments[0 if k < 0 else (last if k > last else k)]
        self._active[piece] = seg
        return seg

    def evaluate(self, t: float) -> tuple[list[float], list[float]]:
        """Flat positions and velocities (per second) at ``t`` [s], ``dims`` per piece."""
        t = float(t)
        pos: list[float] = []
        vel: list[float] = []
        put_p, put_v = pos.append, vel.append
        for piece, seg in enumerate(self._active):
            # The active segment serves [start, end); the last one also holds past its end.
            if not (seg[0] <= t < seg[2]):
                seg = self._segment(piece, t)
            start, duration, _, rows = seg
            tau = t - start
            if tau < 0.0:
                tau = 0.0
            elif tau > duration:
                tau = duration
            u = tau / duration
            for c0, c1, c2, c3, c4, c5, c6, d1, d2, d3, d4, d5, d6 in rows:
                # Horner in u for p and for p' (its coefficients scaled by 1 / duration)
                put_p((((((c6 * u + c5) * u + c4) * u + c3) * u + c2) * u + c1) * u + c0)
                put_v(((((d6 * u + d5) * u + d4) * u + d3) * u + d2) * u + d1)
        return pos, vel


class FastKinematics:
    """`kinematics.inverse_kinematics` and `kinematics.joint_velocities` for one instant.

    Same conventions, limits, tolerances and errors as the numpy functions (see the module
    docstring for how errors are raised). With calibrated legs an instance keeps state between
    calls: each leg's last solution (`fastchain.ScalarLeg`), which starts the next one (results
    depend on the previous call within `fastchain.STEP_BOUND` of the target), and the Jacobian
    of its last evaluation, which `velocities` reuses when given exactly the angles `inverse`
    returned (otherwise it evaluates the chain at the given angles).
    """

    __slots__ = ("_chains", "_kept", "_legs", "_lim", "l1", "l2", "l3", "n_legs", "robot")

    def __init__(self, robot: RobotConfig) -> None:
        self.robot = robot
        self.n_legs = robot.n_legs
        self.l1, self.l2, self.l3 = float(robot.l1), float(robot.l2), float(robot.l3)
        l2, l3 = self.l2, self.l3
        d_max, d_min = l2 + l3, abs(l2 - l3)
        self._legs = tuple(
            (float(robot.hips[i, 0]), float(robot.hips[i, 1]), float(robot.hips[i, 2]),
             float(robot.neutral_yaw[i]), float(robot.knee_sign[i]))
            for i in range(self.n_legs))
        eps = kinematics.REACH_EPS
        lower = [float(x) for x in np.broadcast_to(robot.lower, (3,))]
        upper = [float(x) for x in np.broadcast_to(robot.upper, (3,))]
        # within these an angle needs neither wrapping to (-pi, pi] nor a limit check
        inside = (*(max(x, math.nextafter(-_PI, 0.0)) for x in lower),
                  *(min(x, _PI) for x in upper))
        self._lim = (d_max * (1 + eps), d_min * (1 - eps), l2 * l2, l3 * l3, 2 * l2 * l3,
                     tuple(lower), tuple(upper), inside)
        geometry = robot.geometry if robot.calibrated else None
        self._chains = None if geometry is None else tuple(
            ScalarLeg(joint_frames(geometry.params[i], robot.hips[i],
                                   float(robot.neutral_yaw[i]))) for i in range(self.n_legs))
        #: per calibrated leg: the angles `inverse` returned last if they are its solution
        self._kept: list[tuple[float, ...] | None] = [None] * self.n_legs

    def _reference_ik(self, feet: Sequence[float], check: bool) -> list[float]:
        self._kept = [None] * self.n_legs
        arr = np.asarray(feet, dtype=float)
        if arr.size == 3 * self.n_legs:
            arr = arr.reshape(self.n_legs, 3)
        return kinematics.inverse_kinematics(self.robot, arr, check=check).reshape(-1).tolist()

    def inverse(self, feet: Sequence[float], check: bool = True) -> list[float]:
        """Joint angles (flat, ``3 * n_legs``) [rad] placing the feet at ``feet`` (flat) [m]."""
        if len(feet) != 3 * self.n_legs:
            return self._reference_ik(feet, check)  # raises the shape error
        chains = self._chains
        d_hi, d_lo, l2sq, l3sq, den, _, _, inside = self._lim
        lo0, lo1, lo2, hi0, hi1, hi2 = inside
        l1, l2, l3 = self.l1, self.l2, self.l3
        kept = self._kept
        out: list[float] = []
        for i, (hx, hy, hz, yaw0, sign) in enumerate(self._legs):
            j = 3 * i
            fx, fy, fz = feet[j], feet[j + 1], feet[j + 2]
            angles = None if chains is None else chains[i].warm(fx, fy, fz)
            if angles is None:
                qx = fx - hx
                qy = fy - hy
                w = fz - hz
                r = math.hypot(qx, qy)
                u = r - l1
                d2 = u * u + w * w
                d = math.sqrt(d2)
                # calibrated legs: the closed form only starts the refinement, which decides
                if not ((chains is not None or d_lo <= d <= d_hi)
                        and r >= kinematics.AXIS_EPS):  # also NaN / inf
                    return self._reference_ik(feet, check)
                ck = (d2 - l2sq - l3sq) / den
                ck = -1.0 if ck < -1.0 else (1.0 if ck > 1.0 else ck)
                knee = sign * math.acos(ck)
                shoulder = wrap(math.atan2(w, u) + math.atan2(l3 * math.sin(knee),
                                                               l2 + l3 * math.cos(knee)))
                root = wrap(math.atan2(qy, qx) - yaw0)
                angles = (root, shoulder, knee)
                if chains is not None:
                    angles = chains[i].cold(fx, fy, fz, angles, sign)
                    if angles is None:
                        return self._reference_ik(feet, check)
            a0, a1, a2 = angles
            if lo0 <= a0 <= hi0 and lo1 <= a1 <= hi1 and lo2 <= a2 <= hi2:
                out += angles
                kept[i] = angles
            else:
                wrapped = self._limited(angles, check)
                if wrapped is None:
                    return self._reference_ik(feet, check)
                out += wrapped
                kept[i] = angles if wrapped == angles else None
        return out

    def _limited(self, angles: tuple[float, ...], check: bool) -> tuple[float, ...] | None:
        """``angles`` wrapped to (-pi, pi] and set onto a limit they exceed by at most
        `kinematics.LIMIT_EPS`; None when one is farther out and ``check`` is set."""
        lower, upper = self._lim[5], self._lim[6]
        out = []
        for k, angle in enumerate(angles):
            if not -_PI < angle <= _PI:
                angle = wrap(angle)
            lo, hi = lower[k], upper[k]
            if angle < lo:
                if angle >= lo - kinematics.LIMIT_EPS:
                    angle = lo
                elif check:
                    return None
            elif angle > hi:
                if angle <= hi + kinematics.LIMIT_EPS:
                    angle = hi
                elif check:
                    return None
            out.append(angle)
        return tuple(out)

    def velocities(self, angles: Sequence[float], foot_velocity: Sequence[float]
                   ) -> list[float]:
        """Joint rates (flat) [rad/s] producing ``foot_velocity`` (flat) [m/s] at ``angles``."""
        if len(angles) != 3 * self.n_legs or len(foot_velocity) != 3 * self.n_legs:
            raise KinematicsError(f"angles and foot velocities must hold {3 * self.n_legs} "
                                  f"values each (flat, leg-major), got {len(angles)} and "
                                  f"{len(foot_velocity)}")
        if self._chains is not None:
            return self._calibrated_rates(angles, foot_velocity)
        l1, l2, l3 = self.l1, self.l2, self.l3
        out: list[float] = []
        for i, leg in enumerate(self._legs):
            j = 3 * i
            root, shoulder, knee = angles[j], angles[j + 1], angles[j + 2]
            yaw = leg[3] + root
            tibia = shoulder - knee
            s2, c2 = math.sin(shoulder), math.cos(shoulder)
            s23, c23 = math.sin(tibia), math.cos(tibia)
            r = l1 + (l2 * c2 + l3 * c23)
            det = l2 * l3 * math.sin(knee)
            if not (abs(r) >= kinematics.AXIS_EPS
                    and abs(det) >= kinematics.SINGULAR_EPS):  # also catches NaN
                return self._reference_rates(angles, foot_velocity)
            cy, sy = math.cos(yaw), math.sin(yaw)
            vx, vy, w_dot = foot_velocity[j], foot_velocity[j + 1], foot_velocity[j + 2]
            r_dot = cy * vx + sy * vy
            j11, j12 = -l2 * s2 - l3 * s23, l3 * s23
            j21, j22 = l2 * c2 + l3 * c23, -l3 * c23
            out.append((-sy * vx + cy * vy) / r)
            out.append((j22 * r_dot - j12 * w_dot) / det)
            out.append((-j21 * r_dot + j11 * w_dot) / det)
        return out

    def solve(self, feet: Sequence[float], foot_velocity: Sequence[float]
              ) -> tuple[list[float], list[float]]:
        """`inverse` (limits checked) then `velocities`: joint angles [rad] and rates [rad/s]
        (flat) for foot positions [m] and velocities [m/s] (flat)."""
        chains = self._chains
        fast = (nominal_solve(self, feet, foot_velocity) if chains is None
                else calibrated_solve(self, chains, feet, foot_velocity))
        if fast is not None:
            return fast
        q = self.inverse(feet)
        if chains is not None and len(foot_velocity) == 3 * self.n_legs:
            kept = self._kept
            v = foot_velocity
            out: list[float] = []
            for i, chain in enumerate(chains):  # the angles just returned: no comparison
                j = 3 * i
                rates = (None if kept[i] is None
                         else chain.rates_last(v[j], v[j + 1], v[j + 2]))
                if rates is None:
                    return q, self.velocities(q, foot_velocity)
                out += rates
            return q, out
        return q, self.velocities(q, foot_velocity)

    def _calibrated_rates(self, angles: Sequence[float], foot_velocity: Sequence[float]
                          ) -> list[float]:
        assert self._chains is not None
        out: list[float] = []
        kept = self._kept
        for i, chain in enumerate(self._chains):
            j = 3 * i
            q = (angles[j], angles[j + 1], angles[j + 2])
            v = (foot_velocity[j], foot_velocity[j + 1], foot_velocity[j + 2])
            rates = chain.rates_last(*v) if kept[i] == q else chain.rates(q, v)
            if rates is None:
                return self._reference_rates(angles, foot_velocity)
            out.extend(rates)
        return out

    def _reference_rates(self, angles: Sequence[float], foot_velocity: Sequence[float]
                         ) -> list[float]:
        q = np.asarray(angles, dtype=float).reshape(self.n_legs, 3)
        v = np.asarray(foot_velocity, dtype=float).reshape(self.n_legs, 3)
        return kinematics.joint_velocities(self.robot, q, v).reshape(-1).tolist()


def joint_targets(feet: Track, kin: FastKinematics, t: float
                  ) -> tuple[list[float], list[float]]:
    """Joint angles [rad] and rates [rad/s] (flat, joint-name order) of every leg at ``t`` [s],
    from the foot trajectories ``feet`` (one 3-D piece per leg)."""
    pos, vel = feet.evaluate(t)
    return kin.solve(pos, vel)
