"""``crawler-motion pose`` and the console's ``pose``: flags from the one option table."""

from __future__ import annotations

import csv
import io
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.model.rotations import rpy_matrix
from crawler_motion.motion.body_pose import POSE_FIELDS
from crawler_motion.tools import cli
from crawler_motion.tools.console import Console, build_parser, command_from_args, describe

CFG = load_config()
ROBOT = CFG.robot


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_the_pose_move_as_csv_keeps_the_feet_fixed(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "pose", "--x", "0.02", "--yaw", "-0.1", "--rate", "50")
    assert code == 0 and err == ""
    data = list(csv.DictReader(io.StringIO(out)))
    assert list(data[0])[:7] == ["t", *POSE_FIELDS]
    assert float(data[-1]["t"]) == pytest.approx(1.875 * 0.02 / 0.03)  # the speed limit
    assert (float(data[-1]["x"]), float(data[-1]["yaw"])) == pytest.approx((0.02, -0.1))
    for row in data:
        q = np.array([float(row[name]) for name in ROBOT.joint_names]).reshape(4, 3)
        pose = np.array([float(row[name]) for name in POSE_FIELDS])
        world = forward_kinematics(ROBOT, q) @ rpy_matrix(pose[3:]).T + pose[:3]
        np.testing.assert_allclose(world, ROBOT.standing_feet(), atol=1e-8)  # CSV rounding


@pytest.mark.parametrize(("argv", "message"), [
    (("--roll", "0.3"), "roll = 0.3 rad is outside [-0.2, 0.2] rad"),
    (("--y", "0.03", "--z", "0.02"), "a foot would leave its workspace: leg rb:"),
    (("--body-height", "0.1"), "body height 0.1 m is outside the allowed [0.05, 0.09] m"),
])
def test_a_pose_out_of_reach_is_one_line_and_exit_1(capsys, argv, message) -> None:
    code, out, err = run(capsys, "pose", *argv)
    assert code == 1 and out == ""
    assert err.startswith("crawler-motion pose: error: ") and message in err
    assert err.count("\n") == 1


def test_a_bad_flag_value_is_argparse_s_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main(["pose", "--pitch", "nan"])
    assert exc.value.code == 2 and "pitch" in capsys.readouterr().err


def test_the_console_sends_the_pose_keys_it_was_given() -> None:
    args = build_parser().parse_args(["pose", "--x", "0.01", "--roll", "-0.05"])
    assert command_from_args(args) == {"command": "pose", "x": 0.01, "roll": -0.05}
    args = build_parser().parse_args(["pose"])
    assert command_from_args(args) == {"command": "pose"}  # neutral


@pytest.mark.parametrize(("status", "line"), [
    ({"state": "STANDING", "body_pose": {"x": 0.01, "y": 0.0, "roll": -0.05}},
     "STANDING (pose x 0.01 m, roll -0.05 rad)"),
    ({"state": "STANDING", "body_pose": {"x": 0.0, "yaw": 0.0}}, "STANDING"),
    ({"state": "SITTING", "body_pose": {"x": 0.01}}, "SITTING"),
    ({"state": "MOVING", "body_pose": {"z": "junk", "pitch": 0.1}}, "MOVING (pose pitch 0.1 rad)"),
])
def test_the_console_shows_the_body_pose(status, line) -> None:
    assert describe(status) == line


class ScriptedConsole(Console):
    """A `Console` without ROS: each spin delivers the next planner status of a script."""

    def __init__(self, statuses: list[dict[str, Any]]) -> None:  # no node
        self.status = {"state": "STANDING", "revision": 0, "refusals": 0}
        self._script = iter(statuses)
        self.sent = 0

    def send(self, command: dict[str, Any]) -> None:
        self.sent += 1

    def spin_for(self, seconds: float) -> None:
        pass

    def wait_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        for status in self._script:
            self.status = status
            if predicate():
                return True
        return predicate()


def _status(revision: int, state: str, resuming: bool = False, x: float = 0.0,
            event: str | None = None, interruptions: int = 0) -> dict[str, Any]:
    return {"state": state, "revision": revision, "refusals": 0, "resuming": resuming,
            "body_pose": {"x": x}, "last_event": event, "interruptions": interruptions}


@pytest.mark.parametrize(("script", "ok", "words"), [
    ([_status(1, "MOVING"), _status(2, "MOVING", x=0.01), _status(3, "STANDING", x=0.02)],
     True, "STANDING (pose x 0.02 m)"),
    # starved: the move ends where it was, STANDING at a part of the pose, a resume due
    ([_status(1, "MOVING"), _status(2, "STANDING", True, 1e-4, "no tick", 1)],
     False, "interrupted (no tick); the pose move stopped at STANDING (pose x 0.0001 m): "
            "send the pose again"),
    # the statuses of the interruption and its resume were missed (newest only): the count
    ([_status(1, "MOVING"), _status(3, "STANDING", x=1e-3, event="resumed", interruptions=1)],
     False, "interrupted (resumed)"),
])
def test_the_console_says_when_a_pose_move_was_interrupted(script, ok, words) -> None:
    result = ScriptedConsole(script).run({"command": "pose", "x": 0.02}, 1.0)
    assert result[0] is ok and words in result[1], result


def _refused(revision: int, refusals: int, why: str) -> dict[str, Any]:
    return {"state": "STANDING", "revision": revision, "refusals": refusals,
            "resuming": True, "last_refusal": why}


@pytest.mark.parametrize(("why", "sent"), [
    ("walk refused: resuming from the measured pose; retry when it is done", 2),
    ("walk refused in state MOVING: a resume after pause: x move is in progress; wait", 2),
    ("walk refused: paused: motor manager fault; retry when it clears", 2),
    ("walk refused: the body is posed: send stand first", 1),  # not transient: said once
])
def test_a_scripted_walk_waits_out_a_resume_but_not_a_real_refusal(why, sent) -> None:
    console = ScriptedConsole([_refused(1, 1, why), {**_refused(2, 1, why), "resuming": False},
                               _status(3, "WALKING"), _status(4, "STANDING")])
    ok, message = console.run_when_ready({"command": "walk", "steps": 1}, 1.0)
    assert console.sent == sent and ok is (sent == 2), message
