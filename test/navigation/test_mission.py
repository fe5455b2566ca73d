"""Mission files (the checks, as a table) and the mission runner in a kinematic closed loop:
the `apf` navigator's twists move a point robot on a known map, every task kind in order."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.navigation.apf_navigator import ApfNavigator
from crawler_motion.navigation.mission import TaskKind, parse_mission
from crawler_motion.navigation.mission_cover import CoverageTracker, inside_polygon
from crawler_motion.navigation.mission_runner import MissionRunner, MissionState, home_goal
from crawler_motion.navigation.navigator import NavigatorSettings, NavState, TerrainView

EXAMPLE = Path(__file__).resolve().parents[2] / "config" / "missions" / "harbour.yaml"


def test_the_shipped_example_uses_every_task_kind() -> None:
    mission = parse_mission(EXAMPLE.read_text())
    assert {t.kind for t in mission.tasks} == set(TaskKind)


def test_the_issue_example_parses_as_written() -> None:
    mission = parse_mission("""
tasks:
  - goto: {x: 1.0, y: 0.0}
  - follow: {side: left, length: 1.5, standoff: 0.15}
  - cover: {area: [0.5, -1.0, 2.5, 1.0], spacing: 0.25}
  - home: {}
""")
    assert [t.kind.value for t in mission.tasks] == ["goto", "follow", "cover", "home"]
    assert mission.tasks[2].polygon == [(0.5, -1.0), (2.5, -1.0), (2.5, 1.0), (0.5, 1.0)]
    assert mission.tasks[1].values == {"length": 1.5, "side": "left", "standoff": 0.15}


@pytest.mark.parametrize("text, words", [
    ("tasks: [", "not valid YAML"),
    ("- goto: {x: 1, y: 0}", "a mapping with the key tasks"),
    ("tasks: []", "1 to 100 tasks"),
    ("tasks: [{fly: {}}]", "task 1: unknown task 'fly'"),
    ("tasks: [{goto: {x: 1}}]", "task 1 (goto): missing keys ['y']"),
    ("tasks: [{goto: {x: 1, y: 0, z: 2}}]", "unknown keys ['z']"),
    ("tasks: [{goto: {x: .nan, y: 0}}]", "task 1 (goto) x must be a finite number"),
    ("tasks: [{goto: {x: 1e9, y: 0}}]", "in [-1000, 1000]"),
    ("tasks: [{goto: {x: yes, y: 0}}]", "must be a number"),
    ("tasks: [{home: {}}, {follow: {length: 1, side: up}}]", "task 2 (follow) side"),
    ("tasks: [{cover: {spacing: 0.2}}]", "exactly one of area"),
    ("tasks: [{cover: {spacing: 0.2, area: [1, 0, 0, 1]}}]", "x1 > x0"),
    ("tasks: [{cover: {spacing: 0.2, polygon: [[0, 0], [1, 1]]}}]", "3 to 100 points"),
    ("tasks: [{goto: {x: 1, y: 0, timeout: 0}}]", "timeout must be"),
    ("tasks: [{goto: [1, 0]}]", "takes a mapping"),
    ("[" * 100000, "at most 65536 characters"),
    ("tasks: " + "[" * 5000, "not valid YAML"),
])
def test_bad_missions_say_what_is_wrong(text: str, words: str) -> None:
    with pytest.raises(CommandError, match=None) as exc:
        parse_mission(text)
    assert words in str(exc.value), str(exc.value)


def test_inside_polygon_and_the_tracker() -> None:
    square = [(0, 0), (1, 0), (1, 1), (0, 1)]
    pts = np.array([[0.5, 0.5], [1.5, 0.5], [-0.1, 0.2], [0.99, 0.01]])
    assert inside_polygon(pts, square).tolist() == [True, False, False, True]
    tracker = CoverageTracker(0.05, 0.2)
    tracker.mark(np.array([0.5, 0.5]))
    assert 10 <= len(tracker.cells) <= 16  # cells within 0.1 m of the point: a disc of ~12


def flat_view(obstacles: list[tuple[float, float, float, float]]) -> TerrainView:
    """A 6 m x 6 m known map of 0.05 m cells around the origin with box obstacles."""
    n, res = 120, 0.05
    origin = np.array([-3.0, -3.0])
    xs = origin[0] + (np.arange(n) + 0.5) * res
    gx, gy = np.meshgrid(xs, xs)
    obstacle = np.zeros((n, n), dtype=bool)
    for x0, x1, y0, y1 in obstacles:
        obstacle |= (gx >= x0) & (gx <= x1) & (gy >= y0) & (gy <= y1)
    return TerrainView(origin, res, np.ones((n, n), dtype=bool), obstacle, np.zeros((n, n)))


def walk(runner: MissionRunner, view: TerrainView, limit: float = 400.0) -> np.ndarray:
    """Kinematic closed loop at 10 Hz: the twist moves the body (no dynamics)."""
    pose = np.array([0.0, 0.0, 0.0])
    t, path = 0.0, [pose[:2].copy()]
    radius = 0.215
    while runner.state is MissionState.RUNNING and t < limit:
        runner.before(tuple(pose), view, radius + runner.nav.settings.margin, t)
        out = runner.nav.step(tuple(pose), radius, view, t)
        runner.after(view, radius + runner.nav.settings.margin, t)
        if out.twist is not None and runner.nav.state is NavState.ACTIVE:
            vx, vy, wz = out.twist
            c, s = math.cos(pose[2]), math.sin(pose[2])
            pose += 0.1 * np.array([c * vx - s * vy, s * vx + c * vy, wz])
        t += 0.1
        path.append(pose[:2].copy())
    return np.array(path)


def test_a_mission_of_every_kind_runs_to_the_end() -> None:
    wall = (-0.5, 2.5, 0.5, 0.6)
    box = (1.2, 1.4, -0.9, -0.7)  # inside the cover area
    view = flat_view([wall, box])
    mission = parse_mission("""
id: kinematic
tasks:
  - goto: {x: 0.3, y: 0.0}
  - follow: {side: left, length: 0.6, standoff: 0.1}
  - cover: {area: [0.8, -1.2, 1.8, -0.4], spacing: 0.2}
  - home: {}
""")
    nav = ApfNavigator(NavigatorSettings(standoff=0.05))
    runner = MissionRunner(mission, nav, np.zeros(2), 0.0, tool_width=0.2)
    path = walk(runner, view)
    status = runner.status()
    assert status["state"] == "DONE", status
    assert status["task_index"] == 4 and status["mission"] == "kinematic"
    assert np.hypot(*path[-1]) <= 0.06  # home
    assert runner.covered is not None and runner.covered >= 0.9, status
    assert nav.settings.standoff == 0.05  # the follow's stand-off was the task's only
    # the body never entered an obstacle
    for x0, x1, y0, y1 in (wall, box):
        inside = (path[:, 0] > x0) & (path[:, 0] < x1) & (path[:, 1] > y0) & (path[:, 1] < y1)
        assert not inside.any()


def test_a_failing_task_fails_the_mission_and_the_rest_does_not_run() -> None:
    view = flat_view([(0.9, 1.1, -0.1, 0.1)])
    mission = parse_mission("tasks: [{goto: {x: 1.0, y: 0.0}}, {home: {}}]")
    runner = MissionRunner(mission, ApfNavigator(NavigatorSettings()), np.zeros(2), 0.0, 0.2)
    walk(runner, view, limit=30.0)
    status = runner.status()
    assert status["state"] == "FAILED" and status["task_index"] == 1, status
    assert "task 1 (goto)" in status["reason"]


def test_a_task_timeout_fails_the_mission() -> None:
    mission = parse_mission("tasks: [{goto: {x: 2.0, y: 0.0, timeout: 2}}]")
    runner = MissionRunner(mission, ApfNavigator(NavigatorSettings()), np.zeros(2), 0.0, 0.2)
    walk(runner, flat_view([]), limit=10.0)
    assert runner.state is MissionState.FAILED and "within 2 s" in runner.reason


def test_cancel_ends_the_mission_and_the_goal() -> None:
    mission = parse_mission("tasks: [{goto: {x: 2.0, y: 0.0}}]")
    nav = ApfNavigator(NavigatorSettings())
    runner = MissionRunner(mission, nav, np.zeros(2), 0.0, 0.2)
    runner.before((0.0, 0.0, 0.0), flat_view([]), 0.3, 0.0)
    assert nav.state is NavState.ACTIVE
    runner.cancel()
    assert runner.state is MissionState.CANCELLED and nav.state is NavState.IDLE


# a wall whose face is x = 1.0; the disc (0.3 m) is clear for x < 0.7 and clear by the
# stand-off (0.1 m) for x <= 0.6; home_goal looks no farther than the disc's radius
@pytest.mark.parametrize("start_x, home_x", [
    (0.5, 0.5),  # clear by more than the stand-off: home itself
    (0.59, 0.59),  # clear by 0.11 m: still itself
    (0.65, 0.6),  # clear by 0.05 m, within the stand-off: the nearest point clear by it
    (0.75, 0.6),  # the disc overlaps by 0.05 m
    (0.89, 0.6),  # by 0.19 m: 0.29 m away, within the disc's radius
    (0.95, 0.95),  # 0.35 m away: nothing within 0.3 m; itself (the navigator refuses it)
])
def test_home_is_the_nearest_clear_point_when_the_start_now_is_not(start_x, home_x) -> None:
    view = flat_view([(1.0, 3.0, -3.0, 3.0)])
    home, note = home_goal(view, 0.3, 0.1, np.array([start_x, 0.0]))
    assert home == pytest.approx([home_x, 0.0], abs=0.0126)  # on a grid of a quarter cell
    assert home[0] <= 0.6 + 1e-9 or home_x == start_x
    assert bool(note) is (home_x != start_x), note


def test_a_home_task_walks_to_the_shifted_home_and_says_so() -> None:
    view = flat_view([(1.0, 3.0, -3.0, 3.0)])
    mission = parse_mission("tasks: [{home: {}}]")
    nav = ApfNavigator(NavigatorSettings())
    disc = 0.215 + nav.settings.margin  # as in walk()
    runner = MissionRunner(mission, nav, np.array([0.85, 0.0]), 0.0, 0.2)
    runner.before((0.0, 0.0, 0.0), view, disc, 0.0)
    assert nav.goal is not None and 0.57 <= nav.goal[0] <= 0.585, nav.goal
    assert "nearer an obstacle than the disc" in runner.status()["reason"]
    walk(runner, view, limit=60.0)
    assert runner.state is MissionState.DONE, runner.status()
