"""The crawler-motion command line: CSV contracts and one-line errors."""

from __future__ import annotations

import csv
import io
import subprocess
import sys

import numpy as np
import pytest

from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.tools import cli


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def rows(text: str) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(text)))


def test_trajectory_header_and_both_ends(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "trajectory", "--rate", "100")
    assert code == 0
    assert out.splitlines()[0] == ("t,phase,x,y,z,vx,vy,vz,ax,ay,az,q_root,q_shoulder,q_knee")
    data = rows(out)
    g = load_config().gait  # the default gait's swing and the cycle's stance, both ends
    cycle = g.swing_time_of(g.gait) + g.stance_time
    assert len(data) == round(cycle * 100) + 1
    assert float(data[0]["t"]) == 0.0 and float(data[-1]["t"]) == pytest.approx(cycle)
    assert data[0]["phase"] == "lift" and data[-1]["phase"] == "stance"
    assert {r["phase"] for r in data} == {"lift", "arc", "lower", "stance"}
    first = np.array([float(data[0][k]) for k in "xyz"])
    last = np.array([float(data[-1][k]) for k in "xyz"])
    np.testing.assert_allclose(first, last, atol=1e-12)


@pytest.mark.parametrize("leg", ["lf", "lb", "rb", "rf"])
def test_trajectory_joint_angles_match_positions(capsys: pytest.CaptureFixture[str],
                                                 leg: str) -> None:
    cfg = load_config()
    code, out, _ = run(capsys, "trajectory", "--leg", leg, "--profile", "rest", "--rate", "50")
    assert code == 0
    idx = cfg.robot.legs.index(leg)
    for r in rows(out)[::7]:
        q = np.zeros((4, 3))
        q[:] = [0.0, 0.17, 1.27]
        q[idx] = [float(r[k]) for k in ("q_root", "q_shoulder", "q_knee")]
        foot = forward_kinematics(cfg.robot, q)[idx]
        np.testing.assert_allclose(foot, [float(r[k]) for k in "xyz"], atol=1e-8)


def test_trajectory_options_change_the_step(capsys: pytest.CaptureFixture[str]) -> None:
    _, out, _ = run(capsys, "trajectory", "--profile", "rest", "--stride", "0.04", "--lift",
                    "0.012", "--arc", "0.005", "--swing-time", "0.5", "--stance-time", "0.7",
                    "--rate", "200")
    data = rows(out)
    x = np.array([float(r["x"]) for r in data])
    z = np.array([float(r["z"]) for r in data])
    assert x.max() - x.min() == pytest.approx(0.04, abs=1e-9)
    assert z.max() - z.min() == pytest.approx(0.017, abs=1e-9)
    assert float(data[-1]["t"]) == pytest.approx(1.2)


def test_walk_csv(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "walk", "--steps", "1", "--rate", "50")
    assert code == 0
    data = rows(out)
    header = out.splitlines()[0].split(",")
    assert header[3:15] == list(load_config().robot.joint_names)
    assert len(header) == 3 + 12 + 12
    assert data[0]["kind"] == "start" and data[-1]["kind"] == "stop"
    first = [float(v) for v in list(data[0].values())[3:]]
    last = [float(v) for v in list(data[-1].values())[3:]]
    np.testing.assert_allclose(first, last, atol=1e-9)  # back to standing


@pytest.mark.parametrize("argv, fragment", [
    (["trajectory", "--rate", "abc"], "rate must be a number"),
    (["trajectory", "--rate", "nan"], "rate must be finite"),
    (["trajectory", "--leg", "xx"], "invalid choice"),
    (["trajectory", "--stride", "0.5"], "reachable is"),
    (["trajectory", "--swing-time", "0"], "must be > 0"),
    (["walk", "--steps", "0"], "must be >= 1"),
    (["walk", "--stride", "0.2"], "stride = 0.2 m is outside"),
    (["walk", "--gait", "gallop"], "gait 'gallop' unknown"),
    (["walk", "--config", "does-not-exist.yaml"], "cannot read config file"),
    (["nosuchcommand"], "invalid choice"),
])
def test_bad_options_one_line_error(argv: list[str], fragment: str) -> None:
    proc = subprocess.run([sys.executable, "-m", "crawler_motion.tools.cli", *argv],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode != 0
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert fragment in lines[0]


def _rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), the URDF convention."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def test_urdf_with_a_calibration_file_has_the_calibrated_joint_frames(
        capsys: pytest.CaptureFixture[str], tmp_path) -> None:
    import xml.etree.ElementTree as ET

    from crawler_motion.calibration.synthetic import perturbed_robot
    from crawler_motion.model.calibration_file import write_calibration
    from crawler_motion.model.leg_geometry import joint_frames

    robot = load_config().robot
    true = perturbed_robot(robot, 4)
    assert true.geometry is not None
    write_calibration(tmp_path / "legs.yaml", true.geometry)
    code, nominal, _ = run(capsys, "urdf")
    assert code == 0
    code, text, err = run(capsys, "urdf", "--calibration", str(tmp_path / "legs.yaml"))
    assert code == 0 and err == ""
    origins = {}
    for urdf in (nominal, text):
        for joint in ET.fromstring(urdf).iter("joint"):
            origin = joint.find("origin")
            assert origin is not None
            origins.setdefault(joint.get("name"), []).append(
                [np.array(origin.get(k, "0 0 0").split(), dtype=float) for k in ("xyz", "rpy")])
    for i, leg in enumerate(robot.legs):
        frames = joint_frames(true.geometry.params[i], robot.hips[i],
                              float(robot.neutral_yaw[i]))
        for j, kind in enumerate(("root", "shoulder", "knee")):
            (nominal_xyz, _), (xyz, rpy) = origins[f"{leg}_{kind}_joint"]
            np.testing.assert_allclose(xyz, frames.origins[j], atol=1e-15)
            np.testing.assert_allclose(_rpy_matrix(rpy), frames.rotations[j], atol=1e-12)
            if kind == "root":  # the hip error moves the root joint by up to ~0.9 mm
                assert 1e-5 < np.linalg.norm(xyz - nominal_xyz) < 2e-3
        np.testing.assert_allclose(origins[f"{leg}_foot_joint"][1][0], frames.foot_tip,
                                   atol=1e-15)


@pytest.mark.parametrize(("content", "fragment"), [
    (None, "cannot read calibration file"),
    ("calibration: {legs: {rf: {knee_offset: 0.2}}}", "knee_offset"),   # 11.5 deg: implausible
    ("calibration: {legs: {xx: {l1: 0.03}}}", "leg 'xx' does not exist"),
    ("calibration: {legs: {lf: {l1: .nan}}}", "must be a finite number"),
    ("calibration: [unclosed", "not valid YAML"),
])
def test_urdf_refuses_a_bad_calibration_file(capsys: pytest.CaptureFixture[str], tmp_path,
                                            content: str | None, fragment: str) -> None:
    path = tmp_path / "legs.yaml"
    if content is not None:
        path.write_text(content)
    out_file = tmp_path / "robot.urdf"
    code, out, err = run(capsys, "urdf", "--calibration", str(path), "-o", str(out_file))
    assert code == 1 and out == "" and not out_file.exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0] and lines[0].startswith("crawler-motion: ")


def test_urdf_and_plot(capsys: pytest.CaptureFixture[str], tmp_path) -> None:
    code, out, _ = run(capsys, "urdf")
    assert code == 0 and out.lstrip().startswith("<?xml") and "lf_knee_joint" in out
    code, out, _ = run(capsys, "plot", "--out", str(tmp_path))
    assert code == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["foot_path.png", "foot_profiles.png", "walk_joints.png"]
    assert all((tmp_path / n).stat().st_size > 10_000 for n in names)
