"""``crawler-motion rough``: the closed-loop walk's figures, JSON, and one-line errors."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("mujoco", reason="the seabed simulator needs the mujoco package")

from crawler_motion.tools import cli


def test_a_closed_loop_walk_prints_its_figures(capsys: pytest.CaptureFixture[str]) -> None:
    code = cli.main(["rough", "--gait", "diagonal", "--steps", "1", "--world", "flat",
                     "--foothold-adapt", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    figures = json.loads(out)
    assert figures["state"] == "STANDING"
    assert 0.9 < figures["advance_ratio"] < 1.1
    assert set(figures) == {"advance_ratio", "roll_max", "pitch_max", "yaw_per_cycle",
                            "torque_max", "state", "events"}
    assert "s of walk in" in err


@pytest.mark.parametrize(("argv", "message"), [
    (["--world", "no_such_world"], "crawler-motion rough: error: world file no_such_world"),
    (["--attitude", "level"], "argument --attitude: invalid choice: 'level'"),
    (["--steps", "0"], "argument --steps"),
])
def test_bad_input_is_one_line(capsys: pytest.CaptureFixture[str], argv: list[str],
                               message: str) -> None:
    try:
        code = cli.main(["rough", *argv])
    except SystemExit as exc:
        code = int(exc.code or 0)
    _, err = capsys.readouterr()
    assert code in (1, 2)
    assert message in err and len(err.strip().splitlines()) == 1
