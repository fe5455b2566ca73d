"""The improved potential field over an occupancy grid, for a disc robot (pure numpy).

The robot is a disc of radius ``R``; ``ρ(p)`` is the clearance of the disc centred at ``p``:
the distance from ``p`` to the nearest obstacle cell (a square of the grid) minus ``R``
(negative: the disc overlaps an obstacle cell). Obstacle cells whose four neighbours are all
obstacles are left out: they are never the nearest to a point outside the obstacles.

The potential is the sum of (SI units, ``d = |p_g − p|``):

- attraction to the goal: ``½ k_a d²`` within ``d_a`` of the goal, ``k_a d_a (d − d_a/2)``
  beyond (the classic quadratic well, conic away from it); ``k_a = 1/d_a``, so the pull is 1
  beyond ``d_a``. *Choice:* ``d_a`` = 0.02 m, about two steps: with a quadratic well of metres
  the goal's pull fades near the goal and the obstacle attraction (at most ``k_o`` < 1) would
  hold the path off a goal near a structure;
- repulsion (Khatib): ``½ k_r (1/ρ − 1/ρ_o)²`` for ``0 < ρ < ρ_o``, 0 beyond, +inf at
  ``ρ ≤ 0``; ``k_r = κ_r ρ_o³`` so the field keeps its shape when ρ_o changes;
- obstacle attraction (stand-off, the study's addition, form chosen here): in the band
  ``ρ_o < ρ < ρ_a`` (``ρ_a = band · ρ_o``) ``k_o w/π (1 − cos(π (ρ − ρ_o)/w))``, ``w = ρ_a − ρ_o``,
  and ``2 k_o w/π`` beyond: a pull towards the obstacle rising from 0 at ρ_o to ``k_o`` mid-band
  and back to 0 at ρ_a, continuous everywhere. Below ρ_o the repulsion pushes out, above it the
  attraction pulls in: the path settles at ρ_o.

Every function takes points ``(..., 2)`` and is vectorised (no per-point Python loop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crawler_motion.errors import ConfigError

#: Point-cell pairs per chunk / 64 of the distance computation (~4 MB per array).
CHUNK = 4096


@dataclass(frozen=True)
class FieldSettings:
    """Field gains and ranges (SI units)."""

    standoff: float = 0.10  # ρ_o [m]
    band: float = 2.0  # ρ_a / ρ_o
    repulsion: float = 1.0  # κ_r: k_r = κ_r ρ_o³
    attraction: float = 0.4  # k_o, the obstacle attraction's largest pull (0: none)
    goal_range: float = 0.02  # d_a [m]

    def __post_init__(self) -> None:
        for name in ("standoff", "repulsion", "goal_range"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"field {name} must be a finite number > 0, got {value}")
        if not (math.isfinite(self.band) and self.band > 1):
            raise ConfigError(f"field band must be > 1 (ρ_a = band · ρ_o), got {self.band}")
        if not (math.isfinite(self.attraction) and 0 <= self.attraction < 1):
            raise ConfigError("field attraction must be in [0, 1) (below the goal's pull), "
                              f"got {self.attraction}")


@dataclass(frozen=True)
class Grid:
    """An occupancy grid: ``obstacle[row, col]`` (rows along y), corner ``origin`` (x, y) [m],
    square cells of ``resolution`` [m]."""

    obstacle: np.ndarray
    origin: np.ndarray
    resolution: float

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """x0, x1, y0, y1 of the map [m]."""
        rows, cols = self.obstacle.shape
        x0, y0 = float(self.origin[0]), float(self.origin[1])
        return x0, x0 + cols * self.resolution, y0, y0 + rows * self.resolution

    def inside(self, p: np.ndarray) -> np.ndarray:
        """True where the points ``(..., 2)`` lie on the map."""
        x0, x1, y0, y1 = self.extent
        p = np.asarray(p, dtype=float)
        return (p[..., 0] >= x0) & (p[..., 0] < x1) & (p[..., 1] >= y0) & (p[..., 1] < y1)

    def occupied(self, p: np.ndarray) -> np.ndarray:
        """True where the points ``(..., 2)`` fall in an obstacle cell (False off the map)."""
        p = np.asarray(p, dtype=float)
        ij = np.floor((p - self.origin) / self.resolution).astype(np.int64)
        ok = self.inside(p)
        rows, cols = self.obstacle.shape
        i = np.clip(ij[..., 1], 0, rows - 1)
        j = np.clip(ij[..., 0], 0, cols - 1)
        return ok & self.obstacle[i, j]

    def centres(self) -> np.ndarray:
        """Centres ``(rows, cols, 2)`` of every cell [m]."""
        rows, cols = self.obstacle.shape
        jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
        return self.origin + (np.stack((jj, ii), axis=-1) + 0.5) * self.resolution


def boundary_cells(obstacle: np.ndarray) -> np.ndarray:
    """Obstacle cells with at least one non-obstacle 4-neighbour (or on the map's edge)."""
    padded = np.pad(obstacle, 1, constant_values=False)
    inner = (padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:])
    return obstacle & ~inner


class ObstacleField:
    """Clearance of the disc and the improved field on one grid."""

    def __init__(self, grid: Grid, radius: float, settings: FieldSettings) -> None:
        if not (math.isfinite(radius) and radius >= 0):
            raise ConfigError(f"robot radius must be a finite number >= 0, got {radius}")
        self.grid, self.radius, self.settings = grid, float(radius), settings
        rows, cols = np.nonzero(boundary_cells(grid.obstacle))
        self.cells = grid.origin + (np.column_stack((cols, rows)) + 0.5) * grid.resolution
        self._cx, self._cy = self.cells[:, 0].copy(), self.cells[:, 1].copy()
        self._last: tuple[tuple[float, float], float, tuple[float, float]] | None = None

    def clearance(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ρ ``(...)`` [m] and its gradient ``(..., 2)`` at the points ``(..., 2)``; +inf and 0
        without obstacle cells."""
        p = np.asarray(p, dtype=float)
        if p.shape == (2,) and len(self.cells):
            rho, gx, gy = self._one(float(p[0]), float(p[1]))
            return np.asarray(rho), np.array([gx, gy])
        flat = p.reshape(-1, 2)
        rho = np.full(len(flat), math.inf)
        grad = np.zeros_like(flat)
        if len(self.cells):
            half = self.grid.resolution / 2
            step = max(1, CHUNK * 64 // len(self.cells))
            for k in range(0, len(flat), step):
                q = flat[k:k + step]
                d = q[:, None, :] - self.cells[None, :, :]
                out = np.maximum(np.abs(d) - half, 0.0) * np.sign(d)
                dist = np.hypot(out[..., 0], out[..., 1])
                nearest = np.argmin(dist, axis=1)
                rows = np.arange(len(q))
                near = dist[rows, nearest]
                rho[k:k + len(q)] = near
                grad[k:k + len(q)] = out[rows, nearest] / np.where(near > 0, near, 1.0)[:, None]
        return (rho - self.radius).reshape(p.shape[:-1]), grad.reshape(p.shape)

    def _one(self, px: float, py: float) -> tuple[float, float, float]:
        """`clearance` of one point (the planner's step: the same arithmetic on 1-D arrays,
        the last point remembered, as a step's check and the next step's field share it)."""
        last = self._last
        if last is not None and last[0] == (px, py):
            return last[1], *last[2]
        half = self.grid.resolution / 2
        dx, dy = px - self._cx, py - self._cy
        ox = np.maximum(np.abs(dx) - half, 0.0)
        oy = np.maximum(np.abs(dy) - half, 0.0)
        d2 = ox * ox + oy * oy
        k = int(np.argmin(d2))
        near = math.sqrt(float(d2[k]))
        scale = near if near > 0 else 1.0
        gx = float(ox[k]) * float(np.sign(dx[k])) / scale
        gy = float(oy[k]) * float(np.sign(dy[k])) / scale
        rho = near - self.radius
        self._last = ((px, py), rho, (gx, gy))
        return rho, gx, gy

    def obstacle_potential(self, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Repulsion + obstacle attraction as a function of ρ: value and dU/dρ."""
        s = self.settings
        rho = np.asarray(rho, dtype=float)
        k_r, w = s.repulsion * s.standoff ** 3, (s.band - 1.0) * s.standoff
        safe = np.where(rho > 0, rho, 1.0)
        inv = 1.0 / safe - 1.0 / s.standoff
        near = (rho > 0) & (rho < s.standoff)
        u = np.where(near, 0.5 * k_r * inv ** 2, 0.0)
        du = np.where(near, -k_r * inv / safe ** 2, 0.0)
        phase = np.clip((rho - s.standoff) / w, 0.0, 1.0) * math.pi
        u = u + s.attraction * w / math.pi * (1.0 - np.cos(phase))
        du = du + np.where((rho > s.standoff) & (rho < s.band * s.standoff),
                           s.attraction * np.sin(phase), 0.0)
        return np.where(rho > 0, u, math.inf), du

    def goal_potential(self, p: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Attraction to ``goal``: value ``(...)`` and gradient ``(..., 2)``."""
        d_a = self.settings.goal_range
        diff = np.asarray(p, dtype=float) - np.asarray(goal, dtype=float)
        d = np.hypot(diff[..., 0], diff[..., 1])
        near = d <= d_a
        u = np.where(near, 0.5 * d ** 2 / d_a, d - d_a / 2)
        scale = np.where(near, 1.0 / d_a, 1.0 / np.where(d > 0, d, 1.0))
        return u, diff * scale[..., None]

    def potential(self, p: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Total potential ``(...)`` and its gradient ``(..., 2)`` at the points ``(..., 2)``."""
        rho, grad_rho = self.clearance(p)
        u_o, du_o = self.obstacle_potential(rho)
        u_g, grad_g = self.goal_potential(p, goal)
        return u_o + u_g, grad_g + du_o[..., None] * grad_rho

    def obstacle_force(self, p: np.ndarray) -> np.ndarray:
        """−∇ of the obstacle terms alone ``(..., 2)`` (used when following a structure)."""
        rho, grad_rho = self.clearance(p)
        return -self.obstacle_potential(rho)[1][..., None] * grad_rho

    def on_grid(self, goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The potential and its gradient at every cell centre (rows, cols) — for pictures."""
        return self.potential(self.grid.centres(), goal)
