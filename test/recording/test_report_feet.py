"""The report's foot paths: measured joints through the package's forward kinematics (with the
configuration's calibration), drawn into ``feet.png`` and shown by ``index.html``."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("rclpy")

from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.model.calibration_file import write_calibration
from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.recording import report, series
from crawler_motion.recording.sink import McapSink

ROBOT = load_config().robot
NAMES = list(ROBOT.joint_names)


def _stance(t: float) -> np.ndarray:
    """A slow sway of every joint around a standing pose [rad]."""
    base = np.tile([0.0, 0.3, 0.9], (4, 1))
    return base + 0.1 * np.sin(t + np.arange(12).reshape(4, 3))


@settings(max_examples=25, deadline=None)
@given(st.lists(st.lists(st.floats(-0.5, 0.5), min_size=12, max_size=12), min_size=1,
                max_size=5))
def test_feet_are_the_forward_kinematics_of_every_complete_sample(rows: list[list[float]]
                                                                  ) -> None:
    q = np.array(rows)
    q[0, 4] = np.nan  # the first sample lacks a joint: left out, not guessed
    measured = series.Joints(np.arange(len(q), dtype=float), NAMES, q)
    t, feet = series.feet(measured, ROBOT)
    np.testing.assert_array_equal(t, np.arange(1, len(q), dtype=float))
    np.testing.assert_allclose(feet, forward_kinematics(ROBOT, q[1:].reshape(-1, 4, 3)))


def test_zero_angles_put_each_foot_straight_out_from_its_hip() -> None:
    measured = series.Joints(np.zeros(1), NAMES, np.zeros((1, 12)))
    _, feet = series.feet(measured, ROBOT)
    reach = ROBOT.l1 + ROBOT.l2 + ROBOT.l3
    out = np.stack([np.cos(ROBOT.neutral_yaw), np.sin(ROBOT.neutral_yaw), 0 * ROBOT.neutral_yaw],
                   axis=-1)
    np.testing.assert_allclose(feet[0], ROBOT.hips + reach * out, atol=1e-12)


def test_no_measured_joints_gives_no_feet() -> None:
    t, feet = series.feet(series.Joints(np.zeros(0), NAMES, np.zeros((0, 12))), ROBOT)
    assert t.shape == (0,) and feet.shape == (0, 4, 3)


def _recording(path: Path, samples: int = 50) -> None:
    sink = McapSink(path)
    for i in range(samples):
        q = _stance(0.1 * i)
        msg = JointState(name=NAMES, position=[float(v) for v in q.ravel()])
        sink.write("/joint_states", "sensor_msgs/msg/JointState", serialize_message(msg),
                   1_000_000_000 + i * 10_000_000)
    sink.close()


def _calibrated_yaml(tmp_path: Path) -> tuple[Path, Any]:
    true = perturbed_robot(ROBOT, 3)
    write_calibration(tmp_path / "c.yaml", true.geometry)
    text = Path(load_config().source).read_text()
    robot_yaml = tmp_path / "robot.yaml"
    robot_yaml.write_text(text.replace("  name: crawler\n",
                                       "  name: crawler\n  calibration_file: c.yaml\n"))
    return robot_yaml, load_config(robot_yaml).robot


def test_the_report_draws_the_feet_of_the_configured_robot(tmp_path: Path,
                                                           monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    _recording(tmp_path / "run.mcap")
    robot_yaml, calibrated = _calibrated_yaml(tmp_path)
    assert calibrated.calibrated
    used: list[Any] = []
    real = series.feet
    monkeypatch.setattr(series, "feet", lambda m, r: used.append(r) or real(m, r))
    assert report.main([str(tmp_path / "run.mcap"), "-o", str(tmp_path / "r"), "--config",
                        str(robot_yaml)]) == 0
    assert used and used[0].calibrated
    page = (tmp_path / "r" / "index.html").read_text()
    assert "feet.png" in re.findall(r'<img src="([^"]+)"', page)
    assert (tmp_path / "r" / "feet.png").stat().st_size > 1000
    # the calibration moves the feet: the report is not drawing the nominal legs
    meas = series.Joints(np.zeros(1), NAMES, _stance(0.0).reshape(1, 12))
    shift = np.abs(series.feet(meas, calibrated)[1] - series.feet(meas, ROBOT)[1]).max()
    assert shift > 1e-4


def test_without_joint_states_the_feet_are_not_recorded(tmp_path: Path) -> None:
    sink = McapSink(tmp_path / "s.mcap")
    sink.write("/other", "sensor_msgs/msg/JointState", serialize_message(JointState()), 10)
    sink.close()
    assert report.main([str(tmp_path / "s.mcap"), "-o", str(tmp_path / "r")]) == 0
    assert not (tmp_path / "r" / "feet.png").exists()
    assert "Foot paths" in (tmp_path / "r" / "index.html").read_text()


def test_a_bad_config_is_one_line_and_exit_1(tmp_path: Path, capsys: Any) -> None:
    _recording(tmp_path / "run.mcap", 2)
    assert report.main([str(tmp_path / "run.mcap"), "--config",
                        str(tmp_path / "none.yaml")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "none.yaml" in err[0]
