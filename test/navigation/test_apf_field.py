"""The improved field: clearance, potential and gradient against finite differences and closed
forms; settings checks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.errors import ConfigError
from crawler_motion.navigation.apf.field import FieldSettings, Grid, ObstacleField
from crawler_motion.navigation.apf.maps import U_TRAP, box_grid

RES = 0.05
WALL = box_grid(((0.0, 0.0, 0.05, 1.0),), (-1.0, -1.5), (2.0, 3.0), RES)


def u_field(standoff: float = 0.1) -> ObstacleField:
    return ObstacleField(box_grid(U_TRAP, (-2.0, -2.0), (4.0, 4.0), RES), 0.297,
                         FieldSettings(standoff=standoff))


@pytest.mark.parametrize(("x", "y", "rho"), [
    (0.30, 0.0, 0.30 - 0.05 - 0.1),  # in front of the wall face (x = 0.05)
    (0.15, 0.5, 0.15 - 0.05 - 0.1),
    (0.30, 1.20, math.hypot(0.25, 0.20) - 0.1),  # past the wall's end (corner 0.05, 1.0)
    (-0.5, -1.3, math.hypot(0.45, 0.30) - 0.1),
])
def test_clearance_is_the_disc_to_cell_distance(x: float, y: float, rho: float) -> None:
    fld = ObstacleField(WALL, 0.1, FieldSettings())
    got, grad = fld.clearance(np.array([x, y]))
    assert got == pytest.approx(rho, abs=1e-9)
    assert math.hypot(*grad) == pytest.approx(1.0)


def test_no_obstacle_means_infinite_clearance_and_goal_pull_only() -> None:
    grid = Grid(np.zeros((10, 10), bool), np.zeros(2), RES)
    fld = ObstacleField(grid, 0.2, FieldSettings())
    rho, _ = fld.clearance(np.array([0.2, 0.2]))
    assert math.isinf(rho)
    _, grad = fld.potential(np.array([0.1, 0.1]), np.array([0.4, 0.1]))
    assert grad == pytest.approx([-1.0, 0.0])  # conic: unit pull beyond d_a


@pytest.mark.parametrize(("rho", "u", "du"), [
    (0.05, 0.5 * 1e-3 * 10.0 ** 2, -1e-3 * 10.0 / 0.05 ** 2),  # repulsion, κ_r = 1
    (0.10, 0.0, 0.0),  # ρ_o: repulsion and attraction both vanish
    (0.15, 0.4 * 0.1 / math.pi, 0.4),  # mid-band: the attraction's largest pull
    (0.20, 0.8 * 0.1 / math.pi, 0.0),  # ρ_a = 2 ρ_o
    (0.50, 0.8 * 0.1 / math.pi, 0.0),
    (0.0, math.inf, 0.0),  # touching: infinite
])
def test_obstacle_potential_table(rho: float, u: float, du: float) -> None:
    fld = ObstacleField(WALL, 0.1, FieldSettings(standoff=0.1))
    got_u, got_du = fld.obstacle_potential(np.array(rho))
    assert got_u == pytest.approx(u, abs=1e-12)
    assert got_du == pytest.approx(du, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.floats(-1.5, 1.9), st.floats(-1.5, 1.5), st.floats(0.05, 0.2))
def test_gradient_matches_finite_differences(x: float, y: float, standoff: float) -> None:
    fld = u_field(standoff)
    p, goal, h = np.array([x, y]), np.array([1.3, 0.0]), 1e-6
    rho, _ = fld.clearance(p)
    kinks = [0.0, standoff, 2 * standoff]
    if rho <= 1e-3 or min(abs(rho - k) for k in kinks) < 1e-4 or abs(
            math.hypot(*(p - goal)) - fld.settings.goal_range) < 1e-4:
        return
    half = fld.grid.resolution / 2
    d = np.hypot(*np.maximum(np.abs(p - fld.cells) - half, 0.0).T)
    if np.sort(d)[1] - d.min() < 1e-4:  # two nearest cells: a ridge of the clearance
        return
    pts = p + h * np.array([[1, 0], [-1, 0], [0, 1], [0, -1]])
    u = fld.potential(pts, goal)[0]
    fd = np.array([(u[0] - u[1]) / (2 * h), (u[2] - u[3]) / (2 * h)])
    _, grad = fld.potential(p, goal)
    scale = max(1.0, float(np.abs(grad).max()))
    assert np.allclose(fd, grad, atol=1e-4 * scale), (fd, grad)


def test_field_on_the_grid_is_vectorised_and_agrees_with_points() -> None:
    fld = u_field()
    u, grad = fld.on_grid(np.array([1.3, 0.0]))
    assert u.shape == fld.grid.obstacle.shape and grad.shape == (*u.shape, 2)
    c = fld.grid.centres()[10, 17]
    assert u[10, 17] == pytest.approx(float(fld.potential(c, np.array([1.3, 0.0]))[0]))


@pytest.mark.parametrize("kwargs", [{"standoff": 0.0}, {"standoff": math.nan}, {"band": 1.0},
                                    {"attraction": 1.0}, {"attraction": -0.1},
                                    {"goal_range": -1.0}])
def test_bad_field_settings_are_refused(kwargs: dict) -> None:
    with pytest.raises(ConfigError):
        FieldSettings(**kwargs)


def test_bad_radius_is_refused() -> None:
    with pytest.raises(ConfigError):
        ObstacleField(WALL, math.nan, FieldSettings())
