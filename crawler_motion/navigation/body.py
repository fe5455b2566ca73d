"""The virtual body (spec §4): a circle around the centre of mass that must not touch obstacles.

Its radius is the largest horizontal distance from the body centre (base_link origin, taken as
the centre of mass) to a foot tip, from the forward kinematics of the measured joints, bounded
by the robot's envelope radius: the farthest hip plus the fully stretched leg.
"""

from __future__ import annotations

import numpy as np

from crawler_motion.model.config import RobotConfig
from crawler_motion.model.kinematics import forward_kinematics


def envelope_radius(robot: RobotConfig) -> float:
    """Farthest a foot can be from the body centre, horizontally [m]."""
    hips = np.linalg.norm(np.asarray(robot.hips)[:, :2], axis=1)
    return float(hips.max() + robot.l1 + robot.l2 + robot.l3)


def virtual_radius(robot: RobotConfig, joints: np.ndarray) -> float:
    """Virtual body radius [m] for joint angles ``joints`` ``(n_legs, 3)`` or flat [rad]."""
    feet = forward_kinematics(robot, np.asarray(joints, dtype=float).reshape(-1, 3))
    return float(min(np.linalg.norm(feet[:, :2], axis=1).max(), envelope_radius(robot)))
