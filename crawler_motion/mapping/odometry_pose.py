"""An odometry message read as a stamped body pose (one reading for the mapper and navigator)."""

from __future__ import annotations

from typing import Any

import numpy as np

from crawler_motion.mapping.mapper import Pose
from crawler_motion.model.rotations import quaternion_matrix


def stamp_seconds(stamp: Any) -> float:
    """A builtin_interfaces/Time as seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def odometry_pose(msg: Any) -> Pose:
    """A nav_msgs/Odometry as a `Pose` (stamp [s], rotation base_link -> odom, position [m]);
    the rotation is NaN when the quaternion is not one (`odometry.OdometryGate` refuses it)."""
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    try:
        rot = quaternion_matrix(np.array([q.w, q.x, q.y, q.z]))
    except ValueError:
        rot = np.full((3, 3), np.nan)
    return Pose(stamp_seconds(msg.header.stamp), rot, np.array([p.x, p.y, p.z], dtype=float))
