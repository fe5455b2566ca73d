"""Tests of crawler_motion.motion.sway: support polygons, the nearest point inside, targets."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.motion.sway import (
    SLACK,
    closest_inside,
    convex_hull,
    creep_order,
    halfplanes,
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
