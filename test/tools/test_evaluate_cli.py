"""``crawler-motion evaluate``: the walk options, JSON and table output, one-line errors."""

from __future__ import annotations

import json
import math

import pytest

from crawler_motion.motion.walk_options import OPTIONS
from crawler_motion.tools import cli

#: The figures the issue asks for, as keys of the JSON summary and of every cycle.
METRICS = (
    "advance_ratio", "planned_advance", "advance",  # advance vs the no-slip plan
    "lateral_drift", "yaw_drift",  # drifts
    "turn_ratio", "planned_turn", "turn",  # turn achieved vs commanded
    "slip_mean", "slip_max",  # loaded foot slip
    "stance_displacement", "centre_travel", "stance_contact_loss", "midswing_contact",
    "roll_max", "pitch_max", "height_variation", "body_contact", "torque_p99",
)


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(["evaluate", "--steps", "2", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_every_walk_flag_of_walk_is_accepted() -> None:
    sub = cli.build_parser()._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    flags = {name: set(sub[name]._option_string_actions) for name in ("walk", "evaluate")}
    walk_flags = {OPTIONS[name].flag for name in (*cli.WALK_FIELDS, "steps")}
    assert walk_flags <= flags["walk"] and walk_flags <= flags["evaluate"]
    assert flags["evaluate"] - flags["walk"] == {"--world", "--medium", "--json"}


def test_json_has_every_metric(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "--json", "--gait", "diagonal")
    assert code == 0
    data = json.loads(out)
    assert data["medium"] == "water" and data["world"].endswith("flat.xml")
    assert data["steps"] == 2 and len(data["cycles"]) == 2
    assert data["params"]["gait"] == "diagonal"
    for cycle in (data["summary"], *data["cycles"]):
        assert set(METRICS) <= set(cycle)
    summary = data["summary"]
    assert 0.9 <= summary["advance_ratio"] <= 1.1
    assert summary["turn_ratio"] is None  # a straight walk has no turn to compare
    assert all(math.isfinite(summary[k]) for k in METRICS if k != "turn_ratio")
    assert data["speedup"] > 1.0
    assert err.startswith("evaluate: ") and "x real time" in err and len(err.splitlines()) == 1


def test_table_prints_one_row(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "--gait", "wave", "--world", "relief")
    assert code == 0
    lines = out.splitlines()
    assert len(lines) == 3
    assert lines[0].split("|")[0].strip() == "walk" and "adv" in lines[0]
    assert set(lines[1]) == {"-"}
    assert lines[2].split("|")[0].strip() == "wave water relief"
    assert 0.5 < float(lines[2].split("|")[1]) < 1.5
    assert "x real time" in err


def test_land_medium(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--json", "--medium", "land")
    assert code == 0
    data = json.loads(out)
    assert data["medium"] == "land"
    assert 0.9 <= data["summary"]["advance_ratio"] <= 1.1


@pytest.mark.parametrize(("text", "problem"), [
    ("<mujoco><worldbody>", "not valid XML"),
    ("<mujoco><worldbody/></mujoco>", "found 0"),
    ('<mujoco><asset><hfield name="h" file="gone.png"/></asset><worldbody>'
     '<geom name="seabed" type="plane" size="1 1 1"/></worldbody></mujoco>', "gone.png"),
    (None, "cannot read it"),
])
def test_bad_world_is_refused_in_one_line(capsys: pytest.CaptureFixture[str], tmp_path,
                                          text: str | None, problem: str) -> None:
    path = tmp_path / "bad_world.xml"
    if text is not None:
        path.write_text(text, encoding="utf-8")
    code, out, err = run(capsys, "--world", str(path))
    assert code == 1 and out == ""
    assert len(err.splitlines()) == 1
    assert err.startswith(f"crawler-motion: error: world file {path}: ")
    assert problem in err


def test_bad_medium_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        run(capsys, "--medium", "air")
    assert exc.value.code == 2
    assert "--medium" in capsys.readouterr().err
