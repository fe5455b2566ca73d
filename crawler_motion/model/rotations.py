"""Rotation matrices of the frames the package uses: fixed-axis roll-pitch-yaw and quaternions."""

from __future__ import annotations

import math

import numpy as np

#: Smallest quaternion norm that still has a direction.
MIN_QUATERNION_NORM = 1e-9


def rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """Rotation matrix of fixed-axis roll, pitch, yaw [rad]: ``Rz(yaw) Ry(pitch) Rx(roll)``.

    ``rpy`` is ``(..., 3)``; the result ``(..., 3, 3)`` (one matrix per leading index).
    """
    angles = np.asarray(rpy, dtype=float)
    cr, cp, cy = np.moveaxis(np.cos(angles), -1, 0)
    sr, sp, sy = np.moveaxis(np.sin(angles), -1, 0)
    rows = ((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            (-sp, cp * sr, cp * cr))
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def rpy_angular_velocity(rpy: np.ndarray, rpy_rate: np.ndarray) -> np.ndarray:
    """Angular velocity ``(..., 3)`` [rad/s], in the fixed (parent) frame, of the rotation
    `rpy_matrix` (``rpy`` [rad]) whose angles change at ``rpy_rate`` [rad/s]: yaw turns about
    the fixed z, pitch about the once-yawed y, roll about the rotated x
    (``dR/dt = [w]x R``)."""
    angles = np.asarray(rpy, dtype=float)
    rates = np.asarray(rpy_rate, dtype=float)
    _, pitch, yaw = np.moveaxis(angles, -1, 0)
    roll_dot, pitch_dot, yaw_dot = np.moveaxis(rates, -1, 0)
    cp, sp, cy, sy = np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return np.stack((cy * cp * roll_dot - sy * pitch_dot,
                     sy * cp * roll_dot + cy * pitch_dot,
                     yaw_dot - sp * roll_dot), axis=-1)


def rpy_angular_acceleration(rpy: np.ndarray, rpy_rate: np.ndarray, rpy_accel: np.ndarray
                             ) -> np.ndarray:
    """Angular acceleration ``(..., 3)`` [rad/s^2] (fixed frame), the time derivative of
    `rpy_angular_velocity`, for angles [rad], their rates [rad/s] and accelerations
    [rad/s^2]."""
    angles, rates, accels = (np.asarray(a, dtype=float) for a in (rpy, rpy_rate, rpy_accel))
    _, pitch, yaw = np.moveaxis(angles, -1, 0)
    roll_dot, pitch_dot, yaw_dot = np.moveaxis(rates, -1, 0)
    roll_dd, pitch_dd, yaw_dd = np.moveaxis(accels, -1, 0)
    cp, sp, cy, sy = np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return np.stack(
        (cy * cp * roll_dd - sy * pitch_dd
         - (sy * cp * yaw_dot + cy * sp * pitch_dot) * roll_dot - cy * yaw_dot * pitch_dot,
         sy * cp * roll_dd + cy * pitch_dd
         + (cy * cp * yaw_dot - sy * sp * pitch_dot) * roll_dot - sy * yaw_dot * pitch_dot,
         yaw_dd - sp * roll_dd - cp * pitch_dot * roll_dot), axis=-1)


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


def matrix_quaternion(rotation: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), ``w >= 0``, of a rotation matrix (the inverse of
    `quaternion_matrix`; Shepperd's method: from the largest of w, x, y, z)."""
    m = np.asarray(rotation, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    k = int(np.argmax([tr, m[0, 0], m[1, 1], m[2, 2]]))
    if k == 0:
        s = 2.0 * math.sqrt(max(1.0 + tr, 0.0))
        q = (s / 4, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    elif k == 1:
        s = 2.0 * math.sqrt(max(1.0 + 2 * m[0, 0] - tr, 0.0))
        q = ((m[2, 1] - m[1, 2]) / s, s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
    elif k == 2:
        s = 2.0 * math.sqrt(max(1.0 + 2 * m[1, 1] - tr, 0.0))
        q = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s)
    else:
        s = 2.0 * math.sqrt(max(1.0 + 2 * m[2, 2] - tr, 0.0))
        q = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4)
    quat = np.array(q) / np.linalg.norm(q)
    return -quat if quat[0] < 0 else quat


def slerp_rotation(start: np.ndarray, end: np.ndarray, fraction: float) -> np.ndarray:
    """Rotation matrix ``fraction`` (0..1) of the way from ``start`` to ``end`` along the
    shorter great arc (quaternion slerp: constant angular rate about one axis)."""
    q0, q1 = matrix_quaternion(start), matrix_quaternion(end)
    dot = float(q0 @ q1)
    if dot < 0.0:  # q and -q are the same rotation: take the shorter arc
        q1, dot = -q1, -dot
    angle = math.acos(min(dot, 1.0))
    if angle < 1e-9:  # (nearly) the same rotation: linear is exact to rounding
        return quaternion_matrix(q0 + fraction * (q1 - q0))
    q = (math.sin((1.0 - fraction) * angle) * q0 + math.sin(fraction * angle) * q1)
    return quaternion_matrix(q / math.sin(angle))


def rotation_vector_matrix(vector: np.ndarray) -> np.ndarray:
    """The rotation ``(3, 3)`` by ``|vector|`` [rad] about ``vector`` ``(3,)`` (Rodrigues)."""
    v = np.asarray(vector, dtype=float)
    angle = float(np.linalg.norm(v))
    if angle == 0.0:
        return np.eye(3)
    k = v / angle
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * kx + (1.0 - math.cos(angle)) * kx @ kx


def rotation_angle(rotation: np.ndarray) -> float:
    """Angle [rad] of the rotation matrix ``rotation`` (0..π), accurate for small angles."""
    m = np.asarray(rotation, dtype=float)
    skew = 0.5 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    return math.atan2(float(np.linalg.norm(skew)), (float(np.trace(m)) - 1.0) / 2.0)
