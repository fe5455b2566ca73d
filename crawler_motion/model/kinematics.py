"""Closed-form inverse and forward kinematics of all legs at once (pure numpy).

Shapes: foot positions and joint angles are ``(..., n_legs, 3)`` arrays, one row per leg in
config order (lf, lb, rb, rf); position columns x, y, z in base_link [m] (REP-103), joint
columns root, shoulder, knee [rad]. Leading dimensions batch over time or samples.

Joint conventions (also used by the URDF and the driver):
- zero: leg stretched straight out, horizontal, along the leg's neutral yaw;
- root: + is yaw counter-clockwise seen from above (about +z);
- shoulder: + raises the femur (elevation of the femur above horizontal);
- knee: + bends the tibia down relative to the femur; "knee up" means knee > 0.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

from crawler_motion.errors import JointLimitError, KinematicsError, UnreachableError
from crawler_motion.model import calibrated
from crawler_motion.model.config import JOINT_KINDS, RobotConfig

#: Relative slack on the workspace boundary that is attributed to rounding, not to the target.
REACH_EPS = 1e-12
#: IK angles this close outside a joint limit [rad] are rounding noise of the closed form (e.g.
#: the IK of the FK of a pose at a limit) and are set onto the limit; farther out is an error.
LIMIT_EPS = 1e-9
#: Horizontal distance [m] of the foot from the root axis below which the root angle (IK) and
#: the root rate (Jacobian) are undefined.
AXIS_EPS = 1e-9
#: Smallest ``|l2 l3 sin(knee)|`` [m^2], the determinant of the shoulder/knee Jacobian, below
#: which the leg counts as singular (knee straight) and its joint rates as undefined.
SINGULAR_EPS = 1e-9

_E = TypeVar("_E", bound=KinematicsError)


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Wrap angles to (-pi, pi]."""
    return np.pi - np.mod(np.pi - angle, 2.0 * np.pi)


def _as_feet(feet: np.ndarray, n_legs: int, what: str) -> np.ndarray:
    arr = np.asarray(feet, dtype=float)
    if arr.ndim < 2 or arr.shape[-2:] != (n_legs, 3):
        raise KinematicsError(f"{what} must be shaped (..., {n_legs}, 3), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise KinematicsError(f"{what} contains NaN or inf: {arr[~np.isfinite(arr)][:3]}")
    return arr


def _first(mask: np.ndarray) -> tuple[int, ...]:
    return tuple(int(i) for i in np.argwhere(mask)[0])


def _at_sample(exc: _E, sample: tuple[int, ...] | None) -> _E:
    """``exc`` with its ``sample`` attribute set: the index of the failing sample over the
    leading (batch) dimensions of the input, None for an unbatched input."""
    exc.sample = sample
    return exc


def check_limits(robot: RobotConfig, q: np.ndarray) -> None:
    """Raise `JointLimitError` naming the first leg/joint outside its limits."""
    arr = np.asarray(q, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise _at_sample(JointLimitError("joint angles contain NaN or inf"), None)
    below = arr < robot.lower
    above = arr > robot.upper
    bad = below | above
    if np.any(bad):
        idx = _first(bad)
        leg, joint = idx[-2], idx[-1]
        sample = idx[:-2] if len(idx) > 2 else None
        where = f" at sample {sample}" if sample is not None else ""
        lo, hi = robot.lower[joint], robot.upper[joint]
        side, excess = ("below", lo - arr[idx]) if below[idx] else ("above", arr[idx] - hi)
        raise _at_sample(JointLimitError(
            f"leg {robot.legs[leg]} {JOINT_KINDS[joint]} joint: {arr[idx]:.4f} rad is outside "
            f"its limits [{lo:.4f}, {hi:.4f}] rad ({excess:.3g} rad {side}){where} "
            f"({int(bad.sum())} violation(s) in all)"), sample)


def inverse_kinematics(robot: RobotConfig, feet: np.ndarray, check: bool = True) -> np.ndarray:
    """Joint angles ``(..., n_legs, 3)`` [rad] placing every foot at ``feet`` [m].

    Raises `UnreachableError` for a target outside a leg's workspace and, with ``check``,
    `JointLimitError` for an angle outside the limits (both with ``sample``: the index of the
    first failing sample over the leading dimensions, None for one unbatched pose). Never
    returns NaN, never clips (angles within ``LIMIT_EPS`` of a limit are rounding noise and are
    returned exactly on it). The solution keeps the foot on the leg's side of the root axis
    (r > 0) with the knee sign given by ``robot.knee_sign``; angles are returned in (-pi, pi].
    With calibrated legs (``robot.calibrated``) the closed-form solution of the nominal leg is
    refined by Newton steps through each leg's chain to within `calibrated.IK_ACCEPT`.
    """
    p = _as_feet(feet, robot.n_legs, "foot targets")
    q = p - robot.hips
    r = np.hypot(q[..., 0], q[..., 1])
    u = r - robot.l1
    w = q[..., 2]
    d2 = u * u + w * w
    l2, l3 = robot.l2, robot.l3
    d_max, d_min = l2 + l3, abs(l2 - l3)
    d = np.sqrt(d2)
    bad = (d > d_max * (1 + REACH_EPS)) | (d < d_min * (1 - REACH_EPS)) | (r < AXIS_EPS)
    if robot.calibrated:  # the closed form only starts the refinement, which decides
        bad = r < AXIS_EPS
    if np.any(bad):
        idx = _first(bad)
        leg = idx[-1]
        sample = idx[:-1] if len(idx) > 1 else None
        where = f" at sample {sample}" if sample is not None else ""
        target = np.array2string(p[idx], precision=4)
        raise _at_sample(UnreachableError(
            f"leg {robot.legs[leg]}: foot target {target} m{where} is {d[idx]:.4f} m from the "
            f"shoulder; reachable is [{d_min:.4f}, {d_max:.4f}] m (and off the root axis)"),
            sample)
    cos_knee = np.clip((d2 - l2 * l2 - l3 * l3) / (2 * l2 * l3), -1.0, 1.0)  # rounding only
    knee = robot.knee_sign * np.arccos(cos_knee)
    shoulder = _wrap(np.arctan2(w, u) + np.arctan2(l3 * np.sin(knee), l2 + l3 * np.cos(knee)))
    root = _wrap(np.arctan2(q[..., 1], q[..., 0]) - robot.neutral_yaw)
    angles = np.stack((root, shoulder, knee), axis=-1)
    if robot.calibrated:
        angles = _wrap(calibrated.refine(robot, p, angles))
    lower, upper = robot.lower, robot.upper
    angles = np.where((angles < lower) & (angles >= lower - LIMIT_EPS), lower, angles)
    angles = np.where((angles > upper) & (angles <= upper + LIMIT_EPS), upper, angles)
    if check:
        check_limits(robot, angles)
    return angles


def forward_kinematics(robot: RobotConfig, angles: np.ndarray) -> np.ndarray:
    """Foot positions ``(..., n_legs, 3)`` [m] in base_link for joint angles [rad]."""
    a = _as_feet(angles, robot.n_legs, "joint angles")
    if robot.calibrated:
        return calibrated.forward(robot, a)
    root, shoulder, knee = a[..., 0], a[..., 1], a[..., 2]
    tibia = shoulder - knee
    u = robot.l2 * np.cos(shoulder) + robot.l3 * np.cos(tibia)
    w = robot.l2 * np.sin(shoulder) + robot.l3 * np.sin(tibia)
    r = robot.l1 + u
    yaw = robot.neutral_yaw + root
    return robot.hips + np.stack((r * np.cos(yaw), r * np.sin(yaw), w), axis=-1)


def foot_jacobians(robot: RobotConfig, angles: np.ndarray) -> np.ndarray:
    """Leg Jacobians ``d foot / d q`` ``(..., n_legs, 3, 3)`` [m/rad] at ``angles`` [rad].

    Row i, column j: d (foot coordinate i in base_link) / d (joint j of the leg), joints root,
    shoulder, knee. Its transpose maps a force on the foot to joint torques (tau = J^T F); see
    `joint_velocities` for where it is singular. Calibrated legs use their chains.
    """
    a = _as_feet(angles, robot.n_legs, "joint angles")
    if robot.calibrated:
        return calibrated.jacobians(robot, a)
    root, shoulder, knee = a[..., 0], a[..., 1], a[..., 2]
    yaw = robot.neutral_yaw + root
    tibia = shoulder - knee
    l2, l3 = robot.l2, robot.l3
    r = robot.l1 + l2 * np.cos(shoulder) + l3 * np.cos(tibia)
    cy, sy = np.cos(yaw), np.sin(yaw)
    du = (-l2 * np.sin(shoulder) - l3 * np.sin(tibia), l3 * np.sin(tibia))  # d r / d (s, k)
    dw = (l2 * np.cos(shoulder) + l3 * np.cos(tibia), -l3 * np.cos(tibia))  # d z / d (s, k)
    jac = np.empty((*a.shape, 3))
    jac[..., 0, 0], jac[..., 1, 0], jac[..., 2, 0] = -r * sy, r * cy, 0.0
    for j in (1, 2):
        jac[..., 0, j], jac[..., 1, j], jac[..., 2, j] = du[j - 1] * cy, du[j - 1] * sy, dw[j - 1]
    return jac


def joint_velocities(robot: RobotConfig, angles: np.ndarray, foot_velocity: np.ndarray
                     ) -> np.ndarray:
    """Joint rates ``(..., n_legs, 3)`` [rad/s] producing ``foot_velocity`` [m/s] at ``angles``.

    Analytic inverse of the leg Jacobian; the leg is singular with the knee straight
    (knee = 0, which the limits exclude) and with the foot on the root axis (r = 0, which the
    limits allow: e.g. the foot tucked right under the hip). Raises `KinematicsError` near
    either singularity.
    """
    a = np.asarray(angles, dtype=float)
    v = np.asarray(foot_velocity, dtype=float)
    if robot.calibrated:
        return calibrated.rates(robot, a, v)
    root, shoulder, knee = a[..., 0], a[..., 1], a[..., 2]
    yaw = robot.neutral_yaw + root
    tibia = shoulder - knee
    u = robot.l2 * np.cos(shoulder) + robot.l3 * np.cos(tibia)
    r = robot.l1 + u
    cy, sy = np.cos(yaw), np.sin(yaw)
    if np.any(np.abs(r) < AXIS_EPS):
        raise KinematicsError("leg Jacobian is singular (foot on the root axis); "
                              "root rate undefined")
    r_dot = cy * v[..., 0] + sy * v[..., 1]
    root_dot = (-sy * v[..., 0] + cy * v[..., 1]) / r
    w_dot = v[..., 2]
    s2, c2 = np.sin(shoulder), np.cos(shoulder)
    s23, c23 = np.sin(tibia), np.cos(tibia)
    l2, l3 = robot.l2, robot.l3
    det = l2 * l3 * np.sin(knee)
    if np.any(np.abs(det) < SINGULAR_EPS):
        raise KinematicsError("leg Jacobian is singular (knee straight); joint rates undefined")
    # [u_dot, w_dot] = J [shoulder_dot, knee_dot]
    j11, j12 = -l2 * s2 - l3 * s23, l3 * s23
    j21, j22 = l2 * c2 + l3 * c23, -l3 * c23
    shoulder_dot = (j22 * r_dot - j12 * w_dot) / det
    knee_dot = (-j21 * r_dot + j11 * w_dot) / det
    return np.stack((root_dot, shoulder_dot, knee_dot), axis=-1)
