"""Tests of crawler_motion.motion.sway: support polygons, the nearest point inside, targets."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.motion.sway import (
    SLACK,
    SWAY_SCALE,
    closest_inside,
    convex_hull,
    creep_order,
    halfplanes,
    line_sways,
    support_margin,
    sway_target,
)

SQUARE = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
TRIANGLE = np.array([[1.0, 0.0], [-1.0, 1.0], [-1.0, -1.0]])


def test_hull_is_counter_clockwise_and_drops_inner_points():
    hull = convex_hull(np.vstack((SQUARE, [[0.0, 0.0], [0.5, 0.2]])))
    assert len(hull) == 4
    x, y = hull.T
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) == pytest.approx(4.0)


@pytest.mark.parametrize(("points", "centre", "margin"), [
    (SQUARE, (0.0, 0.0), 1.0),
    (SQUARE, (0.9, 0.0), 0.1),
    (SQUARE, (1.0, 0.0), 0.0),  # on the edge
    (SQUARE, (1.5, 0.0), -0.5),  # outside
    (TRIANGLE, (0.0, 0.0), 1 / math.sqrt(5)),
    (TRIANGLE[::-1], (0.0, 0.0), 1 / math.sqrt(5)),  # any vertex order
    (TRIANGLE[:2], (0.0, 0.0), -math.inf),  # two feet: no polygon
])
def test_support_margin(points, centre, margin):
    assert support_margin(points, np.array(centre)) == pytest.approx(margin)


@pytest.mark.parametrize(("target", "expected"), [
    ((0.2, 0.3), (0.2, 0.3)),  # inside: itself
    ((2.0, 0.3), (1.0, 0.3)),  # beyond an edge: its projection
    ((2.0, 3.0), (1.0, 1.0)),  # beyond a corner: the vertex
])
def test_closest_inside(target, expected):
    a, b = halfplanes(SQUARE)
    np.testing.assert_allclose(closest_inside(a, b, np.array(target)), expected, atol=1e-12)


def test_closest_inside_an_empty_set_is_none():
    a = np.array([[1.0, 0.0], [-1.0, 0.0]])
    assert closest_inside(a, np.array([-1.0, -1.0]), np.zeros(2)) is None  # x <= -1, x >= 1


def test_sway_target_keeps_margin_plus_slack_and_is_none_when_impossible():
    target = sway_target([TRIANGLE], 0.2, centre=np.array([5.0, 0.0]))
    assert support_margin(TRIANGLE, target) == pytest.approx(0.2 + SLACK)
    assert sway_target([TRIANGLE], 0.6) is not None
    assert sway_target([TRIANGLE], 0.62) is None  # the inradius is 4 / (2 + 2 sqrt 5) = 0.618
    assert sway_target([TRIANGLE[:1]], 0.0) is None  # one foot


def test_sway_target_of_a_support_line_is_on_its_segment():
    line = np.array([[0.12, 0.19], [-0.08, -0.19]])
    p = sway_target([line], 0.0)
    d = line[1] - line[0]
    assert abs(d[0] * (p - line[0])[1] - d[1] * (p - line[0])[0]) <= 1e-12
    # the segment's end when the nearest point of the line lies beyond it
    np.testing.assert_allclose(sway_target([np.array([[1.0, 0.5], [2.0, 0.5]])], 0.0),
                               [1.0, 0.5])


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=3, max_size=6),
       st.floats(0.0, 0.3), st.tuples(st.floats(-2, 2), st.floats(-2, 2)))
def test_a_found_target_is_inside_by_the_margin(points, margin, centre):
    pts = np.array(points)
    target = sway_target([pts], margin, np.array(centre))
    if len(convex_hull(pts)) >= 3 and target is not None:
        assert support_margin(pts, target) >= margin + SLACK - 1e-9


@pytest.mark.parametrize(("heading", "order"), [
    (0.0, (1, 0, 2, 3)),  # lb, lf, rb, rf (legs in config order lf, lb, rb, rf)
    (math.pi, (3, 2, 0, 1)),
    (math.pi / 2, (2, 1, 3, 0)),
])
def test_creep_order(heading, order):
    feet = np.array([[0.1, 0.19], [-0.1, 0.19], [-0.1, -0.19], [0.1, -0.19]])
    assert creep_order(feet, heading) == order


# --- support lines: the body moves along them (gaits of pairs) -------------------------------

B_LINE = np.array([[-0.10, -0.19], [0.10, 0.19]])  # lf-rb diagonal of the standing feet [m]
A_LINE = np.array([[-0.10, 0.19], [0.10, -0.19]])  # rf-lb
SHIFT = np.array([0.015, 0.0])  # walking forward: the lines 15 mm behind and ahead [m]
BEHIND, AHEAD = B_LINE - SHIFT, A_LINE + SHIFT


def line_cost(s1, s2, travel, weight):
    r = travel - (s2 - s1)
    return float(r @ r + weight * (SWAY_SCALE**2 @ (s1 * s1) + SWAY_SCALE**2 @ (s2 * s2)))


def test_a_large_weight_gives_the_nearest_points_of_the_lines():
    travel = np.array([-0.015, 0.0])
    s1, s2 = line_sways(BEHIND, AHEAD, travel, 1e6)
    np.testing.assert_allclose(s1, sway_target([BEHIND], 0.0), atol=1e-9)
    np.testing.assert_allclose(s2, sway_target([AHEAD], 0.0), atol=1e-9)


def test_without_weight_the_body_crosses_where_the_lines_meet():
    # Forward: the support line at the swing's end lies 15 mm behind, the next 15 mm ahead,
    # and the feet move 15 mm back in the transfer, which would carry 45 mm. With no cost on
    # the sway both ends go to where the lines cross, and the transfer carries nothing.
    travel = np.array([-0.015, 0.0])
    s1, s2 = line_sways(BEHIND, AHEAD, travel, 0.0)
    np.testing.assert_allclose(s2 - s1, travel, atol=1e-12)


def test_the_shipped_weight_trades_sway_for_travel():
    travel = np.array([-0.015, 0.0])
    first, second = BEHIND, AHEAD
    near = (sway_target([first], 0.0), sway_target([second], 0.0))
    s1, s2 = line_sways(first, second, travel, 0.025)
    before = np.linalg.norm(travel - (near[1] - near[0]))
    after = np.linalg.norm(travel - (s2 - s1))
    assert before == pytest.approx(0.0447, abs=5e-4)  # 15 mm planned + 2 x 14.8 mm of sway
    assert after < 0.6 * before
    assert abs(s1[1]) == pytest.approx(abs(s2[1]))  # the lateral sway zig-zags, same size
    assert 0.010 < abs(s1[1]) < 0.025


def test_a_point_as_the_second_support_stays_that_point():
    s1, s2 = line_sways(B_LINE, np.zeros((2, 2)), np.array([0.01, 0.0]), 0.02)
    np.testing.assert_array_equal(s2, [0.0, 0.0])
    d, e = B_LINE[1] - B_LINE[0], s1 - B_LINE[0]
    assert abs(d[0] * e[1] - d[1] * e[0]) <= 1e-12  # on the line


coords = st.floats(-0.2, 0.2)
segments = st.lists(st.tuples(coords, coords), min_size=2, max_size=2).map(np.array)


@settings(max_examples=60, deadline=None)
@given(first=segments, second=segments, travel=st.tuples(coords, coords).map(np.array),
       weight=st.sampled_from([0.0, 0.001, 0.025, 1.0, 100.0]))
def test_line_sways_are_on_the_segments_and_no_grid_point_does_better(first, second, travel,
                                                                     weight):
    s1, s2 = line_sways(first, second, travel, weight)
    best = line_cost(s1, s2, travel, weight)
    grid = np.linspace(0.0, 1.0, 41)
    for seg, s in ((first, s1), (second, s2)):
        d = seg[1] - seg[0]
        u = float((s - seg[0]) @ d / (d @ d)) if d @ d > 1e-18 else 0.0
        assert -1e-9 <= u <= 1 + 1e-9
        np.testing.assert_allclose(s, seg[0] + u * d, atol=1e-9)
    for u in grid:
        for w in grid:
            other = line_cost(first[0] + u * (first[1] - first[0]),
                              second[0] + w * (second[1] - second[0]), travel, weight)
            assert best <= other + 1e-9
