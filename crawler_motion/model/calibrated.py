"""Kinematics of calibrated legs: forward kinematics through each leg's chain, Newton refinement
of the closed-form IK, joint rates through the chain's Jacobian (pure numpy).

Used by `crawler_motion.model.kinematics` when ``robot.calibrated``; shapes and frames as there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from crawler_motion.errors import KinematicsError, UnreachableError
from crawler_motion.model.leg_geometry import joint_jacobian, leg_chain, to_base, to_leg

if TYPE_CHECKING:
    from crawler_motion.model.config import RobotConfig

#: Newton refinement of the IK takes one last step once every foot is this close to its
#: target [m] and stops (quadratic convergence: that step ends ~1e-14 m away).
IK_FINAL = 1e-7
#: ... or after this many steps; a foot still farther than `IK_ACCEPT` is unreachable.
IK_MAX_STEPS = 20
#: Largest foot error [m] an IK solution may keep (the issue's bound: 1e-6 m).
IK_ACCEPT = 1e-7
#: Smallest knee bend [rad] the refinement starts from (the straight knee is singular).
START_KNEE = 0.05
#: Largest joint change of one Newton step [rad] (damps steps from a poor start).
MAX_STEP = 0.3
#: |det| of a leg's joint Jacobian [m^3] below which its joint rates are undefined.
SINGULAR_DET = 1e-12


def _leg_fk(robot: RobotConfig, leg: int, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Foot ``(..., 3)`` [m] in base_link and joint Jacobian ``(..., 3, 3)`` of leg ``leg``."""
    assert robot.geometry is not None
    foot, jac = leg_chain(robot.geometry.params[leg], q)
    yaw = float(robot.neutral_yaw[leg])
    jq = np.swapaxes(to_base(np.swapaxes(joint_jacobian(jac), -1, -2), 0.0, yaw), -1, -2)
    return to_base(foot, robot.hips[leg], yaw), jq


def forward(robot: RobotConfig, angles: np.ndarray) -> np.ndarray:
    """Foot positions ``(..., n_legs, 3)`` [m] in base_link for joint angles [rad]."""
    return np.stack([_leg_fk(robot, i, angles[..., i, :])[0] for i in range(robot.n_legs)],
                    axis=-2)


def refine(robot: RobotConfig, feet: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Newton steps from ``start`` (the closed-form IK of the nominal leg) [rad] to the angles
    placing every foot at ``feet`` [m] through its calibrated chain.

    Raises `UnreachableError` (``sample`` set) when a foot stays farther than `IK_ACCEPT`.
    """
    q = np.array(start, dtype=float)
    knee = q[..., 2]  # a straight knee (target beyond the nominal reach) is singular
    bend = np.clip(np.abs(knee), START_KNEE, np.pi - START_KNEE)  # so is a folded one
    q[..., 2] = np.where(bend != np.abs(knee), robot.knee_sign * bend, knee)
    for leg in range(robot.n_legs):
        ql = q[..., leg, :]
        for _ in range(IK_MAX_STEPS):
            foot, jac = _leg_fk(robot, leg, ql)
            err = feet[..., leg, :] - foot
            done = np.max(np.abs(err), initial=0.0) < IK_FINAL
            try:
                step = np.linalg.solve(jac, err[..., None])[..., 0]
            except np.linalg.LinAlgError as exc:
                raise KinematicsError(f"leg {robot.legs[leg]}: singular Jacobian in the IK "
                                      f"refinement") from exc
            largest = np.max(np.abs(step), axis=-1, keepdims=True)
            ql = ql + step * np.minimum(1.0, MAX_STEP / np.maximum(largest, 1e-300))
            if done:
                break
        foot = _leg_fk(robot, leg, ql)[0]
        miss = np.linalg.norm(feet[..., leg, :] - foot, axis=-1)
        if np.any(~(miss <= IK_ACCEPT)):
            idx = tuple(int(i) for i in np.argwhere(~(miss <= IK_ACCEPT))[0]) if miss.ndim else ()
            exc = UnreachableError(f"leg {robot.legs[leg]}: the calibrated leg cannot reach "
                                   f"{np.array2string(feet[(*idx, leg)], precision=4)} m "
                                   f"(Newton refinement ends {float(miss[idx]):.3g} m away)")
            exc.sample = idx or None
            raise exc
        q[..., leg, :] = ql
    return q


def rates(robot: RobotConfig, angles: np.ndarray, foot_velocity: np.ndarray) -> np.ndarray:
    """Joint rates ``(..., n_legs, 3)`` [rad/s] producing ``foot_velocity`` [m/s]."""
    out = np.empty(np.broadcast_shapes(np.shape(angles), np.shape(foot_velocity)))
    for leg in range(robot.n_legs):
        jac = _leg_fk(robot, leg, angles[..., leg, :])[1]
        if np.any(np.abs(np.linalg.det(jac)) < SINGULAR_DET):
            raise KinematicsError(f"leg {robot.legs[leg]}: Jacobian singular; joint rates "
                                  f"undefined")
        out[..., leg, :] = np.linalg.solve(jac, foot_velocity[..., leg, :, None])[..., 0]
    return out


def jacobians(robot: RobotConfig, angles: np.ndarray) -> np.ndarray:
    """Leg Jacobians ``d foot / d q`` ``(..., n_legs, 3, 3)`` [m/rad] in base_link."""
    a = np.asarray(angles, dtype=float)
    return np.stack([_leg_fk(robot, i, a[..., i, :])[1] for i in range(robot.n_legs)], axis=-3)


def leg_frame_feet(robot: RobotConfig, leg: int, feet: np.ndarray) -> np.ndarray:
    """Foot positions ``(..., 3)`` [m] of leg ``leg`` from base_link to its leg frame."""
    return to_leg(feet, robot.hips[leg], float(robot.neutral_yaw[leg]))
