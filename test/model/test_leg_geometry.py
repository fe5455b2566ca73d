"""Per-leg geometry: the chain at nominal values is the closed form, its Jacobian matches finite
differences, the calibrated IK lands within 1e-6 m, calibration files are checked."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.errors import CalibrationError, UnreachableError
from crawler_motion.model import kinematics
from crawler_motion.model.calibration_file import (
    load_calibration,
    nominal_calibration,
    with_calibration,
    write_calibration,
)
from crawler_motion.model.config import load_config
from crawler_motion.model.leg_geometry import INDEX, N_PARAMS, NAMES, leg_chain, nominal_params
from crawler_motion.motion.fastpath import FastKinematics

ROBOT = load_config().robot
LINKS = (ROBOT.l1, ROBOT.l2, ROBOT.l3)


def _poses(n: int, seed: int = 0) -> np.ndarray:
    """Poses away from the root axis (the IK's r > 0 branch)."""
    q = np.random.default_rng(seed).uniform([-0.8, -0.9, 0.2], [0.8, 1.3, 2.0], (4 * n, 4, 3))
    feet = kinematics.forward_kinematics(ROBOT, q) - ROBOT.hips
    return q[(np.hypot(feet[..., 0], feet[..., 1]) > 0.04).all(-1)][:n]


def test_nominal_chain_is_the_closed_form() -> None:
    q = _poses(200)
    nominal = replace(ROBOT, geometry=nominal_calibration(ROBOT.legs, LINKS))
    assert not nominal.calibrated
    chain = np.stack([kinematics.calibrated.forward(nominal, q)])[0]
    np.testing.assert_allclose(chain, kinematics.forward_kinematics(ROBOT, q), atol=1e-15)


def test_parameter_jacobian_matches_central_differences() -> None:
    rng = np.random.default_rng(1)
    params = nominal_params(*LINKS) + rng.normal(0.0, 1e-3, N_PARAMS)
    q = _poses(5)[:, 0]
    jac = leg_chain(params, q)[1]
    for k in range(N_PARAMS):
        step = np.zeros(N_PARAMS)
        step[k] = 1e-6
        numeric = (leg_chain(params + step, q)[0] - leg_chain(params - step, q)[0]) / 2e-6
        np.testing.assert_allclose(jac[..., k], numeric, atol=1e-9, err_msg=str(k))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_calibrated_ik_lands_within_a_micrometre(seed: int) -> None:
    true = perturbed_robot(ROBOT, seed)
    q = _poses(300, seed)
    feet = kinematics.forward_kinematics(true, q)
    assert np.linalg.norm(kinematics.forward_kinematics(ROBOT, q) - feet, axis=-1).mean() > 5e-4
    solved = kinematics.inverse_kinematics(true, feet, check=False)
    assert np.abs(kinematics.forward_kinematics(true, solved) - feet).max() < 1e-6
    np.testing.assert_allclose(solved, q, atol=1e-6)


def test_calibrated_rates_invert_the_chain_jacobian() -> None:
    true = perturbed_robot(ROBOT, 4)
    q = _poses(20)
    qd = np.random.default_rng(2).normal(0.0, 0.3, q.shape)
    h = 1e-7
    v = (kinematics.forward_kinematics(true, q + h * qd)
         - kinematics.forward_kinematics(true, q - h * qd)) / (2 * h)
    np.testing.assert_allclose(kinematics.joint_velocities(true, q, v), qd, atol=1e-6)


def test_fast_path_uses_the_calibrated_legs() -> None:
    true = perturbed_robot(ROBOT, 5)
    q = _poses(1)[0]
    feet = kinematics.forward_kinematics(true, q)
    fast = np.array(FastKinematics(true).inverse(feet.reshape(-1).tolist(), check=False))
    np.testing.assert_allclose(fast.reshape(4, 3), q, atol=1e-6)


def test_unreachable_for_the_calibrated_leg_is_refused() -> None:
    true = perturbed_robot(ROBOT, 1)
    far = ROBOT.standing_feet()
    far[0, 1] += 0.2
    with pytest.raises(UnreachableError):
        kinematics.inverse_kinematics(true, far)


def test_file_round_trip_and_robot_yaml_reference(tmp_path: Path) -> None:
    true = perturbed_robot(ROBOT, 6)
    assert true.geometry is not None
    write_calibration(tmp_path / "c.yaml", true.geometry)
    back = load_calibration(tmp_path / "c.yaml", ROBOT.legs, LINKS)
    np.testing.assert_array_equal(back.params, true.geometry.params)
    text = Path(load_config().source).read_text()
    robot_yaml = tmp_path / "robot.yaml"
    robot_yaml.write_text(text.replace("  name: crawler\n",
                                       "  name: crawler\n  calibration_file: c.yaml\n"))
    loaded = load_config(robot_yaml).robot
    assert loaded.calibrated
    np.testing.assert_array_equal(loaded.geometry.params, true.geometry.params)


@pytest.mark.parametrize(("body", "reason"), [
    ("calibration: {legs: {lf: {l2: 0.0661}}}", "more than 10%"),   # 10.2 % long
    ("calibration: {legs: {lf: {l2: 0.0539}}}", "more than 10%"),   # 10.2 % short
    (f"calibration: {{legs: {{lf: {{knee_offset: {math.radians(10.01)}}}}}}}", "beyond ±10 deg"),
    (f"calibration: {{legs: {{rb: {{root_tilt_x: {-math.radians(10.5)}}}}}}}", "beyond ±10 deg"),
    ("calibration: {legs: {lf: {hip_x: 0.0031}}}", "beyond"),
    ("calibration: {legs: {xx: {l1: 0.03}}}", "does not exist"),
    ("calibration: {legs: {lf: {l9: 0.03}}}", "is not a parameter"),
    ("calibration: {legs: {lf: {l1: .nan}}}", "finite number"),
    ("calibration: {legs: {lf: {l1: yes}}}", "finite number"),
    ("calibration: {legs: [lf]}", "needs a mapping"),
    ("calibration: {legs: {lf: {l1: [}}", "not valid YAML"),
    ("calibration: {legs: {lf: {knee_yaw: 0.001}}}", "needs 'version: 2'"),
    ("calibration: {version: 3, legs: {lf: {l1: 0.03}}}", "newer than this"),
    ("calibration: {version: two, legs: {lf: {l1: 0.03}}}", "must be 1 or 2"),
    ("calibration: {version: 0, legs: {lf: {l1: 0.03}}}", "must be 1 or 2"),
    (f"calibration: {{version: 2, legs: {{lf: {{knee_yaw: {math.radians(10.01)}}}}}}}",
     "beyond ±10 deg"),
])
def test_bad_files_are_refused_with_the_reason(tmp_path: Path, body: str, reason: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(body)
    with pytest.raises(CalibrationError, match=reason):
        with_calibration(ROBOT, path)


@pytest.mark.parametrize(("key", "value"), [("l2", 0.0659), ("l2", 0.0541),
                                            ("knee_offset", math.radians(9.99)),
                                            ("knee_yaw", -math.radians(9.99))])
def test_plausible_boundary_values_load(tmp_path: Path, key: str, value: float) -> None:
    path = tmp_path / "ok.yaml"
    path.write_text(f"calibration: {{version: 2, legs: {{lb: {{{key}: {value}}}}}}}")
    calib = load_calibration(path, ROBOT.legs, LINKS)
    assert calib.params[1, INDEX[key]] == value and calib.nominal_legs == (True, False, True,
                                                                           True)


def test_a_version_1_file_loads_unchanged_with_a_note(tmp_path: Path) -> None:
    """A file of the 16-parameter model (no version, no knee_yaw): same legs, knee_yaw 0, and
    a note saying to identify again; a written file is version 2."""
    true = perturbed_robot(ROBOT, 6)
    assert true.geometry is not None
    old = true.geometry.params.copy()
    old[:, INDEX["knee_yaw"]] = 0.0
    lines = [f"    {leg}: {{" + ", ".join(f"{name}: {float(old[i, k])!r}" for k, name in enumerate(
        NAMES) if name != "knee_yaw") + "}" for i, leg in enumerate(ROBOT.legs)]
    (tmp_path / "v1.yaml").write_text("calibration:\n  legs:\n" + "\n".join(lines) + "\n")
    back = load_calibration(tmp_path / "v1.yaml", ROBOT.legs, LINKS)
    np.testing.assert_array_equal(back.params, old)
    assert back.version == 1 and "identify the legs again" in back.note
    write_calibration(tmp_path / "v2.yaml", back)
    again = load_calibration(tmp_path / "v2.yaml", ROBOT.legs, LINKS)
    assert again.version == 2 and again.note == ""
    assert "version: 2" in (tmp_path / "v2.yaml").read_text()
