"""Rolling foot contact: where the foot sphere's centre goes so its contact point stays put.

The foot is a sphere of radius ``r`` (`crawler_motion.model.urdf.foot_sphere_radius`, the
URDF's) rigidly fixed to the tibia; the IK places its centre. On the ground the sphere turns
with the tibia: about the vertical when the root yaws (no effect on the ground) and about the
horizontal axis normal to the leg's plane when the tibia's elevation ``beta = shoulder - knee``
changes. Rolling without slip, the centre then travels ``-r * delta_beta`` along the leg's
outward horizontal direction ``u`` (about 6-7 mm over a 6 cm sideways stride: the body went
10 % further than planned).

A plan therefore states **contact points** — the points of the ground the stance feet stand on
(in base_link, at the centres' height) — and the centre target of a stance foot is its contact
point plus the roll since its touch-down: ``c = p - r * (beta(c) - beta(c_touch)) * u(c)``,
solved by a fixed-point iteration (a contraction: ``r |d beta / d c| < 0.3``). At touch-down
the roll is zero, so the swing ends on the contact point. The nominal leg is used (the roll of a
calibrated leg differs by well under 0.1 mm).
"""

from __future__ import annotations

import numpy as np

from crawler_motion.errors import KinematicsError
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.kinematics import inverse_kinematics
from crawler_motion.model.urdf import foot_sphere_radius

#: Fixed-point iterations of `rolled_centres` (the error shrinks ~4x per iteration: < 0.1 um).
ITERATIONS = 10


def _elevation_and_direction(robot: RobotConfig, centres: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Tibia elevation ``(n_legs,)`` [rad] and outward unit direction ``(n_legs, 2)``."""
    q = inverse_kinematics(robot, centres, check=False)
    yaw = np.asarray(robot.neutral_yaw, dtype=float) + q[:, 0]
    return q[:, 1] - q[:, 2], np.stack((np.cos(yaw), np.sin(yaw)), axis=-1)


def rolled_centres(robot: RobotConfig, contacts: np.ndarray, touch: np.ndarray) -> np.ndarray:
    """Centre targets ``(n_legs, 3)`` [m] of stance feet on ``contacts`` ``(n_legs, 3)`` that
    touched down with their centres at ``touch`` ``(n_legs, 3)`` (both in base_link)."""
    radius = foot_sphere_radius(robot)
    centres = np.array(contacts, dtype=float)
    try:
        beta_touch, _ = _elevation_and_direction(robot, touch)
        for _ in range(ITERATIONS):
            beta, u = _elevation_and_direction(robot, centres)
            centres[:, :2] = contacts[:, :2] - radius * (beta - beta_touch)[:, None] * u
    except KinematicsError:
        # A point at the edge of the workspace: plan it without the roll; the walk's check
        # (`check_trajectories`) then refuses it if even the contact point is out of reach.
        return np.array(contacts, dtype=float)
    return centres
