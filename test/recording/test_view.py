"""The live view's robot description: the configured robot with its leg calibration."""

from __future__ import annotations

import pytest

from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.model.calibration_file import write_calibration
from crawler_motion.model.config import load_config
from crawler_motion.model.urdf import generate_urdf
from crawler_motion.recording import view


def test_the_description_has_the_given_calibration(tmp_path) -> None:
    robot = load_config().robot
    true = perturbed_robot(robot, 6)
    assert true.geometry is not None
    write_calibration(tmp_path / "legs.yaml", true.geometry)
    nominal = view.robot_description(view.parse_args([]))
    calibrated = view.robot_description(view.parse_args(["--calibration",
                                                         str(tmp_path / "legs.yaml")]))
    assert nominal == generate_urdf(robot)
    assert calibrated == generate_urdf(true) != nominal


def test_a_bad_calibration_file_is_one_line_and_exit_1(tmp_path, capsys) -> None:
    bad = tmp_path / "legs.yaml"
    bad.write_text("calibration: {legs: {rf: {knee_offset: 0.2}}}")  # 11.5 deg: implausible
    assert view.main(["--calibration", str(bad), "--port", "0"]) == 1
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert out == "" and len(lines) == 1 and "knee_offset" in lines[0]
    assert lines[0].startswith("crawler-motion view: error: ")


@pytest.mark.parametrize("argv", [["--calibration", "missing.yaml"], ["--config", "no.yaml"]])
def test_missing_files_are_refused_before_serving(argv, capsys) -> None:
    assert view.main(argv) == 1
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
