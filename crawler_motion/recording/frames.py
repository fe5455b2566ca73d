"""Frame transforms of the robot without tf2: each URDF joint's frame at the measured angles.

What ``robot_state_publisher`` does for a ROS user: the URDF generated from the robot
configuration (`crawler_motion.model.urdf`, the one source of the joint frames) is parsed into
its joints, and each joint becomes a parent -> child transform at its joint angle (revolute:
origin, then a rotation about its axis). With ``odom`` -> ``base_link`` from the odometry the
tree is complete from ``odom`` down to every foot.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from crawler_motion.errors import ConfigError
from crawler_motion.model.rotations import quaternion_matrix, rotation_vector_matrix, rpy_matrix

#: One transform: parent frame, child frame, translation [m], rotation quaternion (x, y, z, w).
Transform = tuple[str, str, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class UrdfJoint:
    """A URDF joint: its origin in the parent link (``xyz`` [m], ``rotation``) and its axis."""

    name: str
    kind: str
    parent: str
    child: str
    xyz: np.ndarray
    rotation: np.ndarray
    axis: np.ndarray


def _floats(text: str | None, default: str) -> np.ndarray:
    return np.array([float(v) for v in (text or default).split()])


def urdf_joints(urdf: str) -> list[UrdfJoint]:
    """The joints of the URDF text ``urdf``, in document order."""
    joints = []
    for el in ET.fromstring(urdf).iter("joint"):
        origin = el.find("origin")
        axis = el.find("axis")
        parent, child = el.find("parent"), el.find("child")
        if parent is None or child is None:
            raise ConfigError(f"URDF joint {el.get('name')!r} lacks its parent or child link")
        joints.append(UrdfJoint(
            el.get("name", ""), el.get("type", "fixed"), parent.get("link", ""),
            child.get("link", ""),
            _floats(None if origin is None else origin.get("xyz"), "0 0 0"),
            rpy_matrix(_floats(None if origin is None else origin.get("rpy"), "0 0 0")),
            _floats(None if axis is None else axis.get("xyz"), "1 0 0")))
    return joints


def axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """The rotation by ``angle`` [rad] about the unit vector ``axis`` (Rodrigues)."""
    return rotation_vector_matrix(axis / np.linalg.norm(axis) * angle)


def quaternion_xyzw(rotation: np.ndarray) -> np.ndarray:
    """The unit quaternion (x, y, z, w) of a rotation matrix."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    i = int(np.argmax([m[0, 0], m[1, 1], m[2, 2], trace]))
    if i == 3:  # Shepperd: divide by the largest component
        w = np.sqrt(1.0 + trace) / 2.0
        q = np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1], 0.0]) / (4 * w)
        q[3] = w
    else:
        j, k = (i + 1) % 3, (i + 2) % 3
        v = np.sqrt(max(0.0, 1.0 + m[i, i] - m[j, j] - m[k, k])) / 2.0
        q = np.zeros(4)
        q[i] = v
        q[j] = (m[j, i] + m[i, j]) / (4 * v)
        q[k] = (m[k, i] + m[i, k]) / (4 * v)
        q[3] = (m[k, j] - m[j, k]) / (4 * v)
    return q / np.linalg.norm(q)


def joint_transforms(joints: list[UrdfJoint], angles: Mapping[str, float]) -> list[Transform]:
    """Every joint's parent -> child transform; revolute joints at ``angles`` [rad] (a joint
    without an angle is left out: its subtree has no pose yet)."""
    out: list[Transform] = []
    for joint in joints:
        rotation = joint.rotation
        if joint.kind in ("revolute", "continuous"):
            if joint.name not in angles:
                continue
            rotation = rotation @ axis_rotation(joint.axis, float(angles[joint.name]))
        out.append((joint.parent, joint.child, joint.xyz, quaternion_xyzw(rotation)))
    return out


def chain_position(transforms: list[Transform], child: str, root: str) -> np.ndarray:
    """The origin of frame ``child`` in frame ``root`` [m] by composing ``transforms``."""
    by_child = {t[1]: t for t in transforms}
    point = np.zeros(3)
    frame = child
    while frame != root:
        parent, _, xyz, q = by_child[frame]
        rot = quaternion_matrix(np.array([q[3], q[0], q[1], q[2]]))
        point = xyz + rot @ point
        frame = parent
    return point
