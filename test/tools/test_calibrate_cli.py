"""``crawler-motion calibrate`` / ``fk``: the loop end to end, and bad input: one line, exit 1,
nothing written."""

from __future__ import annotations

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
