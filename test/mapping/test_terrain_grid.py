"""The elevation grid: Kalman fusion against its closed forms, the gate, drift, scrolling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.errors import ConfigError
from crawler_motion.mapping.grid import ElevationGrid


def grid(**kw: float) -> ElevationGrid:
    args = {"resolution": 0.05, "cells": 20, "gate": 2.5, "drift": 0.0} | kw
    return ElevationGrid(args["resolution"], int(args["cells"]), args["gate"], args["drift"])


def cell_points(heights: np.ndarray, x: float = 0.12, y: float = -0.07) -> np.ndarray:
    return np.column_stack((np.full(len(heights), x), np.full(len(heights), y), heights))


@pytest.mark.parametrize("n", [1, 2, 7, 100])
@pytest.mark.parametrize("split", [False, True])
def test_n_returns_of_one_variance_give_the_mean_and_variance_over_n(n: int, split: bool
                                                                      ) -> None:
    g, sigma2 = grid(gate=1e9), 4e-6
    h = np.random.default_rng(n).normal(0.03, 0.002, n)
    chunks = np.array_split(np.arange(n), n) if split else [np.arange(n)]
    for idx in chunks:  # one scan, or one scan per return
        g.fuse(cell_points(h[idx]), np.full(len(idx), sigma2))
    r, c, _ = g.index(np.array([[0.12, -0.07]]))
    assert g.variance[r[0], c[0]] == pytest.approx(sigma2 / n, rel=1e-9)
    assert g.height[r[0], c[0]] == pytest.approx(h.mean(), abs=1e-12)
    assert g.count[r[0], c[0]] == n
    assert g.known.sum() == 1


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.1, 0.1), st.floats(1e-6, 1e-2)), min_size=1,
                max_size=12))
def test_batch_fusion_equals_the_sequential_scalar_kalman_update(returns: list) -> None:
    g = grid(gate=1e9)
    h = np.array([r[0] for r in returns])
    v = np.array([r[1] for r in returns])
    g.fuse(cell_points(h), v)
    est, var = h[0], v[0]  # the spec's eqs., one return at a time
    for hi, vi in zip(h[1:], v[1:], strict=True):
        est, var = (vi * est + var * hi) / (var + vi), var * vi / (var + vi)
    r, c, _ = g.index(np.array([[0.12, -0.07]]))
    assert g.height[r[0], c[0]] == pytest.approx(est, abs=1e-9)
    assert g.variance[r[0], c[0]] == pytest.approx(var, rel=1e-9)


def test_a_return_outside_the_gate_is_not_fused_and_grows_the_variance() -> None:
    g = grid()
    g.fuse(cell_points(np.zeros(4)), np.full(4, 1e-6))  # h 0, variance 2.5e-7
    result = g.fuse(cell_points(np.array([0.10])), np.array([1e-6]))
    assert (result.fused, result.gated) == (0, 1)
    r, c, _ = g.index(np.array([[0.12, -0.07]]))
    assert g.height[r[0], c[0]] == 0.0
    assert g.variance[r[0], c[0]] == pytest.approx(2.5e-7 + 0.01)
    result = g.fuse(cell_points(np.array([0.10])), np.array([1e-6]))  # it lasts: accepted
    assert result.fused == 1 and g.height[r[0], c[0]] > 0.09


def test_a_return_just_inside_the_gate_is_fused() -> None:
    g = grid(gate=2.0)
    g.fuse(cell_points(np.zeros(1)), np.array([1e-4]))  # sigma 0.01
    assert g.fuse(cell_points(np.array([0.0199])), np.array([1e-4])).fused == 1
    assert g.fuse(cell_points(np.array([0.05])), np.array([1e-4])).gated == 1


def test_travel_grows_known_variances_only() -> None:
    g = grid(drift=1e-4)
    g.fuse(cell_points(np.zeros(1)), np.array([1e-6]))
    g.grow(0.5)
    assert g.variance[g.known][0] == pytest.approx(1e-6 + 5e-5)
    assert np.isinf(g.variance[~g.known]).all()


def test_points_outside_the_window_are_counted_not_fused() -> None:
    g = grid()
    res = g.fuse(np.array([[5.0, 0.0, 0.0], [0.0, 0.0, 0.0]]), np.array([1e-6, 1e-6]))
    assert (res.fused, res.outside) == (1, 1)


@pytest.mark.parametrize("x, moved", [(0.25, False), (0.26, True), (-0.3, True), (10.0, True)])
def test_the_window_follows_the_robot_and_keeps_cells_in_place(x: float, moved: bool) -> None:
    g = grid()  # 1 m window, re-centres beyond 0.25 m
    g.fuse(np.array([[0.32, 0.02, 0.04]]), np.array([1e-6]))
    assert g.follow(x, 0.0) is moved
    r, c, inside = g.index(np.array([[0.32, 0.02]]))
    if inside[0]:
        assert g.known[r[0], c[0]] and g.height[r[0], c[0]] == pytest.approx(0.04)
    assert g.known.sum() == int(inside[0])
    assert not np.isnan(g.height).any() and not np.isnan(g.variance).any()


@pytest.mark.parametrize("kw", [{"resolution": 0.0}, {"cells": 2}, {"gate": float("nan")},
                                {"drift": -1.0}])
def test_bad_grid_settings_are_refused(kw: dict) -> None:
    with pytest.raises(ConfigError):
        grid(**kw)
