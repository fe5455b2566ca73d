"""Per-tick fast path: foot trajectories, IK and joint rates of all legs in plain floats.

The public numpy API (`gait.WalkPlan.evaluate`, `kinematics.inverse_kinematics`,
`kinematics.joint_velocities`) is vectorised for batches; for one time instant its cost is
dominated by numpy's per-call overhead (dozens of ufunc calls on 12 numbers). This module
computes the same numbers for one instant with `math` on Python floats:

- `LegEvaluator` holds every leg's `Piecewise` as tuples of coefficients and the active
  segment of each leg (found again with `bisect` only when the time leaves it), and evaluates
  position and velocity with the same Horner recurrence as `Piecewise.evaluate`;
- `FastKinematics` is the closed-form IK and the analytic Jacobian inverse of
  `crawler_motion.model.kinematics`, operation for operation, for all legs;
- `joint_targets` chains them: one call per control tick.

Results equal the numpy path to rounding (tested to 1e-12 over whole walks). Errors are
identical by construction: whenever a fast check finds a target outside the workspace, an
angle outside the joint limits or a singular Jacobian, the numpy function is called on the
same input and raises its own `UnreachableError` / `JointLimitError` / `KinematicsError`
(should it not raise, a disagreement within rounding at a boundary, its result is returned).

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
from crawler_motion.motion.trajectory import Piecewise

__all__ = ["FastKinematics", "LegEvaluator", "joint_targets"]

_sin, _cos, _atan2, _hypot, _sqrt, _acos = (math.sin, math.cos, math.atan2, math.hypot,
                                            math.sqrt, math.acos)
_PI = math.pi
_TWO_PI = 2.0 * math.pi
_DEGREE = 6  # sextic (lower degrees are zero-padded)


def _wrap(angle: float) -> float:
    """Wrap to (-pi, pi] exactly like `kinematics._wrap`."""
    return _PI - (_PI - angle) % _TWO_PI


class LegEvaluator:
    """Position and velocity of every leg's foot at one time, from ``legs`` (one `Piecewise`
    per leg, e.g. `gait.Slot.legs` or `gait.WalkPlan.legs`).

    Semantics of `Piecewise.evaluate`: times before the start or after the end hold the
    first / last segment evaluated at its boundary. Keeps the active segment of each leg, so
    consecutive calls with increasing times cost one comparison per leg.
    """

    __slots__ = ("_active", "_legs", "n_legs", "t0", "t_end")

    def __init__(self, legs: Sequence[Piecewise]) -> None:
        if not legs:
            raise TrajectoryError("LegEvaluator needs at least one leg trajectory")
        self.n_legs = len(legs)
        self._legs = []
        for pw in legs:
            widths = {seg.coeffs.shape for seg in pw.segments}
            if any(shape[0] != 3 or shape[1] > _DEGREE + 1 for shape in widths):
                raise TrajectoryError(f"LegEvaluator needs 3-D trajectories of degree <= "
                                      f"{_DEGREE}, got coefficients {sorted(widths)}")
            coeffs = np.zeros((len(pw.segments), 3, _DEGREE + 1))
            for k, seg in enumerate(pw.segments):
                coeffs[k, :, :seg.coeffs.shape[1]] = seg.coeffs
            breaks = [float(b) for b in pw.breaks]
            segments = tuple(
                (breaks[k], float(pw.durations[k]), breaks[k + 1],
                 tuple(tuple(float(x) for x in row) for row in coeffs[k]))
                for k in range(len(pw.segments)))
            self._legs.append((breaks, segments))
        self._active = [self._legs[i][1][0] for i in range(self.n_legs)]
        self.t0 = min(b[0] for b, _ in self._legs)
        self.t_end = max(b[-1] for b, _ in self._legs)

    def _segment(self, leg: int, t: float) -> tuple:
        breaks, segments = self._legs[leg]
        k = bisect_right(breaks, t) - 1
        last = len(segments) - 1
        seg = segments[0 if k < 0 else (last if k > last else k)]
        self._active[leg] = seg
        return seg

    def evaluate(self, t: float) -> tuple[list[float], list[float]]:
        """Flat foot positions [m] and velocities [m/s], ``3 * n_legs`` floats each."""
        t = float(t)
        pos: list[float] = []
        vel: list[float] = []
        active = self._active
        for leg in range(self.n_legs):
            seg = active[leg]
            # The active segment serves [start, end); the last one also holds past its end.
            if not (seg[0] <= t < seg[2]):
                seg = self._segment(leg, t)
            start, duration, _, rows = seg
            tau = t - start
            if tau < 0.0:
                tau = 0.0
            elif tau > duration:
                tau = duration
            u = tau / duration
            for c0, c1, c2, c3, c4, c5, c6 in rows:
                # Horner for p and p' in u, in the order of `Piecewise.evaluate`.
                v = c6
                p = c6 * u + c5
                v = v * u + p
                p = p * u + c4
                v = v * u + p
                p = p * u + c3
                v = v * u + p
                p = p * u + c2
                v = v * u + p
                p = p * u + c1
                v = v * u + p
                p = p * u + c0
                pos.append(p)
                vel.append(v / duration)
        return pos, vel


class FastKinematics:
    """`kinematics.inverse_kinematics` and `kinematics.joint_velocities` for one instant.

    Same conventions, limits, tolerances and errors as the numpy functions (see the module
    docstring for how errors are raised).
    """

    __slots__ = ("_legs", "_lim", "l1", "l2", "l3", "n_legs", "robot")

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
        eps = kinematics._REACH_EPS
        lower = [float(x) for x in np.broadcast_to(robot.lower, (3,))]
        upper = [float(x) for x in np.broadcast_to(robot.upper, (3,))]
        self._lim = (d_max * (1 + eps), d_min * (1 - eps), l2 * l2, l3 * l3, 2 * l2 * l3,
                     tuple(lower), tuple(upper), kinematics._LIMIT_EPS,
                     kinematics._AXIS_EPS)

    def _reference_ik(self, feet: Sequence[float], check: bool) -> list[float]:
        arr = np.asarray(feet, dtype=float)
        if arr.size == 3 * self.n_legs:
            arr = arr.reshape(self.n_legs, 3)
        return kinematics.inverse_kinematics(self.robot, arr, check=check).reshape(-1).tolist()

    def inverse(self, feet: Sequence[float], check: bool = True) -> list[float]:
        """Joint angles (flat, ``3 * n_legs``) [rad] placing the feet at ``feet`` (flat) [m]."""
        if len(feet) != 3 * self.n_legs:
            return self._reference_ik(feet, check)  # raises the shape error
        d_hi, d_lo, l2sq, l3sq, den, lower, upper, lim_eps, axis_eps = self._lim
        l1, l2, l3 = self.l1, self.l2, self.l3
        out: list[float] = []
        for i, (hx, hy, hz, yaw0, sign) in enumerate(self._legs):
            j = 3 * i
            qx = feet[j] - hx
            qy = feet[j + 1] - hy
            w = feet[j + 2] - hz
            r = math.hypot(qx, qy)
            u = r - l1
            d2 = u * u + w * w
            d = math.sqrt(d2)
            if not (d_lo <= d <= d_hi and r >= axis_eps):  # also catches NaN / inf
                return self._reference_ik(feet, check)
            ck = (d2 - l2sq - l3sq) / den
            ck = -1.0 if ck < -1.0 else (1.0 if ck > 1.0 else ck)
            knee = sign * math.acos(ck)
            shoulder = _wrap(math.atan2(w, u) + math.atan2(l3 * math.sin(knee),
                                                           l2 + l3 * math.cos(knee)))
            root = _wrap(math.atan2(qy, qx) - yaw0)
            for k, angle in enumerate((root, shoulder, knee)):
                lo, hi = lower[k], upper[k]
                if angle < lo:
                    if angle >= lo - lim_eps:
                        angle = lo
                    elif check:
                        return self._reference_ik(feet, check)
                elif angle > hi:
                    if angle <= hi + lim_eps:
                        angle = hi
                    elif check:
                        return self._reference_ik(feet, check)
                out.append(angle)
        return out

    def velocities(self, angles: Sequence[float], foot_velocity: Sequence[float]
                   ) -> list[float]:
        """Joint rates (flat) [rad/s] producing ``foot_velocity`` (flat) [m/s] at ``angles``."""
        if len(angles) != 3 * self.n_legs or len(foot_velocity) != 3 * self.n_legs:
            raise KinematicsError(f"angles and foot velocities must hold {3 * self.n_legs} "
                                  f"values each (flat, leg-major), got {len(angles)} and "
                                  f"{len(foot_velocity)}")
        l1, l2, l3 = self.l1, self.l2, self.l3
        axis_eps = self._lim[-1]
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
            if not (abs(r) >= axis_eps and abs(det) >= 1e-9):  # also catches NaN
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
        """`inverse` and `velocities` in one pass: joint angles [rad] and rates [rad/s] (flat).

        Same numbers and errors as ``q = inverse(feet); velocities(q, foot_velocity)``.
        """
        n = 3 * self.n_legs
        if len(feet) != n or len(foot_velocity) != n:
            q = self.inverse(feet)
            return q, self.velocities(q, foot_velocity)
        d_hi, d_lo, l2sq, l3sq, den, lower, upper, lim_eps, axis_eps = self._lim
        lo0, lo1, lo2 = lower
        hi0, hi1, hi2 = upper
        l1, l2, l3 = self.l1, self.l2, self.l3
        l2l3 = l2 * l3
        sin, cos, atan2, hypot, sqrt, acos = _sin, _cos, _atan2, _hypot, _sqrt, _acos
        q: list[float] = []
        qd: list[float] = []
        j = 0
        for hx, hy, hz, yaw0, sign in self._legs:
            qx = feet[j] - hx
            qy = feet[j + 1] - hy
            w = feet[j + 2] - hz
            r = hypot(qx, qy)
            u = r - l1
            d2 = u * u + w * w
            d = sqrt(d2)
            if not (d_lo <= d <= d_hi and r >= axis_eps):  # also catches NaN / inf
                q = self._reference_ik(feet, True)  # raises
                return q, self.velocities(q, foot_velocity)
            ck = (d2 - l2sq - l3sq) / den
            ck = -1.0 if ck < -1.0 else (1.0 if ck > 1.0 else ck)
            knee = sign * acos(ck)
            sk = sin(knee)
            shoulder = _PI - (_PI - (atan2(w, u) + atan2(l3 * sk, l2 + l3 * cos(knee)))
                              ) % _TWO_PI
            root = _PI - (_PI - (atan2(qy, qx) - yaw0)) % _TWO_PI
            if not (lo0 <= root <= hi0 and lo1 <= shoulder <= hi1 and lo2 <= knee <= hi2):
                snapped = []
                for k, angle in enumerate((root, shoulder, knee)):
                    if lower[k] - lim_eps <= angle < lower[k]:
                        angle = lower[k]
                    elif upper[k] < angle <= upper[k] + lim_eps:
                        angle = upper[k]
                    elif not lower[k] <= angle <= upper[k]:
                        q = self._reference_ik(feet, True)  # raises
                        return q, self.velocities(q, foot_velocity)
                    snapped.append(angle)
                if snapped[2] != knee:
                    sk = sin(snapped[2])
                root, shoulder, knee = snapped
            q.append(root)
            q.append(shoulder)
            q.append(knee)
            # joint rates at (root, shoulder, knee), as `kinematics.joint_velocities`
            yaw = yaw0 + root
            tibia = shoulder - knee
            s2, c2 = sin(shoulder), cos(shoulder)
            s23, c23 = sin(tibia), cos(tibia)
            rr = l1 + (l2 * c2 + l3 * c23)
            det = l2l3 * sk
            if not (abs(rr) >= axis_eps and abs(det) >= 1e-9):
                full = self.inverse(feet)
                return full, self.velocities(full, foot_velocity)  # raises
            cy, sy = cos(yaw), sin(yaw)
            vx, vy, w_dot = foot_velocity[j], foot_velocity[j + 1], foot_velocity[j + 2]
            r_dot = cy * vx + sy * vy
            j11, j12 = -l2 * s2 - l3 * s23, l3 * s23
            j21, j22 = l2 * c2 + l3 * c23, -l3 * c23
            qd.append((-sy * vx + cy * vy) / rr)
            qd.append((j22 * r_dot - j12 * w_dot) / det)
            qd.append((-j21 * r_dot + j11 * w_dot) / det)
            j += 3
        return q, qd

    def _reference_rates(self, angles: Sequence[float], foot_velocity: Sequence[float]
                         ) -> list[float]:
        q = np.asarray(angles, dtype=float).reshape(self.n_legs, 3)
        v = np.asarray(foot_velocity, dtype=float).reshape(self.n_legs, 3)
        return kinematics.joint_velocities(self.robot, q, v).reshape(-1).tolist()


def joint_targets(evaluator: LegEvaluator, kin: FastKinematics, t: float
                  ) -> tuple[list[float], list[float]]:
    """Joint angles [rad] and rates [rad/s] (flat, joint-name order) of every leg at ``t``."""
    pos, vel = evaluator.evaluate(t)
    return kin.solve(pos, vel)
