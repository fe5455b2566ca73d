"""The URDF joint frames at given angles put every foot where the kinematics puts it."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.model.urdf import generate_urdf
from crawler_motion.recording.frames import (
    axis_rotation,
    chain_position,
    joint_transforms,
    quaternion_xyzw,
    urdf_joints,
)

CFG = load_config()
ROBOT = CFG.robot
JOINTS = urdf_joints(generate_urdf(ROBOT))


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-0.6, 0.6), min_size=12, max_size=12))
def test_feet_of_the_urdf_frames_match_the_forward_kinematics(q: list[float]) -> None:
    angles = np.array(q).reshape(4, 3)
    angles_by_name = dict(zip(ROBOT.joint_names, angles.ravel(), strict=True))
    transforms = joint_transforms(JOINTS, angles_by_name)
    feet = forward_kinematics(ROBOT, angles)
    for leg, name in enumerate(ROBOT.legs):
        np.testing.assert_allclose(chain_position(transforms, f"{name}_foot", "base_link"),
                                   feet[leg], atol=1e-9)


def test_a_joint_without_an_angle_leaves_its_subtree_out() -> None:
    transforms = joint_transforms(JOINTS, {})
    children = {t[1] for t in transforms}
    assert "base_inertia" in children  # fixed joints are always there
    assert not any(child.endswith("_coxa") for child in children)


@settings(max_examples=50, deadline=None)
@given(st.floats(-3.1, 3.1), st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(
    lambda v: np.linalg.norm(v) > 0.1))
def test_quaternions_are_unit_and_rotate_like_the_matrix(angle: float, axis: list[float]) -> None:
    from crawler_motion.model.rotations import quaternion_matrix

    rot = axis_rotation(np.array(axis), angle)
    x, y, z, w = quaternion_xyzw(rot)
    assert abs(np.linalg.norm([x, y, z, w]) - 1.0) < 1e-12
    np.testing.assert_allclose(quaternion_matrix(np.array([w, x, y, z])), rot, atol=1e-9)
