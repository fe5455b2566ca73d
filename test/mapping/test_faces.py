"""A cell on an obstacle's face is never free: faces, steps, slopes and noise as a table.

Returns are fused scan by scan as the mapper fuses them (each scan gated against the cell's
estimate before it), then classified by the obstacle rule of `mapping.obstacles` with the
mapper's defaults (threshold 0.02 m, confidence 2 σ, ground window 0.25 m).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_motion.mapping.grid import ElevationGrid
from crawler_motion.mapping.obstacles import (
    face_cells,
    obstacle_cells,
    occupancy,
    uncertain_cells,
)

RES, CELLS, THRESHOLD, RADIUS = 0.05, 40, 0.02, 5
SIGMA = 0.002  # noise of a return's height [m] (the rule asks for at most threshold / 8)


def profile_surface(kind: str, size: float) -> callable:
    """Seabed height z(x) [m] along x (uniform in y): a face (a vertical rise of ``size`` at
    x = 0.525 m, inside the cell 0.50..0.55), a step of ``size`` at the same place, or a slope
    of ``size`` degrees from x = 0.4 m."""
    if kind == "slope":
        grade = math.tan(math.radians(size))
        return lambda x: np.maximum(0.0, (x - 0.4) * grade)
    return lambda x: np.where(x >= 0.525, size, 0.0)


def fused_grid(kind: str, size: float, noise: float, scans: int = 20, stray: float = 0.0,
               seed: int = 3) -> ElevationGrid:
    """A grid fed ``scans`` scans of the surface; a face adds returns along its vertical
    extent at x = 0.525 m (the beam hits the face at every height); ``stray`` adds one return
    that high above the ground in the cell at x = 0.3 m."""
    rng = np.random.default_rng(seed)
    grid = ElevationGrid(RES, CELLS, gate=2.5, drift=1e-5, centre=(0.5, 0.0))
    z_of = profile_surface(kind, size)
    for k in range(scans):
        x = rng.uniform(0.0, 1.0, 400)
        y = rng.uniform(-0.2, 0.2, 400)
        z = z_of(x)
        if kind == "face":
            fz = rng.uniform(0.0, size, 40)
            x = np.concatenate([x, np.full(40, 0.525)])
            y = np.concatenate([y, rng.uniform(-0.2, 0.2, 40)])
            z = np.concatenate([z, fz])
        z = z + rng.normal(0.0, noise, len(z)) if noise else z
        pts = np.column_stack([x, y, z])
        if stray and k == scans // 2:
            pts = np.vstack([pts, [0.3, 0.0, stray]])
        grid.fuse(pts, np.full(len(pts), max(noise, 1e-3) ** 2))
    return grid


def classify(grid: ElevationGrid, new_rule: bool = True) -> np.ndarray:
    """OccupancyGrid values of the grid by the mapper's rule (``new_rule`` False: the height
    rule alone, as the mapper had it)."""
    if not new_rule:
        obstacle = obstacle_cells(grid.height, grid.known, THRESHOLD, RADIUS, grid.variance,
                                  2.0)
        return occupancy(grid.known, obstacle)
    obstacle = obstacle_cells(grid.height, grid.known, THRESHOLD, RADIUS, grid.variance, 2.0,
                              face_cells(grid.far, grid.returns))
    uncertain = uncertain_cells(grid.height, grid.known, THRESHOLD, RADIUS, obstacle,
                                grid.far, grid.variance, 2.0)
    return occupancy(grid.known, obstacle, uncertain)


def cell_at(grid: ElevationGrid, x: float, y: float = 0.0) -> tuple[int, int]:
    rows, cols, _ = grid.index(np.array([[x, y]]))
    return int(rows[0]), int(cols[0])


#: kind, size, noise [m], the value of the cell at x = 0.525 m, free cells before x = 0.45 m
CASES = [
    ("face", 0.15, 0.0, 100), ("face", 0.15, SIGMA, 100), ("face", 0.05, SIGMA, 100),
    ("face", 0.03, 0.0, 100),  # just above the 0.02 m threshold
    ("step", 0.15, SIGMA, 100), ("step", 0.03, SIGMA, 100),
    ("step", 0.004, SIGMA, 0),  # a step the crawler steps over
    ("slope", 3.0, 0.0, 0), ("slope", 3.0, SIGMA, 0),  # 0.26 cm per cell, 1.3 cm per window
    ("slope", 35.0, 0.0, 100),  # 3.5 cm per cell: more than the threshold
]


@pytest.mark.parametrize("kind, size, noise, expected", CASES)
def test_faces_steps_and_slopes(kind: str, size: float, noise: float, expected: int) -> None:
    grid = fused_grid(kind, size, noise)
    data = classify(grid)
    assert data[cell_at(grid, 0.525)] == expected
    if expected == 100 and kind != "slope":
        # a face or step cell is never free, in any row of the wall
        for y in np.arange(-0.175, 0.2, 0.05):
            assert data[cell_at(grid, 0.525, y)] != 0, y
    # flat ground in front of the obstacle is free, never an obstacle
    row = data[cell_at(grid, 0.1)[0], cell_at(grid, 0.01)[1]:cell_at(grid, 0.4)[1]]
    assert not (row == 100).any() and (row == 0).mean() >= 0.8, row


def test_the_height_rule_alone_calls_the_face_free() -> None:
    """The defect the spread rule fixes: face returns gated out inflate the cell's variance,
    and the fused height (a mean of foot and top) fails threshold + 2 σ."""
    grid = fused_grid("face", 0.15, SIGMA)
    assert classify(grid, new_rule=False)[cell_at(grid, 0.525)] == 0
    assert classify(grid)[cell_at(grid, 0.525)] == 100


def test_one_stray_return_makes_no_obstacle_only_doubt() -> None:
    grid = fused_grid("step", 0.008, SIGMA, stray=0.2)
    assert classify(grid)[cell_at(grid, 0.3)] == -1  # unknown: neither free nor obstacle
    assert grid.far[cell_at(grid, 0.3)] == 1


def test_returns_far_from_the_estimate_are_counted() -> None:
    grid = ElevationGrid(RES, CELLS, gate=2.5, drift=0.0, step=0.02)  # far: > 0.01 m
    cell = cell_at(grid, 0.01, 0.01)
    grid.fuse(np.array([[0.01, 0.01, 0.0]] * 3), np.full(3, 1e-6))  # unknown before: none
    assert (grid.far[cell], grid.returns[cell]) == (0, 3)
    grid.fuse(np.array([[0.01, 0.01, z] for z in (0.009, 0.011, -0.03)]), np.full(3, 1e-6))
    assert (grid.far[cell], grid.returns[cell]) == (2, 6)


@pytest.mark.parametrize(("residual", "sigma", "far"), [
    (0.011, 0.001, True),  # beyond step / 2 (0.01 m) and 2 σ
    (0.009, 0.001, False),  # within step / 2
    (0.015, 0.007, True),  # beyond 2 σ = 0.014 m
    (0.013, 0.007, False),  # within 2 σ: the noise the return says it has
    (-0.05, 0.02, True),  # below the estimate counts the same
    (0.035, 0.02, False),  # a grazing return of the flat seabed seen at range
])
def test_a_return_is_far_beyond_half_the_step_and_two_of_its_own_sigma(
        residual: float, sigma: float, far: bool) -> None:
    grid = ElevationGrid(RES, CELLS, gate=2.5, drift=0.0, step=0.02)
    cell = cell_at(grid, 0.01, 0.01)
    grid.fuse(np.array([[0.01, 0.01, 0.0]] * 50), np.full(50, 1e-6))  # a settled cell
    grid.fuse(np.array([[0.01, 0.01, residual]]), np.array([sigma**2]))
    assert grid.far[cell] == int(far)


def test_a_cell_above_the_threshold_without_the_margin_is_unknown_not_free() -> None:
    known = np.ones((9, 9), dtype=bool)
    height = np.zeros((9, 9))
    height[4, 4] = 0.03  # above 0.02, but σ = 0.01 asks for 0.04
    variance = np.full((9, 9), 1e-4)
    obstacle = obstacle_cells(height, known, THRESHOLD, 2, variance, 2.0)
    uncertain = uncertain_cells(height, known, THRESHOLD, 2, obstacle)
    data = occupancy(known, obstacle, uncertain)
    assert data[4, 4] == -1 and (data == 0).sum() == 80


def test_the_counts_follow_the_window() -> None:
    grid = fused_grid("face", 0.15, 0.0, scans=3)
    before = grid.far[cell_at(grid, 0.525)], grid.returns[cell_at(grid, 0.525)]
    assert before[0] > 0
    assert grid.follow(1.2, 0.0)
    assert (grid.far[cell_at(grid, 0.525)], grid.returns[cell_at(grid, 0.525)]) == before


# (heights of a cell's returns [mm], σ of each [mm], scans: 1 return each) -> published value.
# A cell is free only below the threshold by the confidence margin (2 σ_h of its height).
FREE_ROWS = [
    # a cell inside the U trap's wall, seen only at the foot of its outer face (a real-time
    # run; the 40 mm return gated out grew σ_h to 31 mm): the map had called it free
    ((11.0, 12.0, 40.0), (16.0, 16.0, 15.0), -1),
    ((0.0,), (16.0,), -1),  # flat seabed seen once at range: σ_h 16 mm, not known to be free
    ((0.0,) * 30, (16.0,) * 30, 0),  # seen 30 times: σ_h 2.9 mm, free
    ((1.0,) * 4, (9.0,) * 4, 0),  # h + 2 σ_h = 1 + 9 = 10 mm: free
]


@pytest.mark.parametrize(("heights", "sigmas", "value"), FREE_ROWS)
def test_free_needs_the_confidence_margin_below_the_threshold(heights, sigmas, value) -> None:
    grid = ElevationGrid(RES, CELLS, gate=2.5, drift=1e-5, centre=(0.5, 0.0))
    ground = np.array([[x, y, 0.0] for x in np.arange(0.0, 1.0, 0.01)
                       for y in (-0.1, -0.05)] * 3)  # settled seabed beside it
    grid.fuse(ground, np.full(len(ground), 1e-6))
    for h, s in zip(heights, sigmas, strict=True):
        grid.fuse(np.array([[0.5, 0.06, h / 1000]]), np.array([(s / 1000) ** 2]))
    assert classify(grid)[cell_at(grid, 0.5, 0.06)] == value


@pytest.mark.parametrize(("rise", "value"), [(0.0099, 0), (0.0101, -1)])
def test_the_free_margin_boundary(rise, value) -> None:
    """σ_h 5 mm, confidence 2: free up to a rise of 10 mm above the local ground."""
    known = np.ones((9, 9), dtype=bool)
    height = np.zeros((9, 9))
    height[4, 4] = rise
    variance = np.full((9, 9), 1e-8)
    variance[4, 4] = 0.005**2
    obstacle = obstacle_cells(height, known, THRESHOLD, 2, variance, 2.0)
    uncertain = uncertain_cells(height, known, THRESHOLD, 2, obstacle, None, variance, 2.0)
    assert occupancy(known, obstacle, uncertain)[4, 4] == value
