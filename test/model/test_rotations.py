"""Tests of crawler_motion.model.rotations: roll-pitch-yaw and quaternion matrices."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from crawler_motion.model.rotations import (
    matrix_quaternion,
    quaternion_matrix,
    roll_pitch,
    rpy_angular_acceleration,
    rpy_angular_velocity,
    rpy_matrix,
    slerp_rotation,
    yaw_of,
)


def _rx(a: float) -> np.ndarray:
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def _ry(a: float) -> np.ndarray:
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def _rz(a: float) -> np.ndarray:
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


@pytest.mark.parametrize(("rpy", "x_axis"), [
    ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)),
    ((0.0, math.pi / 2, 0.0), (0.0, 0.0, -1.0)),  # pitch +90°: x points down (REP-103)
    ((0.0, 0.0, math.pi / 2), (0.0, 1.0, 0.0)),  # yaw +90°: x points left
    ((math.pi / 2, 0.0, 0.0), (1.0, 0.0, 0.0)),  # roll leaves x alone
])
def test_rpy_matrix_moves_the_x_axis_as_rep103_says(rpy: tuple, x_axis: tuple) -> None:
    np.testing.assert_allclose(rpy_matrix(np.array(rpy)) @ [1.0, 0.0, 0.0], x_axis, atol=1e-15)


angles = st.floats(-3.0, 3.0)


@given(angles, st.floats(-1.5, 1.5), angles)
def test_rpy_is_fixed_axis_roll_then_pitch_then_yaw(roll: float, pitch: float, yaw: float
                                                     ) -> None:
    r = rpy_matrix(np.array([roll, pitch, yaw]))
    np.testing.assert_allclose(r, _rz(yaw) @ _ry(pitch) @ _rx(roll), atol=1e-12)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert roll_pitch(r) == pytest.approx((roll, pitch), abs=1e-9)
    assert yaw_of(r) == pytest.approx(yaw, abs=1e-9)


def test_rpy_matrix_takes_a_batch_of_angles() -> None:
    rpy = np.random.default_rng(3).uniform(-3.0, 3.0, (5, 2, 3))
    batch = rpy_matrix(rpy)
    assert batch.shape == (5, 2, 3, 3)
    for index in np.ndindex(5, 2):
        np.testing.assert_array_equal(batch[index], rpy_matrix(rpy[index]))


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


vectors = st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3).map(np.array)


@given(vectors, vectors, vectors)
def test_angular_velocity_and_acceleration_are_the_derivatives(rpy, rate, accel) -> None:
    """dR/dt = [w]x R and dw/dt, against central differences along rpy + rate t + accel t^2/2."""
    h = 1e-5

    def angles(t: float) -> np.ndarray:
        return rpy + rate * t + 0.5 * accel * t * t

    def omega(t: float) -> np.ndarray:
        return rpy_angular_velocity(angles(t), rate + accel * t)

    r_dot = (rpy_matrix(angles(h)) - rpy_matrix(angles(-h))) / (2 * h)
    np.testing.assert_allclose(r_dot, _skew(omega(0.0)) @ rpy_matrix(rpy), atol=1e-8)
    np.testing.assert_allclose((omega(h) - omega(-h)) / (2 * h),
                               rpy_angular_acceleration(rpy, rate, accel), atol=1e-8)


@given(st.floats(-3.0, 3.0), st.floats(0.1, 10.0))
def test_quaternion_of_a_yaw_equals_the_yaw_matrix(yaw: float, scale: float) -> None:
    q = scale * np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])  # normalised first
    np.testing.assert_allclose(quaternion_matrix(q), _rz(yaw), atol=1e-12)


@pytest.mark.parametrize("q", [(0.0, 0.0, 0.0, 0.0), (1e-12, 0.0, 0.0, 0.0),
                               (math.nan, 0.0, 0.0, 1.0)])
def test_a_quaternion_without_direction_is_refused(q: tuple) -> None:
    with pytest.raises(ValueError, match="no direction"):
        quaternion_matrix(np.array(q))


unit_quaternions = st.tuples(*[st.floats(-1.0, 1.0)] * 4).filter(
    lambda q: np.linalg.norm(q) > 0.1)


@given(unit_quaternions)
def test_matrix_quaternion_inverts_quaternion_matrix(q: tuple) -> None:
    rot = quaternion_matrix(np.array(q))
    back = matrix_quaternion(rot)
    assert back[0] >= 0.0 and np.linalg.norm(back) == pytest.approx(1.0)
    np.testing.assert_allclose(quaternion_matrix(back), rot, atol=1e-12)


@pytest.mark.parametrize("start, end, fraction, expected", [
    (0.0, 1.0, 0.0, 0.0),  # the ends
    (0.0, 1.0, 1.0, 1.0),
    (0.0, 1.0, 0.25, 0.25),  # a quarter of the angle
    (0.5, 0.5, 0.7, 0.5),  # the same rotation
    (3.0, -3.0, 0.5, math.pi),  # the shorter arc, through 180° (not through 0)
])
def test_slerp_of_yaws_turns_at_a_constant_rate_along_the_shorter_arc(
        start: float, end: float, fraction: float, expected: float) -> None:
    np.testing.assert_allclose(slerp_rotation(_rz(start), _rz(end), fraction), _rz(expected),
                               atol=1e-12)
