"""Rotation matrices of the frames the package uses: fixed-axis roll-pitch-yaw and quaternions."""

from __future__ import annotations

import math

import numpy as np

#: Smallest quaternion norm that still has a direction.
MIN_QUATERNION_NORM = 1e-9


def rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """Rotation matrix of fixed-axis roll, pitch, yaw [rad]: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    roll, pitch, yaw = (float(a) for a in rpy)
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def quaternion_matrix(wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z); it is normalised first."""
    q = np.asarray(wxyz, dtype=float)
    norm = float(np.linalg.norm(q))
    if not (math.isfinite(norm) and norm > MIN_QUATERNION_NORM):
        raise ValueError(f"quaternion {q.tolist()} has no direction")
    w, x, y, z = q / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def roll_pitch(rotation: np.ndarray) -> tuple[float, float]:
    """Roll and pitch [rad] of ``rotation`` = ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    return (math.atan2(rotation[2, 1], rotation[2, 2]),
            math.asin(max(-1.0, min(1.0, -rotation[2, 0]))))


def yaw_of(rotation: np.ndarray) -> float:
    """Yaw [rad] of ``rotation`` (about z)."""
    return math.atan2(rotation[1, 0], rotation[0, 0])
