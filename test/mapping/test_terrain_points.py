"""Returns into the map frame and their height variance (the study's eq. 3)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_motion.errors import ConfigError
from crawler_motion.mapping.points import (
    Mount,
    NoiseModel,
    returns_in_map,
)
from crawler_motion.model.rotations import quaternion_matrix, roll_pitch, rpy_matrix


@pytest.mark.parametrize("theta_deg", [0.0, 10.0, 30.0, 45.0, 89.0, 90.0])
def test_a_pitched_beam_with_range_noise_only_has_height_sigma_r_sin_theta(theta_deg: float
                                                                           ) -> None:
    theta, sigma_r = math.radians(theta_deg), 0.01
    mount = Mount(rpy_matrix(np.array([0.0, theta, 0.0])), np.array([0.12, 0.0, 0.0]))
    noise = NoiseModel(range_noise=sigma_r, lateral_noise=0.0, attitude_noise=0.0)
    p_m, var = returns_in_map(np.array([[1.5, 0.0, 0.0]]), mount, np.eye(3),
                              np.array([0.0, 0.0, 0.07]), noise)
    assert math.sqrt(var[0]) == pytest.approx(sigma_r * math.sin(theta), abs=1e-12)
    assert p_m[0, 2] == pytest.approx(0.07 - 1.5 * math.sin(theta), abs=1e-12)


def test_lateral_noise_of_a_level_beam_is_its_whole_height_noise() -> None:
    mount = Mount(np.eye(3), np.zeros(3))
    noise = NoiseModel(range_noise=0.01, lateral_noise=0.002, attitude_noise=0.0)
    _, var = returns_in_map(np.array([[2.0, 0.0, 0.0]]), mount, np.eye(3), np.zeros(3), noise)
    assert var[0] == pytest.approx((0.002 * 2.0) ** 2)


@pytest.mark.parametrize("roll, pitch", [(0.0, 0.0), (0.1, -0.05), (-0.3, 0.2)])
def test_the_attitude_term_is_the_numeric_jacobian_of_the_height(roll: float, pitch: float
                                                                 ) -> None:
    mount = Mount(rpy_matrix(np.array([0.0, 0.17, 0.0])), np.array([0.12, 0.0, 0.0]))
    pts = np.array([[1.0, 0.3, -0.1], [0.4, -0.2, 0.05]])
    sq, eps = 0.02, 1e-7
    body = rpy_matrix(np.array([roll, pitch, 0.4]))
    _, var = returns_in_map(pts, mount, body, np.zeros(3),
                            NoiseModel(range_noise=0.0, lateral_noise=0.0, attitude_noise=sq))

    def height(r: float, p: float) -> np.ndarray:
        return returns_in_map(pts, mount, rpy_matrix(np.array([r, p, 0.4])), np.zeros(3),
                              NoiseModel())[0][:, 2]

    d_roll = (height(roll + eps, pitch) - height(roll - eps, pitch)) / (2 * eps)
    d_pitch = (height(roll, pitch + eps) - height(roll, pitch - eps)) / (2 * eps)
    np.testing.assert_allclose(var, sq**2 * (d_roll**2 + d_pitch**2), rtol=1e-5)


def test_quaternion_and_roll_pitch_agree_with_rpy() -> None:
    rpy = np.array([0.1, -0.2, 1.0])
    half = rpy / 2
    cr, sr, cp, sp, cy, sy = (np.cos(half[0]), np.sin(half[0]), np.cos(half[1]),
                              np.sin(half[1]), np.cos(half[2]), np.sin(half[2]))
    q = [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
         cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]
    np.testing.assert_allclose(quaternion_matrix(np.array(q) * 3.0), rpy_matrix(rpy), atol=1e-12)
    assert roll_pitch(rpy_matrix(rpy)) == pytest.approx((0.1, -0.2))
    with pytest.raises(ValueError, match="no direction"):
        quaternion_matrix(np.zeros(4))


@pytest.mark.parametrize("kw", [{"range_noise": -0.1}, {"lateral_noise": float("inf")},
                                {"range_noise": 0.0, "lateral_noise": 0.0,
                                 "attitude_noise": 0.0}])
def test_bad_noise_models_are_refused(kw: dict) -> None:
    with pytest.raises(ConfigError):
        NoiseModel(**kw)


def test_the_mount_of_robot_yaml_looks_forward_and_down_by_its_pitch() -> None:
    from crawler_motion.model.config import load_scanner

    sc = load_scanner()
    mount = Mount.from_config(sc)
    forward = mount.rotation @ np.array([1.0, 0.0, 0.0])  # scanner x axis in base_link
    pitch = float(sc.rpy[1])
    np.testing.assert_allclose(forward, [np.cos(pitch), 0.0, -np.sin(pitch)], atol=1e-12)
    assert forward[2] < 0.0  # pitched down: a positive pitch about y tilts x towards -z
    np.testing.assert_allclose(mount.position, sc.position)
