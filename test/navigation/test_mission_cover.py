"""The cover task (pure): which cells the tool can reach, the clean-up goal's spot and
tolerance, and a clean-up goal that ends when its cell is covered."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.navigation.apf_navigator import ApfNavigator
from crawler_motion.navigation.mission import parse_mission
from crawler_motion.navigation.mission_cover import (
    MIN_TOLERANCE,
    CoverageTracker,
    CoverTask,
    cover_field,
)
from crawler_motion.navigation.navigator import NavigatorSettings, NavState, TerrainView

RES = 0.05
DISC = 0.3  # the navigator's disc (virtual radius + margin) [m]
STANDOFF = NavigatorSettings().standoff
TOOL = 0.16


def wall_view() -> TerrainView:
    """A 4 m x 4 m known map of 0.05 m cells round the origin; a wall filling y >= 1.0."""
    n = 80
    origin = np.array([-2.0, -2.0])
    ys = origin[1] + (np.arange(n) + 0.5) * RES
    obstacle = np.repeat((ys >= 1.0)[:, None], n, axis=1)
    return TerrainView(origin, RES, np.ones((n, n), bool), obstacle, np.zeros((n, n)))


def cover_task(area: str = "[-0.5, -0.5, 0.5, 0.95]") -> CoverTask:
    task = parse_mission(f"tasks: [{{cover: {{area: {area}, spacing: 0.15}}}}]").tasks[0]
    return CoverTask(task, ApfNavigator(), TOOL, RES)


# the wall's face is at y = 1.0: the disc is ρ_o clear up to y = 1.0 - DISC - STANDOFF = 0.6,
# and the tool reaches cells up to half its width (0.08 m) beyond: centres up to y = 0.68
@pytest.mark.parametrize("y, reachable", [
    (0.575, True), (0.625, True), (0.675, True), (0.725, False), (0.925, False)])
def test_the_tool_reaches_cells_within_half_its_width_of_a_clear_point(y, reachable) -> None:
    view = wall_view()
    tracker = CoverageTracker(RES, TOOL)
    fld = cover_field(view, np.array([[0.0, 0.0]]), DISC, STANDOFF)
    square = [(-0.05, y - 0.01), (0.05, y - 0.01), (0.05, y + 0.01), (-0.05, y + 0.01)]
    cells = tracker.reachable(view, square, fld)
    assert (len(cells) == 2) is reachable, cells  # the two cells at x = -0.025, 0.025


@pytest.mark.parametrize("y, tolerance", [
    (0.475, NavigatorSettings().goal_tolerance),  # clear itself: the navigator's tolerance
    (0.625, None),  # 0.025 m beyond the clear line: the nearest clear point, tighter
    (0.675, MIN_TOLERANCE),  # 0.075 m beyond: the tightest
])
def test_a_cleanup_spot_is_clear_and_its_tolerance_covers_the_cell(y, tolerance) -> None:
    view = wall_view()
    task = cover_task()
    task._xy = np.array([0.0, 0.0])
    fld = cover_field(view, np.array([[0.0, 0.0]]), DISC, STANDOFF)
    cell = np.array([0.025, y])
    spot = task._spot(fld, cell)
    assert spot is not None
    point, tol = spot
    assert float(fld.clearance(point)[0]) >= STANDOFF - 1e-9
    gap = float(np.hypot(*(point - cell)))
    if tolerance is None:
        assert MIN_TOLERANCE < tol < NavigatorSettings().goal_tolerance
    else:
        assert tol == pytest.approx(tolerance)
    assert gap + tol <= TOOL / 2 or tol == MIN_TOLERANCE  # arriving covers the cell


def test_a_cleanup_goal_ends_when_its_cell_is_covered() -> None:
    view = wall_view()
    task = cover_task("[-0.1, 0.55, 0.1, 0.7]")
    task._slices_done = len(task._slices(task.task))  # the slices are walked: clean-up only
    task.mark(np.array([0.0, 0.3]))
    assert task.start(view, DISC, 0.0)
    cell, goal = task._cell, task.nav.goal
    assert cell is not None and goal is not None and task.nav.state is NavState.ACTIVE
    assert task.after(view, DISC, 1.0) and task.nav.goal is goal  # not covered yet: walk on
    task.mark(cell + np.array([0.0, -0.07]))  # within half the tool width: covered
    task.after(view, DISC, 2.0)
    assert task._cell is None or not np.array_equal(task._cell, cell)
    assert task.skipped == 0


def test_a_cleanup_goal_not_covering_its_cell_in_time_is_given_up() -> None:
    view = wall_view()
    task = cover_task("[-0.1, 0.55, 0.1, 0.7]")
    task._slices_done = len(task._slices(task.task))
    task.mark(np.array([0.0, 0.3]))
    assert task.start(view, DISC, 0.0)
    first = task._cell
    assert first is not None
    task.after(view, DISC, 31.0)  # past CLEANUP_LIMIT
    assert task.skipped == 1
    assert task._cell is None or not np.array_equal(task._cell, first)


def test_goals_failing_in_a_row_from_one_place_fail_the_task() -> None:
    view = wall_view()
    task = cover_task()
    task.mark(np.array([0.0, 0.0]))
    assert task.start(view, DISC, 0.0)
    for k in range(3):
        assert task.failed is None
        task.nav.fail("start (0, 0) is inside an obstacle")
        more = task.after(view, DISC, 1.0 + k)
        task.mark(np.array([0.01 * (k + 1), 0.0]))  # within STUCK_DISTANCE
    assert not more and task.failed is not None
    assert task.failed.startswith("3 goals in a row failed from") and "inside" in task.failed
    assert task.skipped == 2


def test_failed_goals_from_different_places_are_skipped_not_fatal() -> None:
    view = wall_view()
    task = cover_task()
    task.mark(np.array([0.0, 0.0]))
    assert task.start(view, DISC, 0.0)
    for k in range(4):
        task.nav.fail("trapped")
        assert task.after(view, DISC, 1.0 + k)
        task.mark(np.array([0.1 * (k + 1), 0.0]))  # the body moved on between failures
    assert task.failed is None and task.skipped == 4
