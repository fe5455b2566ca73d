"""The navigator's map from the mapper's messages (as arrays): occupancy and heights (pure)."""

from __future__ import annotations

import numpy as np

from crawler_motion.errors import CommandError
from crawler_motion.navigation.navigator import TerrainView

#: Height [m] given to obstacle cells when no height cloud has arrived.
OBSTACLE_PROXY_HEIGHT = 1.0


def view_from_grid(origin: tuple[float, float], resolution: float, width: int, height: int,
                   data: np.ndarray, heights: np.ndarray | None) -> TerrainView:
    """A `TerrainView` from OccupancyGrid fields (``data`` row-major int8: 100 obstacle, 0
    free, -1 unknown) and optional cell heights ``(k, 4)`` (x, y, z, variance in the same
    frame; cells outside the grid are ignored). Raises `CommandError` for an inconsistent grid.
    """
    grid = np.asarray(data, dtype=np.int16)
    if width <= 0 or height <= 0 or grid.size != width * height or not resolution > 0:
        raise CommandError(f"terrain_map is inconsistent: {width} x {height} cells of "
                           f"{resolution} m with {grid.size} values")
    grid = grid.reshape(height, width)
    known, obstacle = grid >= 0, grid >= 100
    level = np.where(obstacle, OBSTACLE_PROXY_HEIGHT, 0.0)
    o = np.array(origin, dtype=float)
    if heights is not None and len(heights):
        ij = np.floor((heights[:, :2] - o) / resolution).astype(np.int64)
        ok = (np.all(np.isfinite(heights[:, :3]), axis=1) & (ij[:, 0] >= 0)
              & (ij[:, 0] < width) & (ij[:, 1] >= 0) & (ij[:, 1] < height))
        level[ij[ok, 1], ij[ok, 0]] = heights[ok, 2]
    return TerrainView(o, float(resolution), known, obstacle, level)
