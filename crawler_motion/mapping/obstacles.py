"""Obstacle cells (spec §3): cells the crawler cannot step over.

The rule used here: a known cell is an obstacle when its height exceeds the local ground by
more than ``threshold`` [m], the local ground being the lowest known height within
``ground_radius`` [m] (a square window) around it. This marks a whole box or wall (its top
and its faces), not only its edges as the neighbour-step rule would, as long as the window
reaches ground beside it. The threshold for the crawler is the smaller of its foot clearance
(lift + arc) and its belly clearance (`step_threshold`). A cell must also clear the
threshold by ``confidence`` standard deviations of its fused height, so a cell seen once
through a pose error is not an obstacle until more returns agree.

A face is an obstacle too (`face_cells`): a known cell with at least ``FACE_MIN_RETURNS``
returns, and at least ``FACE_SHARE`` of all its returns, more than ``threshold`` from its
estimate (`grid.ElevationGrid.far`) holds a step the crawler cannot take within one cell,
whatever its fused height (the mean of its foot and its top) says. Gated returns inflate a
face cell's variance, so the height rule alone fails there.

Occupancy: 100 obstacle; -1 unknown, which includes a known cell that is not below the
threshold by the confidence margin (``height above ground + confidence × σ_h > threshold``),
or that has a return far from its estimate without being a face yet (`uncertain_cells`:
never called free); 0 free. *Rule chosen*: free needs the same confidence as an obstacle. A
real-time U-trap run published a cell inside a wall as free: it held 3 returns from the foot
of the wall's outer face (11, 12 and 40 mm high; the third gated out, σ_h grown to 31 mm), so
its fused height 11.5 mm was below the 20 mm threshold although its σ_h was larger than the
threshold. Now such a cell is unknown; a flat cell seen a few times near the robot (σ_h a few
mm) stays free. The navigator walks unknown cells as free ones, so only the map's word
changes.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from crawler_motion.model.config import Config

#: A face needs this many returns far from the cell's estimate (one or two strays are not)...
FACE_MIN_RETURNS = 3
#: ... and this share of all the cell's returns.
FACE_SHARE = 0.1
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


def above_ground(height: np.ndarray, known: np.ndarray, radius_cells: int) -> np.ndarray:
    """Height of every known cell above its local ground [m] (-inf where unknown)."""
    rise = height - local_ground(height, known, radius_cells)
    return np.where(known, rise, -np.inf)


def obstacle_cells(height: np.ndarray, known: np.ndarray, threshold: float,
                   radius_cells: int, variance: np.ndarray | None = None,
                   confidence: float = 0.0, face: np.ndarray | None = None) -> np.ndarray:
    """Boolean ``(rows, cols)``: known cells higher than their local ground by more than
    ``threshold + confidence × σ_h`` (σ_h from ``variance``; 0 without it), or faces
    (``face``, from `face_cells`)."""
    margin = threshold if variance is None else threshold + confidence * np.sqrt(
        np.where(known, variance, 0.0))
    obstacle = known & (above_ground(height, known, radius_cells) > margin)
    if face is not None:
        obstacle |= known & face
    return obstacle


def face_cells(far: np.ndarray, returns: np.ndarray) -> np.ndarray:
    """Cells whose returns disagree: ``far`` returns (more than the threshold from the cell's
    estimate) at least `FACE_MIN_RETURNS` and `FACE_SHARE` of ``returns``."""
    return (far >= FACE_MIN_RETURNS) & (far >= FACE_SHARE * returns)


def uncertain_cells(height: np.ndarray, known: np.ndarray, threshold: float,
                    radius_cells: int, obstacle: np.ndarray,
                    far: np.ndarray | None = None, variance: np.ndarray | None = None,
                    confidence: float = 0.0) -> np.ndarray:
    """Known cells that are not obstacles but not below the threshold by ``confidence`` σ_h
    of their height (σ_h from ``variance``; 0 without it), or with a return far from their
    estimate (``far`` counts): published as unknown, never free."""
    sigma = 0.0 if variance is None else np.sqrt(np.where(known, variance, 0.0))
    doubt = above_ground(height, known, radius_cells) + confidence * sigma > threshold
    if far is not None:
        doubt |= known & (far > 0)
    return ~obstacle & doubt


def occupancy(known: np.ndarray, obstacle: np.ndarray,
              uncertain: np.ndarray | None = None) -> np.ndarray:
    """OccupancyGrid values (int8): 100 obstacle, 0 free, -1 unknown (and ``uncertain``)."""
    out = np.full(known.shape, -1, dtype=np.int8)
    out[known] = 0
    if uncertain is not None:
        out[uncertain] = -1
    out[obstacle] = 100
    return out
