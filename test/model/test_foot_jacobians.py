"""The leg Jacobians of `kinematics.foot_jacobians`: finite differences of the FK, the inverse
of `joint_velocities`, calibrated legs through their chains."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.errors import KinematicsError
from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import (
    foot_jacobians,
    forward_kinematics,
    inverse_kinematics,
    joint_velocities,
)

ROBOT = load_config().robot
CALIBRATED = perturbed_robot(ROBOT, 1)


def angles(robot):
    columns = [st.floats(float(lo), float(hi)) for lo, hi in zip(robot.lower, robot.upper,
                                                                  strict=True)]
    return st.lists(st.tuples(*columns), min_size=4, max_size=4).map(np.array)


def numeric(robot, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    jac = np.empty((*q.shape, 3))
    for j in range(3):
        dq = np.zeros(3)
        dq[j] = h
        jac[..., j] = (forward_kinematics(robot, q + dq) - forward_kinematics(robot, q - dq)) / (
            2 * h)
    return jac


@pytest.mark.parametrize("robot", [ROBOT, CALIBRATED], ids=["nominal", "calibrated"])
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_jacobians_are_the_derivatives_of_the_fk(robot, data):
    q = data.draw(angles(robot))
    np.testing.assert_allclose(foot_jacobians(robot, q), numeric(robot, q), rtol=0, atol=1e-8)


def test_the_jacobian_inverts_joint_velocities():
    q = inverse_kinematics(ROBOT, ROBOT.standing_feet())
    v = np.array([[0.1, 0.0, 0.0], [0.0, -0.05, 0.02], [0.0, 0.0, -0.1], [0.03, 0.03, 0.03]])
    qdot = joint_velocities(ROBOT, q, v)
    np.testing.assert_allclose(np.einsum("lij,lj->li", foot_jacobians(ROBOT, q), qdot), v,
                               atol=1e-12)


def test_batches_and_shapes():
    q = inverse_kinematics(ROBOT, ROBOT.standing_feet())
    batch = np.stack([q, q + 0.1, q - 0.05])
    jac = foot_jacobians(ROBOT, batch)
    assert jac.shape == (3, 4, 3, 3)
    np.testing.assert_allclose(jac[1], foot_jacobians(ROBOT, q + 0.1))
    assert foot_jacobians(CALIBRATED, batch).shape == (3, 4, 3, 3)
    with pytest.raises(KinematicsError, match="shaped"):
        foot_jacobians(ROBOT, np.zeros((3, 3)))
    with pytest.raises(KinematicsError, match="NaN"):
        foot_jacobians(ROBOT, np.full((4, 3), np.nan))
