"""Synthetic occupancy grids from axis-aligned boxes: test and picture maps, among them the U
trap of ``config/worlds/u_trap.xml`` (pure)."""

from __future__ import annotations

import numpy as np

from crawler_motion.navigation.apf.field import Grid

#: A box as centre x, y and half sizes x, y [m].
Box = tuple[float, float, float, float]
#: The U trap of ``config/worlds/u_trap.xml`` (opening towards −x, the start side).
U_TRAP: tuple[Box, ...] = ((0.55, 0.0, 0.05, 0.35), (0.20, 0.35, 0.30, 0.05),
                           (0.20, -0.35, 0.30, 0.05))
#: The two obstacles of the coverage target (in a 2 m x 2 m area from (0, 0)).
TWO_OBSTACLES: tuple[Box, ...] = ((0.6, 0.6, 0.15, 0.15), (1.4, 1.3, 0.10, 0.20))


def box_grid(boxes: tuple[Box, ...], origin: tuple[float, float], size: tuple[float, float],
             resolution: float) -> Grid:
    """A grid of ``size`` (x, y [m]) from ``origin``: a cell is an obstacle when its centre
    lies inside one of the boxes."""
    cols, rows = (round(s / resolution) for s in size)
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    x = origin[0] + (jj + 0.5) * resolution
    y = origin[1] + (ii + 0.5) * resolution
    obstacle = np.zeros((rows, cols), dtype=bool)
    for cx, cy, hx, hy in boxes:
        obstacle |= (np.abs(x - cx) < hx) & (np.abs(y - cy) < hy)
    return Grid(obstacle, np.array(origin, dtype=float), resolution)
