"""Body attitude on rough ground: the stance plane, the limits, the smooth profile and the foot
targets of a posed body."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import load_config
from crawler_motion.motion.attitude import (
    AttitudeMode,
    AttitudeProfile,
    AttitudeSettings,
    apply_pose,
    bounded,
    stance_plane,
)
from crawler_motion.motion.body_pose import posed_foot_motion

ROBOT = load_config().robot
XY = ROBOT.standing_feet(None)[:, :2]  # x ±0.1 m, y ±0.19 m
FRONT = XY[:, 0] > 0
LEFT = XY[:, 1] > 0


@pytest.mark.parametrize(("delta", "expected"), [
    (np.zeros(4), (0.0, 0.0, 0.0)),  # the planned ground: no change
    (np.full(4, 0.01), (0.01, 0.0, 0.0)),  # all 1 cm up: the body 1 cm up
    (np.where(FRONT, 0.01, 0.0), (0.005, 0.0, -math.atan(0.05))),  # front on a step: nose up
    (np.where(LEFT, 0.019, 0.0), (0.0095, math.atan(0.05), 0.0)),  # left higher: roll left up
    (np.where(FRONT, -0.01, 0.0), (-0.005, 0.0, math.atan(0.05))),  # front lower: nose down
])
def test_the_stance_plane_gives_height_roll_and_pitch(delta: np.ndarray,
                                                      expected: tuple[float, ...]) -> None:
    assert stance_plane(XY, delta) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize(("xy", "delta"), [
    (XY[:2], np.zeros(2)),  # two footholds
    (np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0]]), np.zeros(3)),  # collinear
    (XY, np.array([0.0, 0.0, math.nan, 0.0])),  # a foothold unknown
    (XY, np.zeros(3)),  # counts differ
])
def test_no_plane_without_three_footholds_spread_in_x_and_y(xy: np.ndarray,
                                                            delta: np.ndarray) -> None:
    assert stance_plane(xy, delta) is None


@settings(max_examples=50, deadline=None)
@given(st.floats(-0.02, 0.02), st.floats(-0.3, 0.3), st.floats(-0.3, 0.3),
       st.lists(st.floats(-0.3, 0.3), min_size=8, max_size=8))
def test_footholds_on_a_plane_give_that_plane(z: float, b: float, c: float,
                                              coords: list[float]) -> None:
    xy = np.reshape(coords, (4, 2))
    centred = xy - xy.mean(axis=0)
    assume(np.linalg.det(centred.T @ centred) / 16 > 1e-4)
    delta = z + b * xy[:, 0] + c * xy[:, 1]
    assert stance_plane(xy, delta) == pytest.approx((z, math.atan(c), -math.atan(b)),
                                                    abs=1e-9)


@pytest.mark.parametrize(("target", "expected"), [
    ((0.03, 0.2, -0.2), (0.02, 0.15, -0.15)),
    ((0.02, 0.15, -0.15), (0.02, 0.15, -0.15)),  # at the limits: kept
    ((-0.001, 0.01, 0.0), (-0.001, 0.01, 0.0)),
])
def test_targets_are_bounded(target: tuple[float, ...], expected: tuple[float, ...]) -> None:
    assert bounded(target, AttitudeSettings()) == pytest.approx(expected)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"mode": "tilted"}, "attitude mode must be one of"),
    ({"max_tilt": -0.01}, "attitude max_tilt"),
    ({"max_tilt": 0.51}, "attitude max_tilt"),
    ({"max_lift": 0.051}, "attitude max_lift"),
    ({"max_lift": math.inf}, "attitude max_lift"),
])
def test_bad_settings_are_refused(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        AttitudeSettings(**kwargs)  # type: ignore[arg-type]


def test_a_mode_given_by_name_is_the_enum() -> None:
    assert AttitudeSettings(mode="imu").mode is AttitudeMode.IMU  # type: ignore[arg-type]
    assert AttitudeSettings(max_tilt=0.5, max_lift=0.0).max_tilt == 0.5


def test_the_profile_moves_smoothly_from_rest_to_rest_over_the_slot() -> None:
    profile = AttitudeProfile()
    assert profile.quiet()
    profile.plan(1.0, 0.6, (0.01, 0.02, -0.03))
    assert not profile.quiet()
    times = np.linspace(1.0, 1.6, 601)
    poses = np.array([profile.evaluate(t)[0] for t in times])
    rates = np.array([profile.evaluate(t)[1] for t in times])
    np.testing.assert_allclose(poses[0], 0.0, atol=1e-15)
    np.testing.assert_allclose(poses[-1], (0.01, 0.02, -0.03), atol=1e-15)
    np.testing.assert_allclose(rates[[0, -1]], 0.0, atol=1e-15)  # at rest at both ends
    np.testing.assert_allclose(np.gradient(poses, times, axis=0)[1:-1], rates[1:-1],
                               atol=1e-4)  # the rate is the pose's derivative
    acc = np.gradient(rates, times, axis=0)
    assert np.abs(acc[[1, -2]]).max() < 0.01  # C²: the acceleration starts and ends at ~0
    profile.plan(1.3, 0.6, (0.0, 0.0, 0.0))  # re-planned mid-way: starts where it was
    assert profile.evaluate(1.3)[0] == pytest.approx(tuple(poses[300]))


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-0.2, 0.2), min_size=6, max_size=6))
def test_posed_foot_targets_are_the_body_pose_commands(values: list[float]) -> None:
    z, roll, pitch, dz, droll, dpitch = values
    z *= 0.1
    dz *= 0.1
    feet = ROBOT.standing_feet(None)
    pos, vel = feet.reshape(-1).tolist(), [0.0] * 12
    apply_pose(pos, vel, (z, roll, pitch), (dz, droll, dpitch))
    ref_p, ref_v, _ = posed_foot_motion(feet, np.array([0, 0, z, roll, pitch, 0.0]),
                                        np.array([0, 0, dz, droll, dpitch, 0.0]), np.zeros(6))
    np.testing.assert_allclose(np.reshape(pos, (4, 3)), ref_p, atol=1e-12)
    np.testing.assert_allclose(np.reshape(vel, (4, 3)), ref_v, atol=1e-12)


def test_a_moving_foot_keeps_its_own_velocity_turned_into_the_body() -> None:
    pos, vel = [0.1, 0.19, -0.07], [0.2, 0.0, 0.05]
    pitch = 0.1
    apply_pose(pos, vel, (0.0, 0.0, pitch), (0.0, 0.0, 0.0))
    # R^T v for R = Ry(pitch): x' = cos p x - sin p z, z' = sin p x + cos p z
    assert vel == pytest.approx([0.2 * math.cos(pitch) - 0.05 * math.sin(pitch), 0.0,
                                 0.2 * math.sin(pitch) + 0.05 * math.cos(pitch)])
