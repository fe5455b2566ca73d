"""``crawler-motion calibrate`` / ``fk``: the loop end to end, and bad input: one line, exit 1,
nothing written."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from crawler_motion.tools import calibrate, fk

POSES = "q_root,q_shoulder,q_knee\n" + "".join(
    f"{r:.6f},{s:.6f},{k:.6f}\n" for r, s, k in
    np.random.default_rng(0).uniform([-0.8, -0.9, 0.2], [0.8, 1.3, 2.0], (30, 3)))


def test_simulate_identify_fk_loop(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "p.csv").write_text(POSES)
    assert calibrate.main(["simulate", "--leg", "rb", "--poses", str(tmp_path / "p.csv"),
                           "--perturb-seed", "2", "--write-true", str(tmp_path / "t.yaml")]) == 0
    (tmp_path / "f.csv").write_text(capsys.readouterr().out)
    out = tmp_path / "c.yaml"
    assert calibrate.main(["identify", "--leg", "rb", "--poses", str(tmp_path / "p.csv"),
                           "--measured", str(tmp_path / "f.csv"), "--out", str(out)]) == 0
    table = capsys.readouterr().out
    assert "| rls-de |" in table and "fixed at their current value" in table
    monkeypatch.setattr("sys.stdin", (tmp_path / "p.csv").open())
    assert fk.main(["--leg", "rb", "--calibration", str(out)]) == 0
    got = np.loadtxt(capsys.readouterr().out.splitlines()[1:], delimiter=",")
    want = np.loadtxt((tmp_path / "f.csv").read_text().splitlines()[1:], delimiter=",")
    assert np.abs(got - want).max() < 1e-9


@pytest.mark.parametrize(("poses", "feet", "leg", "message"), [
    (POSES, "x,y,z\n0.1,0.1,0.0\n", "lf", "30 poses but 1 measured"),
    (POSES.replace("\n", "\nabc,1,2\n", 2), None, "lf", "not a number"),
    (POSES.replace("\n", "\nnan,1,2\n", 2), None, "lf", "NaN"),
    ("q_root,q_shoulder,q_knee\n0.0,0.0,2.7\n", None, "lf", "outside the joint limits"),
    ("q_root,q_shoulder,q_knee\n0,0,1\n0.1,0.2,1.1\n", "x,y,z\n0,0,0\n0,0,0\n", "lf",
     "2 poses, fewer than its 15"),
    (POSES, None, "zz", "does not exist"),
])
def test_bad_input_one_line_exit_1_nothing_written(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], poses: str, feet: str | None,
        leg: str, message: str) -> None:
    (tmp_path / "p.csv").write_text(poses)
    (tmp_path / "f.csv").write_text(feet or "x,y,z\n" + "0.1,0.1,0\n" * poses.count("\n"))
    out = tmp_path / "c.yaml"
    assert calibrate.main(["identify", "--leg", leg, "--poses", str(tmp_path / "p.csv"),
                           "--measured", str(tmp_path / "f.csv"), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


def test_identify_starts_from_the_given_calibration(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "p.csv").write_text(POSES)
    assert calibrate.main(["simulate", "--leg", "lf", "--poses", str(tmp_path / "p.csv"),
                           "--perturb-seed", "4", "--write-true", str(tmp_path / "t.yaml")]) == 0
    (tmp_path / "f.csv").write_text(capsys.readouterr().out)
    rows = {}
    for start in (None, str(tmp_path / "t.yaml")):
        extra = [] if start is None else ["--calibration", start]
        assert calibrate.main(["identify", "--leg", "lf", "--poses", str(tmp_path / "p.csv"),
                               "--measured", str(tmp_path / "f.csv"), "--method", "rls",
                               "--out", str(tmp_path / "c.yaml"), *extra]) == 0
        before = next(line for line in capsys.readouterr().out.splitlines()
                      if line.startswith("| before |"))
        rows[start is None] = float(before.split("|")[2])  # mean [mm]
    assert rows[True] > 0.3 and rows[False] < 1e-6  # nominal start vs the true geometry


@pytest.mark.parametrize("tool", ["fk", "poses", "identify"])
def test_implausible_calibration_option_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        tool: str) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("calibration: {legs: {lf: {l2: 0.07}}}")
    (tmp_path / "p.csv").write_text(POSES)
    (tmp_path / "f.csv").write_text("x,y,z\n" + "0.1,0.1,0\n" * 30)
    monkeypatch.setattr("sys.stdin", (tmp_path / "p.csv").open())
    argv = {"fk": ["--leg", "lf"], "poses": ["poses", "--leg", "lf"],
            "identify": ["identify", "--leg", "lf", "--poses", str(tmp_path / "p.csv"),
                         "--measured", str(tmp_path / "f.csv"), "--out",
                         str(tmp_path / "c.yaml")]}[tool]
    main = fk.main if tool == "fk" else calibrate.main
    assert main([*argv, "--calibration", str(bad)]) == 1
    captured = capsys.readouterr()
    assert "more than 10%" in captured.err and captured.err.count("\n") == 1
    assert captured.out == "" and not (tmp_path / "c.yaml").exists()


def _session(tmp_path: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> Path:
    """A simulated session of every leg (30 poses each), written as a --measurements file."""
    (tmp_path / "p.csv").write_text(POSES)
    assert calibrate.main(["simulate", "--leg", "all", "--poses", str(tmp_path / "p.csv"),
                           "--perturb-seed", "5", "--write-true", str(tmp_path / "t.yaml"),
                           *extra]) == 0
    path = tmp_path / "m.csv"
    path.write_text(capsys.readouterr().out)
    return path


@pytest.mark.parametrize("frame", ["body", "tracker"])
def test_session_identify_recovers_every_leg(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             monkeypatch: pytest.MonkeyPatch,
                                             frame: str) -> None:
    extra = ["--tracker", "1.5", "-0.7", "0.4", "0.3", "-0.2", "2.0"] if frame == "tracker" else []
    measurements = _session(tmp_path, capsys, *extra)
    out = tmp_path / "c.yaml"
    assert calibrate.main(["identify", "--measurements", str(measurements), "--frame", frame,
                           "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "condition number" in text and "outliers: none" in text
    assert ("tracker pose in base_link" in text) == (frame == "tracker")
    assert ("6 combinations of hip_x" in text) == (frame == "tracker")
    if frame == "tracker":  # the tracker's pose, in the frame the legs' roots define
        assert "t = [1.5" in text or "t = [1.4" in text
    monkeypatch.setattr("sys.stdin", (tmp_path / "p.csv").open())
    assert fk.main(["--leg", "rb", "--calibration", str(out)]) == 0
    got = np.loadtxt(capsys.readouterr().out.splitlines()[1:], delimiter=",")
    monkeypatch.setattr("sys.stdin", (tmp_path / "p.csv").open())
    assert fk.main(["--leg", "rb", "--calibration", str(tmp_path / "t.yaml")]) == 0
    want = np.loadtxt(capsys.readouterr().out.splitlines()[1:], delimiter=",")
    assert np.abs(got - want).max() < (1e-9 if frame == "body" else 2e-3)


def test_session_outliers_are_reported_by_line(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    measurements = _session(tmp_path, capsys, "--noise", "2e-5")
    lines = measurements.read_text().splitlines()
    for number in (5, 40, 77):  # file lines (the header is line 1)
        cells = lines[number - 1].split(",")
        cells[4] = f"{float(cells[4]) + 0.01:.9f}"
        lines[number - 1] = ",".join(cells)
    measurements.write_text("\n".join(lines) + "\n")
    assert calibrate.main(["identify", "--measurements", str(measurements), "--out",
                           str(tmp_path / "c.yaml")]) == 0
    text = capsys.readouterr().out
    assert "outliers, excluded" in text
    assert [int(n) for n in re.findall(r"line (\d+) \(", text)] == [5, 40, 77]


GOOD = "leg,q_root,q_shoulder,q_knee,x,y,z\n"


@pytest.mark.parametrize(("body", "frame", "message"), [
    ("leg,q_root,q_shoulder,x,y,z\nlf,0,0,0,0\n", "body", "line 1: the header must name"),
    (GOOD + "lf,0.1,0.2,nan,0.1,0.1,0\n", "body", "line 2: NaN"),
    (GOOD + "lf,0.1,0.2,1.0,0.1,0.1\n", "body", "line 2: expected 7 values"),
    (GOOD + "zz,0.1,0.2,1.0,0.1,0.1,0\n", "body", "line 2: leg 'zz' does not exist"),
    (GOOD + "lf,0.1,0.2,2.7,0.1,0.1,0\n", "body", "line 2: pose outside the joint limits"),
    (GOOD + "lf,0.1,0.2,1.0,0.1,0.1,0\nlf,0.1,0.2,1.0,0.1,0.1,0\n", "body",
     "line 3: duplicate row"),
    (GOOD + "lf,0.1,0.2,1.0,0.1,0.1,0\n", "body", "1 poses, fewer than its 15"),
    ("tracker", "body", "implausible calibration: hip_x"),
    ("moved", "tracker", "the readings do not fit one model"),
    (GOOD, "tracker", "no readings"),
])
def test_session_bad_input_one_line_exit_1_nothing_written(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], body: str, frame: str,
        message: str) -> None:
    if body == "tracker":  # readings in a tracker's frame, identified as if in base_link
        path = _session(tmp_path, capsys, "--tracker", "1.5", "0", "0", "0", "0", "1.0")
    elif body == "moved":  # the tracker moved by 5 mm, every other reading after the move
        runs = [_session(tmp_path, capsys, "--tracker", x, "0", "0", "0", "0", "1.0")
                .read_text().splitlines() for x in ("1.5", "1.505")]
        path = tmp_path / "m.csv"
        path.write_text("\n".join(runs[n % 2][n] for n in range(len(runs[0]))) + "\n")
    else:
        path = tmp_path / "m.csv"
        path.write_text(body)
    out = tmp_path / "c.yaml"
    assert calibrate.main(["identify", "--measurements", str(path), "--frame", frame,
                           "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()
