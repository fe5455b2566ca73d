"""Paths on the improved field: the local-minimum test, virtual-goal geometry, the U trap with
and without virtual goals, stand-off following, coverage, bad points."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.navigation.apf.coverage import cover
from crawler_motion.navigation.apf.field import FieldSettings, ObstacleField
from crawler_motion.navigation.apf.maps import TWO_OBSTACLES, U_TRAP, box_grid
from crawler_motion.navigation.apf.planner import (
    ApfMethod,
    PlanSettings,
    follow,
    min_clearance,
    open_line,
    plan,
)
from crawler_motion.navigation.apf.virtual import place_virtual_goal, trapped
from crawler_motion.navigation.navigator import TerrainView
from crawler_motion.testing.avoidance_loop import circle_clearance

RES, RADIUS, S = 0.05, 0.297, 0.01
START, GOAL = np.array([-1.2, 0.0]), np.array([1.3, 0.0])


def u_field(standoff: float = 0.1) -> ObstacleField:
    return ObstacleField(box_grid(U_TRAP, (-2.0, -2.0), (4.0, 4.0), RES), RADIUS,
                         FieldSettings(standoff=standoff))


def independent_clearance(fld: ObstacleField, path: np.ndarray) -> float:
    """The navigator's circle-to-cell clearance (another implementation) along the path."""
    g = fld.grid
    view = TerrainView(g.origin, g.resolution, np.ones_like(g.obstacle), g.obstacle,
                       np.zeros(g.obstacle.shape))
    return min(circle_clearance(view, x, y, fld.radius) for x, y in path)


def line(n: int, dx: float) -> np.ndarray:
    return np.column_stack((np.arange(n) * dx, np.zeros(n)))


@pytest.mark.parametrize(("points", "target", "expected"), [
    (line(6, 0.01), np.array([1.0, 0.0]), False),  # 5 steps of s: 5s of progress
    (line(6, 0.0031), np.array([1.0, 0.0]), False),  # 1.55 s over the window: progress
    (line(6, 0.0029), np.array([0.0145 + 0.019, 0.0]), False),  # target within 2s
    (line(6, 0.0029), np.array([0.0145 + 0.021, 0.0]), True),  # just beyond 2s
    (line(6, 0.0029), np.array([1.0, 0.0]), True),  # 1.45 s over the window
    (line(5, 0.0), np.array([1.0, 0.0]), False),  # fewer than 6 points since the switch
    (line(6, 0.0), np.array([1.0, 0.0]), True),  # standing still, goal far
    (np.array([[0, 0], [0.01, 0], [0, 0], [0.01, 0], [0, 0], [0.01, 0]]),
     np.array([1.0, 0.0]), True),  # oscillating (the saw-tooth of a minimum)
])
def test_local_minimum_table(points: np.ndarray, target: np.ndarray, expected: bool) -> None:
    assert trapped(np.asarray(points, float), target, S) is expected


def test_local_minimum_boundaries() -> None:
    far = np.array([1.0, 0.0])
    assert trapped(line(6, 0.0029), far, S)  # 1.45 s < 1.5 s: trapped
    assert not trapped(line(6, 0.0031), far, S)  # 1.55 s
    near = line(6, 0.0)
    assert not trapped(near, np.array([0.0199, 0.0]), S)  # within 2 s of the target
    assert trapped(near, np.array([0.0201, 0.0]), S)


def test_virtual_goal_lies_on_the_bisector_rho_o_beyond_the_boundary() -> None:
    fld = u_field(0.1)
    local_min, target = np.array([-0.3, 0.0]), GOAL
    v = place_virtual_goal(fld, local_min, target, S, [])
    assert v is not None
    mid, lt = (local_min + target) / 2, target - local_min
    assert abs(np.dot(v - mid, lt)) / np.linalg.norm(lt) < 1e-9  # on the bisector x = 0.5
    # beyond the side wall's outer face (|y| = 0.4) by R + ρ_o, to half a sample
    assert abs(v[1]) == pytest.approx(0.4 + RADIUS + 0.1, abs=RES / 2)
    assert float(fld.clearance(v)[0]) == pytest.approx(0.1, abs=RES / 2)
    assert v[1] > 0  # the tie goes to the left of L -> G
    other = place_virtual_goal(fld, local_min, target, S, [v])
    assert other is not None and other[1] < 0  # a used goal is not placed again
    assert place_virtual_goal(fld, local_min, target, S, [v, other]) is None


def test_without_an_obstacle_on_the_bisector_the_goal_is_half_of_lt_out() -> None:
    fld = u_field(0.1)
    local_min, target = np.array([-1.5, -1.5]), np.array([-1.5, -0.9])
    v = place_virtual_goal(fld, local_min, target, S, [])
    assert v is not None
    assert v[1] == pytest.approx(-1.2) and abs(v[0] + 1.5) == pytest.approx(0.3, abs=RES / 2)


def test_u_trap_plain_apf_is_trapped_virtual_goals_reach() -> None:
    fld = u_field()
    plain = plan(fld, START, GOAL, ApfMethod.APF)
    assert not plain.reached and plain.reason.startswith("local minimum")
    assert plain.path[-1][0] < -0.1  # stalled in front of the opening
    res = plan(fld, START, GOAL, ApfMethod.APF_VIRTUAL)
    assert res.reached, res.reason
    assert np.allclose(res.path[-1], GOAL) and np.allclose(res.path[0], START)
    assert 1 <= len(res.virtual_goals) <= PlanSettings().max_virtual
    assert min_clearance(fld, res.path) > 0
    assert independent_clearance(fld, res.raw) > 0
    assert res.length > np.linalg.norm(GOAL - START)
    steps = np.hypot(*np.diff(res.raw, axis=0).T)
    assert steps[:-1] == pytest.approx(S)  # the fixed step
    assert len(res.path) == math.ceil(len(res.raw) / 5) + ((len(res.raw) - 1) % 5 != 0)


def test_the_step_budget_ends_a_plan_trapped() -> None:
    res = plan(u_field(), START, GOAL, ApfMethod.APF_VIRTUAL, PlanSettings(max_steps=50))
    assert not res.reached and "budget" in res.reason and len(res.raw) == 51


@pytest.mark.parametrize(("start", "goal", "words"), [
    ((-5.0, 0.0), (1.3, 0.0), "outside the map"),
    ((-1.2, 0.0), (0.55, 0.0), "inside an obstacle"),
    ((-1.2, 0.0), (0.3, 0.0), "inside an obstacle"),  # the disc does not fit in the U
    ((math.nan, 0.0), (1.3, 0.0), "not a finite"),
])
def test_bad_start_or_goal(start: tuple, goal: tuple, words: str) -> None:
    with pytest.raises(CommandError, match=words):
        plan(u_field(), np.array(start), np.array(goal), ApfMethod.APF)


def bumpy_wall(bumps: bool) -> list[tuple[float, float, float, float]]:
    boxes = [(0.0, -0.5, 2.0, 0.1)]  # face at y = -0.4
    if bumps:
        boxes += [(x, -0.4, 0.1, 0.05) for x in (-1.0, -0.2, 0.6, 1.4)]  # 5 cm bumps
    return boxes


@pytest.mark.parametrize("bumps", [False, True])
def test_standoff_tracks_rho_o(bumps: bool) -> None:
    means = []
    for rho_o in (0.05, 0.10, 0.15):
        grid = box_grid(tuple(bumpy_wall(bumps)), (-2.0, -1.0), (4.0, 2.0), RES)
        fld = ObstacleField(grid, RADIUS, FieldSettings(standoff=rho_o))
        res = follow(fld, np.array([-1.5, -0.4 + RADIUS + 1.5 * rho_o]), 3.0, side=1)
        assert res.reached, res.reason
        rho = fld.clearance(res.raw[len(res.raw) // 5:])[0]  # after settling
        means.append(float(rho.mean()))
        assert rho.mean() == pytest.approx(rho_o, rel=0.2)
        assert rho.min() > 0
    assert means[0] < means[1] < means[2]


def test_coverage_of_a_2m_area_with_two_obstacles() -> None:
    grid = box_grid(TWO_OBSTACLES, (-0.5, -0.5), (3.0, 3.0), RES)
    fld = ObstacleField(grid, RADIUS, FieldSettings(standoff=0.03))
    res = cover(fld, (0.0, 0.0, 2.0, 2.0), 0.3, RADIUS)
    assert res.problems == []
    assert res.share >= 0.95
    assert 0 < res.overlap < 1 and res.length > 7 * 2.0
    assert min_clearance(fld, res.route) > 0


def unseen_boxes(seed: int) -> tuple[tuple[float, float, float, float], ...]:
    """1-3 boxes (centre x, y, half sizes [m]) at random in the 2 m x 2 m area: maps the
    route's rules were not tuned on."""
    rng = np.random.default_rng(seed)
    return tuple((*rng.uniform(0.2, 1.8, 2), *rng.uniform(0.05, 0.25, 2))
                 for _ in range(rng.integers(1, 4)))


@pytest.mark.parametrize("seed", range(6))
def test_coverage_of_maps_it_has_not_seen_reaches_95_percent(seed: int) -> None:
    grid = box_grid(unseen_boxes(seed), (-0.5, -0.5), (3.0, 3.0), RES)
    fld = ObstacleField(grid, RADIUS, FieldSettings(standoff=0.03))
    res = cover(fld, (0.0, 0.0, 2.0, 2.0), 0.3, RADIUS)
    assert res.share >= 0.95, (unseen_boxes(seed), res.share, res.problems)
    assert res.share_free <= res.share  # the reachable cells are among the free ones
    assert min_clearance(fld, res.route) > 0


@pytest.mark.parametrize(("area", "spacing"), [((0, 0, 0, 2), 0.3), ((0, 0, 2, 2), 0.0),
                                                ((0, 0, 9, 2), 0.3), ((0, 0, 2, math.nan), 0.3)])
def test_bad_coverage_requests(area: tuple, spacing: float) -> None:
    fld = ObstacleField(box_grid(TWO_OBSTACLES, (-0.5, -0.5), (3.0, 3.0), RES), RADIUS,
                        FieldSettings())
    with pytest.raises(CommandError):
        cover(fld, area, spacing, RADIUS)


# a wall of cells with centres from x = 1.025; the field's reach is the disc radius + ρ_a (2 ρ_o)
# + half a cell's diagonal = 0.297 + 0.2 + 0.0354 = 0.5324 m: open up to x = 0.4926
@pytest.mark.parametrize(("end_x", "boxes", "expected"), [
    (0.0, ((1.5, 0.0, 0.5, 2.0),), True),
    (0.49, ((1.5, 0.0, 0.5, 2.0),), True),
    (0.50, ((1.5, 0.0, 0.5, 2.0),), False),
    (0.9, ((1.5, 0.0, 0.5, 2.0),), False),
    (1.9, (), True),  # no obstacle cell at all
])
def test_open_line_table(end_x: float, boxes: tuple, expected: bool) -> None:
    fld = ObstacleField(box_grid(boxes, (-2.0, -2.0), (4.0, 4.0), RES), RADIUS,
                        FieldSettings(standoff=0.1))
    assert open_line(fld, np.array([-1.0, 0.0]), np.array([end_x, 0.0])) is expected


def test_the_open_line_shortcut_takes_the_steps_the_descent_takes() -> None:
    fld = u_field()
    short = plan(fld, START, GOAL, ApfMethod.APF_VIRTUAL)
    # open_check beyond the budget: checked only at the start (not open: the U is in the way)
    full = plan(fld, START, GOAL, ApfMethod.APF_VIRTUAL, PlanSettings(open_check=10 ** 9))
    assert short.reached and full.reached
    assert short.raw.shape == full.raw.shape
    assert np.allclose(short.raw, full.raw, atol=1e-9)


def test_a_goal_across_open_water_costs_no_field_steps(monkeypatch) -> None:
    fld = ObstacleField(box_grid(U_TRAP, (-12.0, -12.0), (24.0, 24.0), RES), RADIUS,
                        FieldSettings(standoff=0.1))
    calls = []
    monkeypatch.setattr(fld, "potential", lambda *a: calls.append(a) or (0.0, np.zeros(2)))
    goal = np.array([-1.2, -9.9])  # 9.9 m from the start, the U 1.18 m aside
    res = plan(fld, START, goal, ApfMethod.APF_VIRTUAL)
    assert res.reached and not calls
    assert np.hypot(*np.diff(res.raw, axis=0).T) == pytest.approx(S)
    assert np.allclose(res.raw[-1], goal)
