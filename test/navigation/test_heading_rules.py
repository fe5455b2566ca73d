"""The heading rules: tangent law, too close, back to the goal, blocked, best direction."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.navigation.heading import (
    HeadingSettings,
    Rule,
    best_direction,
    blocked_interval,
    decide,
)

RC = 0.3
SET = HeadingSettings(clearance=RC, lookahead=2.0, max_turn=math.radians(100))


def deg(a: float) -> float:
    return math.degrees(a)


# N (goal frame), side kept, expected heading = atan2(y, x) ± asin(Rc / |ON|) [deg]
TANGENT_CASES = [
    ((1.0, 0.0), 1, deg(math.asin(0.3))),             # straight ahead, left: +17.46°
    ((1.0, 0.0), -1, -deg(math.asin(0.3))),           # straight ahead, right
    ((0.6, 0.2), 1, deg(math.atan2(0.2, 0.6) + math.asin(RC / math.hypot(0.6, 0.2)))),
    ((0.6, 0.2), -1, deg(math.atan2(0.2, 0.6) - math.asin(RC / math.hypot(0.6, 0.2)))),
    ((0.5, -0.1), 1, deg(math.atan2(-0.1, 0.5) + math.asin(RC / math.hypot(0.5, 0.1)))),
    ((RC + 1e-6, 0.0), 1, 90.0 - 0.15),               # just outside Rc: almost 90°
]


@pytest.mark.parametrize("n, side, expected", TANGENT_CASES)
def test_the_tangent_law_on_one_boundary_point(n: tuple, side: int, expected: float) -> None:
    d = decide(np.array([n]), 5.0, side, 0.0, SET)
    assert d.rule is Rule.TANGENT and d.side == side and d.boundary == pytest.approx(n)
    assert deg(d.heading) == pytest.approx(expected, abs=0.2)


def test_a_wall_is_passed_at_the_tangent_of_its_end() -> None:
    ys = np.arange(-0.3, 0.301, 0.05)
    wall = np.column_stack((np.full(len(ys), 0.8), ys))
    d = decide(wall, 1.6, 1, 0.0, SET)
    end = math.atan2(0.3, 0.8) + math.asin(RC / math.hypot(0.8, 0.3))
    assert d.boundary == pytest.approx((0.8, 0.3)) and d.heading == pytest.approx(end)


@pytest.mark.parametrize("n, goal, expected_rule", [
    ((-0.5, 0.0), 1.0, Rule.GOAL),       # behind: back to the goal direction
    ((-0.01, 0.35), 1.0, Rule.GOAL),     # just behind, beside the path
    ((0.01, 0.35), 1.0, Rule.GOAL),      # ahead but off the goal direction
    ((0.5, 0.25), 1.0, Rule.TANGENT),    # ahead, covers it (asin(0.3/0.56) > atan(0.5))
    ((2.5, 0.0), 5.0, Rule.GOAL),        # beyond the look-ahead (2 m)
    ((1.29, 0.0), 1.0, Rule.TANGENT),    # beyond the goal by less than Rc
    ((1.31, 0.0), 1.0, Rule.GOAL),       # beyond the goal by more than Rc
])
def test_which_cells_block(n: tuple, goal: float, expected_rule: Rule) -> None:
    assert decide(np.array([n]), goal, 0, 0.0, SET).rule is expected_rule


@pytest.mark.parametrize("n, side, expected", [
    ((0.2, 0.0), 1, 90.0), ((0.2, 0.0), -1, -90.0),  # ahead: sideways, on the kept side
    ((0.0, 0.3), 1, 0.0),                             # on the left, touching: along it
    ((0.1, -0.1), 1, 45.0),                           # ahead right: away, towards the goal
    ((RC, 0.0), 1, 90.0),                             # |ON| = Rc is too close
])
def test_too_close_turns_away_by_90_degrees(n: tuple, side: int, expected: float) -> None:
    d = decide(np.array([n]), 5.0, side, 0.0, SET)
    assert d.rule is Rule.TOO_CLOSE and deg(d.heading) == pytest.approx(expected, abs=1e-6)


def test_the_side_follows_the_best_direction_then_the_smaller_turn() -> None:
    wall = np.array([[0.8, y] for y in np.arange(-0.1, 0.5, 0.05)])  # reaches further left
    assert decide(wall, 2.0, 0, -0.5, SET).side == -1
    assert decide(wall, 2.0, 0, 0.5, SET).side == 1
    assert decide(wall, 2.0, 0, 0.0, SET).side == -1  # right is the smaller turn


def test_no_heading_within_the_largest_turn_is_blocked() -> None:
    u = [(x, y) for x in (0.4,) for y in np.arange(-1.5, 1.51, 0.05)]
    u += [(x, s * 1.5) for x in np.arange(-0.5, 0.4, 0.05) for s in (-1, 1)]
    d = decide(np.array(u), 2.0, 1, 0.0, HeadingSettings(RC, 2.0, math.radians(60)))
    assert d.rule is Rule.BLOCKED and d.heading is None


def test_the_other_side_is_taken_when_the_kept_side_turns_too_far() -> None:
    wall = np.array([[0.5, y] for y in np.arange(-0.1, 3.0, 0.05)])
    d = decide(wall, 2.0, 1, 0.0, HeadingSettings(RC, 2.0, math.radians(60)))
    assert d.side == -1 and d.heading < 0


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(st.floats(0.35, 1.5), st.floats(-1.0, 1.0)), min_size=1,
                max_size=20), st.sampled_from([1, -1]))
def test_a_tangent_heading_keeps_every_cell_at_least_rc_from_the_line(cells: list, side: int
                                                                      ) -> None:
    pts = np.array(cells)
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) > RC + 1e-3]
    if not len(pts):
        return
    d = decide(pts, 10.0, side, 0.0, HeadingSettings(RC, 10.0, math.pi))
    if d.rule is Rule.TANGENT:
        u = np.array([math.cos(d.heading), math.sin(d.heading)])
        along = pts @ u
        across = np.abs(pts[:, 0] * u[1] - pts[:, 1] * u[0])
        dist = np.where(along > 0, across, np.hypot(pts[:, 0], pts[:, 1]))
        assert dist.min() >= RC - 1e-9


def test_blocked_interval_merges_overlaps_only() -> None:
    pts = np.array([[1.0, 0.0], [1.0, 0.5], [1.0, -2.0]])
    _, high, i_low, i_high = blocked_interval(pts, 0.3)
    assert (i_low, i_high) == (0, 1)
    assert high == pytest.approx(math.atan2(0.5, 1) + math.asin(0.3 / math.hypot(1, 0.5)))
    assert blocked_interval(np.array([[1.0, 1.0]]), 0.3) is None


def test_best_direction_is_the_lowest_mean_height_nearest_the_goal_on_ties() -> None:
    xs, ys = np.meshgrid(np.arange(0, 1.5, 0.05), np.arange(-1, 1, 0.05))
    centres = np.column_stack((xs.ravel(), ys.ravel()))
    heights = np.where((centres[:, 1] < 0.2), 0.1, 0.0)  # high on the right and centre
    cands = np.radians(np.arange(-90, 91, 10))
    assert best_direction(centres, heights, 0.25, 0.6, cands) > 0.5
    assert best_direction(centres, np.zeros(len(centres)), 0.25, 0.6, cands) == 0.0
    assert best_direction(np.zeros((0, 2)), np.zeros(0), 0.25, 0.6, cands) == 0.0
