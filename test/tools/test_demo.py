"""Tests of crawler_motion.tools.demo without processes: options, odom track, advance line."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from crawler_motion.model.config import load_config
from crawler_motion.tools.demo import BodyTrack, advance_line, parse_args, planned_advance


def _odom(x: float, y: float, yaw: float) -> SimpleNamespace:
    q = SimpleNamespace(w=math.cos(yaw / 2), x=0.0, y=0.0, z=math.sin(yaw / 2))
    return SimpleNamespace(pose=SimpleNamespace(pose=SimpleNamespace(
        position=SimpleNamespace(x=x, y=y, z=0.1), orientation=q)))


def test_defaults_are_the_physical_walk_in_water_on_the_flat_world() -> None:
    args = parse_args([])
    assert (args.sim, args.world, args.medium, args.out, args.steps) == (
        "seabed", "flat", "water", Path("plots"), 3)
    assert parse_args(["--sim", "joint"]).sim == "joint"


@pytest.mark.parametrize("argv", [["--sim", "physics"], ["--medium", "air"], ["--steps", "0"]])
def test_bad_options_are_refused(argv: list[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        parse_args(argv)
    assert exc.value.code == 2


@pytest.mark.parametrize(("start", "end", "moved"), [
    ((0.0, 0.0, 0.0), (0.1, 0.0, 0.0), (0.1, 0.0)),
    ((1.0, 2.0, math.pi / 2), (1.0, 2.1, math.pi / 2), (0.1, 0.0)),  # heading +y: forward
    ((0.0, 0.0, math.pi / 2), (0.1, 0.0, math.pi / 2), (0.0, -0.1)),  # +x is to the right
    ((0.0, 0.0, math.pi), (-0.2, 0.05, math.pi), (0.2, -0.05)),
])
def test_the_advance_is_measured_in_the_body_frame_at_the_start(start, end, moved) -> None:
    body = BodyTrack()
    body.on_odom(_odom(*start))
    body.mark()
    body.on_odom(_odom(*end))
    assert body.moved() == pytest.approx(np.array(moved), abs=1e-12)


def test_no_odom_is_an_error() -> None:
    body = BodyTrack()
    body.mark()
    with pytest.raises(RuntimeError, match="no odom"):
        body.moved()


def test_planned_advance_and_its_line() -> None:
    pytest.importorskip("mujoco")
    planned = planned_advance(parse_args(["--steps", "3"]))
    gait = load_config().gait  # two half steps + 3 cycles of two strides: 7 strides
    assert planned == pytest.approx([7 * gait.stride_of(gait.gait), 0.0], abs=1e-9)
    line = advance_line(np.array([0.4109, -0.0029]), np.array([0.42, 0.0]))
    assert line == ("  body advance          410.9 mm of 420.0 mm planned without slip "
                    "(0.98), -2.9 mm left (odom)")
    assert "(nan)" in advance_line(np.array([0.0, 0.0]), np.array([0.0, 0.0]))
    # along the planned direction: sideways to the left, the body 3 mm behind the plan's line
    line = advance_line(np.array([-0.003, 0.33]), np.array([0.0, 0.35]))
    assert line == ("  body advance          330.0 mm of 350.0 mm planned without slip "
                    "(0.94), +3.0 mm left (odom)")
    sideways = planned_advance(parse_args(["--steps", "1", "--heading", str(math.pi / 2)]))
    assert sideways == pytest.approx([0.0, 3 * gait.stride_of(gait.gait)], abs=1e-9)
