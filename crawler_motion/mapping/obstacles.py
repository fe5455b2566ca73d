"""Obstacle cells (spec §3): cells the crawler cannot step over.

The rule used here: a known cell is an obstacle when its height exceeds the local ground by
more than ``threshold`` [m], the local ground being the lowest known height within
``ground_radius`` [m] (a square window) around it. This marks a whole box or wall (its top
and its faces), not only its edges as the neighbour-step rule would, as long as the window
reaches ground beside it. The threshold for the crawler is the smaller of its foot clearance
(lift + arc) and its belly clearance (`step_threshold`). A cell must also clear the
threshold by ``confidence`` standard deviations of its fused height, so a cell seen once
through a pose error is not an obstacle until more returns agree. Unknown cells are neither
free nor obstacle.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from crawler_motion.model.config import Config

#: Half the hull height [m] (the hull box of the seabed model is 0.05 m high).
HULL_HALF_HEIGHT = 0.025


def step_threshold(cfg: Config) -> float:
    """Highest step the crawler walks over [m]: min(lift + arc, belly clearance)."""
    clearance = cfg.gait.lift + cfg.gait.arc
    belly = cfg.robot.body_height - HULL_HALF_HEIGHT
    return float(min(clearance, belly))


def local_ground(height: np.ndarray, known: np.ndarray, radius_cells: int) -> np.ndarray:
    """Lowest known height within ``radius_cells`` of each cell (+inf where none) [m]."""
    lowest = np.where(known, height, np.inf)
    if radius_cells <= 0:
        return lowest
    k = 2 * radius_cells + 1
    padded = np.pad(lowest, ((radius_cells, radius_cells), (0, 0)), constant_values=np.inf)
    lowest = sliding_window_view(padded, k, axis=0).min(axis=-1)
    padded = np.pad(lowest, ((0, 0), (radius_cells, radius_cells)), constant_values=np.inf)
    return sliding_window_view(padded, k, axis=1).min(axis=-1)


def obstacle_cells(height: np.ndarray, known: np.ndarray, threshold: float,
                   radius_cells: int, variance: np.ndarray | None = None,
                   confidence: float = 0.0) -> np.ndarray:
    """Boolean ``(rows, cols)``: known cells higher than their local ground by more than
    ``threshold + confidence × σ_h`` (σ_h from ``variance``; 0 without it)."""
    ground = local_ground(height, known, radius_cells)
    margin = threshold if variance is None else threshold + confidence * np.sqrt(
        np.where(known, variance, 0.0))
    return known & (height - ground > margin)


def occupancy(known: np.ndarray, obstacle: np.ndarray) -> np.ndarray:
    """OccupancyGrid values (int8): 100 obstacle, 0 free, -1 unknown."""
    out = np.full(known.shape, -1, dtype=np.int8)
    out[known] = 0
    out[obstacle] = 100
    return out
