"""The terrain mapper's core: odometry window, scan checks with counted reasons, fusion, obstacles.

`TerrainMapper.add_odometry` keeps the body poses of the last ``odom_window`` seconds;
`TerrainMapper.add_scan` takes a scan (points in scanner_link and its stamp), finds the body
pose at its stamp (the nearest odometry sample, at most ``pose_tolerance`` away), transforms
the returns into the odom frame with their height variances, and fuses them. A scan that
cannot be used is skipped and its `SkipReason` counted; non-finite points of a usable scan are
left out and counted too. The map never holds NaN.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections import Counter, deque
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from crawler_motion.mapping.grid import ElevationGrid, FuseResult
from crawler_motion.mapping.obstacles import obstacle_cells, occupancy
from crawler_motion.mapping.points import Mount, NoiseModel, returns_in_map


class SkipReason(Enum):
    """Why a scan was not fused (or, for ``NON_FINITE_POINTS``, why points were left out)."""

    EMPTY = "empty scan"
    NON_FINITE_POINTS = "non-finite points left out"
    ALL_NON_FINITE = "no finite point in the scan"
    NO_ODOMETRY = "no odometry yet"
    STALE = "scan older than the odometry window"
    AHEAD_OF_ODOMETRY = "scan newer than the latest odometry by more than the tolerance"
    BAD_POSE = "odometry pose not finite"
    MALFORMED = "not an x y z float32 cloud in the scanner frame"


@dataclass(frozen=True)
class MapperSettings:
    """Grid, noise, gate, drift and obstacle rule of the mapper (SI units)."""

    resolution: float = 0.05  # [m]
    size: float = 4.0  # side of the window [m]
    gate: float = 2.5  # Mahalanobis gate
    drift: float = 1e-5  # variance growth per metre of travel [m²/m]
    noise: NoiseModel = field(default_factory=lambda: NoiseModel(attitude_noise=0.02))
    obstacle_height: float = 0.02  # [m]
    confidence: float = 2.0  # standard deviations of a cell's height above the threshold
    ground_radius: float = 0.25  # [m]
    odom_window: float = 1.0  # [s]
    pose_tolerance: float = 0.05  # [s]

    @property
    def cells(self) -> int:
        """Cells along a side."""
        return max(3, round(self.size / self.resolution))


@dataclass(frozen=True)
class Pose:
    """Body pose at ``stamp`` [s]: rotation base_link -> odom and position [m]."""

    stamp: float
    rotation: np.ndarray
    position: np.ndarray


class TerrainMapper:
    """Elevation grid fed by scans and odometry; obstacle cells on request."""

    def __init__(self, settings: MapperSettings, mount: Mount) -> None:
        self.settings, self.mount = settings, mount
        self.grid = ElevationGrid(settings.resolution, settings.cells, settings.gate,
                                  settings.drift)
        self.skipped: Counter[SkipReason] = Counter()
        self.scans_fused = 0
        self.last_fuse: FuseResult | None = None
        self._poses: deque[Pose] = deque()
        self._last_position: np.ndarray | None = None

    @property
    def latest_pose(self) -> Pose | None:
        """The newest odometry sample."""
        return self._poses[-1] if self._poses else None

    def add_odometry(self, pose: Pose) -> SkipReason | None:
        """Keep a body pose (stamps must increase; an older one is refused as STALE)."""
        if not (np.all(np.isfinite(pose.rotation)) and np.all(np.isfinite(pose.position))
                and math.isfinite(pose.stamp)):
            self.skipped[SkipReason.BAD_POSE] += 1
            return SkipReason.BAD_POSE
        if self._poses and pose.stamp <= self._poses[-1].stamp:
            self.skipped[SkipReason.STALE] += 1
            return SkipReason.STALE
        self._poses.append(pose)
        while self._poses and self._poses[0].stamp < pose.stamp - self.settings.odom_window:
            self._poses.popleft()
        if self._last_position is not None:
            self.grid.grow(float(np.linalg.norm(pose.position[:2] - self._last_position[:2])))
        self._last_position = pose.position
        self.grid.follow(float(pose.position[0]), float(pose.position[1]))
        return None

    def pose_at(self, stamp: float) -> Pose | SkipReason:
        """The odometry sample nearest ``stamp`` [s], or why there is none."""
        if not self._poses:
            return SkipReason.NO_ODOMETRY
        tol = self.settings.pose_tolerance
        if stamp < self._poses[0].stamp - tol:
            return SkipReason.STALE
        if stamp > self._poses[-1].stamp + tol:
            return SkipReason.AHEAD_OF_ODOMETRY
        stamps = [p.stamp for p in self._poses]
        i = bisect_left(stamps, stamp)
        near = [j for j in (i - 1, i) if 0 <= j < len(stamps)]
        return self._poses[min(near, key=lambda j: abs(stamps[j] - stamp))]

    def add_scan(self, points: np.ndarray, stamp: float) -> SkipReason | None:
        """Fuse one scan (``(k, 3)`` scanner_link [m], stamp [s]); the reason when skipped."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if len(pts) == 0:
            return self._skip(SkipReason.EMPTY)
        finite = np.all(np.isfinite(pts), axis=1)
        if not finite.all():
            self.skipped[SkipReason.NON_FINITE_POINTS] += int((~finite).sum())
            pts = pts[finite]
            if len(pts) == 0:
                return self._skip(SkipReason.ALL_NON_FINITE)
        pose = self.pose_at(stamp)
        if isinstance(pose, SkipReason):
            return self._skip(pose)
        p_m, var = returns_in_map(pts, self.mount, pose.rotation, pose.position,
                                  self.settings.noise)
        self.last_fuse = self.grid.fuse(p_m, var)
        self.scans_fused += 1
        return None

    def _skip(self, reason: SkipReason) -> SkipReason:
        self.skipped[reason] += 1
        return reason

    def obstacles(self) -> np.ndarray:
        """Obstacle cells ``(rows y, cols x)`` by the rule of `obstacles`."""
        s, g = self.settings, self.grid
        return obstacle_cells(g.height, g.known, s.obstacle_height,
                              round(s.ground_radius / s.resolution), g.variance, s.confidence)

    def occupancy(self) -> np.ndarray:
        """OccupancyGrid data (int8, rows y): 100 obstacle, 0 free, -1 unknown."""
        return occupancy(self.grid.known, self.obstacles())
