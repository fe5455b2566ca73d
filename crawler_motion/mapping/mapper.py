"""The terrain mapper's core: odometry window, scan checks with counted reasons, fusion, obstacles.

`TerrainMapper.add_odometry` keeps the body poses of the last ``odom_window`` seconds that
`odometry.OdometryGate` accepts (a stale, future-stamped, absurd or jumping sample is refused
with its reason; a restarted odometry stream clears the map to unknown and is followed);
`TerrainMapper.add_scan` takes a scan (points in scanner_link and its stamp), finds the body
pose at its stamp, transforms the returns into the odom frame with their height variances, and
fuses them. The pose at a scan's stamp ``t`` (as tf2's message filter, on stamps only: the
core has no clock), with ``tol`` = ``pose_tolerance``:

- ``t`` within the odometry kept (oldest <= t <= newest): interpolated between the two samples
  bracketing ``t`` (position linear, rotation slerp); at a sample's stamp, that sample. When
  the two are more than ``2 tol`` apart (a gap in the odometry) the scan is skipped
  (``ODOMETRY_GAP``): the pose is never taken from a sample more than ``tol`` away from both
  sides.
- ``newest < t <= newest + tol``: the scan is held (`ScanFate.HELD`, at most ``scan_queue``
  scans; one more drops the oldest held, counted ``QUEUE_FULL``) until an odometry sample at
  or after ``t`` arrives; `add_odometry` then fuses it by the rule above.
- ``t > newest + tol`` (the odometry is later than the tolerance allows):
  ``AHEAD_OF_ODOMETRY``; ``t < oldest``: ``STALE``; no odometry yet: ``NO_ODOMETRY``.

`last_fused_stamp` is the stamp of the newest scan fused (None before the first and after an
odometry restart cleared the map): the age of the map's content, which the node publishes as
``map_load_time``. Every scan given to `add_scan` ends fused (`scans_fused`), skipped (its
`SkipReason` counted in `skipped`) or still held (`held`). Non-finite points of a usable scan
are left out and counted too. The map never holds NaN.
"""

from __future__ import annotations

import math
from bisect import bisect_left, insort
from collections import Counter, deque
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from crawler_motion.mapping.grid import ElevationGrid, FuseResult
from crawler_motion.mapping.obstacles import (
    face_cells,
    obstacle_cells,
    occupancy,
    uncertain_cells,
)
from crawler_motion.mapping.odometry import OdometryGate, OdometryLimits, OdometryVerdict
from crawler_motion.mapping.points import Mount, NoiseModel, returns_in_map
from crawler_motion.model.rotations import slerp_rotation


class ScanFate(Enum):
    """What `TerrainMapper.add_scan` did with a usable scan."""

    FUSED = "fused"
    HELD = "held until an odometry sample at or after its stamp arrives"


class SkipReason(Enum):
    """Why a scan was not fused (or, for ``NON_FINITE_POINTS``, why points were left out)."""

    EMPTY = "empty scan"
    NON_FINITE_POINTS = "non-finite points left out"
    ALL_NON_FINITE = "no finite point in the scan"
    NO_ODOMETRY = "no odometry yet"
    STALE = "scan older than the odometry window"
    AHEAD_OF_ODOMETRY = "scan newer than the latest odometry by more than the tolerance"
    ODOMETRY_GAP = "the odometry samples around the scan are more than 2 tolerances apart"
    QUEUE_FULL = "held scan dropped: more than scan_queue scans waiting for odometry"
    ODOMETRY_RESET = "held scan dropped: the odometry restarted (a new stream)"
    BAD_STAMP = "scan stamp not finite"
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
    scan_queue: int = 4  # scans held for odometry at most
    odometry: OdometryLimits = field(default_factory=OdometryLimits)  # plausible odometry

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


def interpolate_pose(before: Pose, after: Pose, stamp: float) -> Pose:
    """The pose at ``stamp`` [s] between two samples (``before.stamp <= stamp <= after.stamp``):
    position linear, rotation slerp; at either stamp that sample itself."""
    if stamp == before.stamp or after.stamp == before.stamp:
        return before
    if stamp == after.stamp:
        return after
    f = (stamp - before.stamp) / (after.stamp - before.stamp)
    return Pose(stamp, slerp_rotation(before.rotation, after.rotation, f),
                before.position + f * (after.position - before.position))


@dataclass(frozen=True)
class _HeldScan:
    stamp: float
    points: np.ndarray


class TerrainMapper:
    """Elevation grid fed by scans and odometry; obstacle cells on request."""

    def __init__(self, settings: MapperSettings, mount: Mount) -> None:
        self.settings, self.mount = settings, mount
        self.grid = self._new_grid()
        self.skipped: Counter[SkipReason] = Counter()
        self.scans_fused = 0
        self.last_fused_stamp: float | None = None  # [s]
        self.last_fuse: FuseResult | None = None
        self._poses: deque[Pose] = deque()
        self._held: list[_HeldScan] = []  # ordered by stamp
        self._last_position: np.ndarray | None = None
        self.gate = OdometryGate(settings.odometry)
        #: Odometry samples refused or reset, by verdict (`odometry.OdometryVerdict`).
        self.odometry_refused: Counter[OdometryVerdict] = Counter()

    @property
    def latest_pose(self) -> Pose | None:
        """The newest odometry sample."""
        return self._poses[-1] if self._poses else None

    @property
    def held(self) -> int:
        """Scans waiting for an odometry sample at or after their stamp."""
        return len(self._held)

    def add_odometry(self, pose: Pose, now: float | None = None) -> OdometryVerdict | None:
        """Keep a body pose that `odometry.OdometryGate` accepts (``now`` [s]: the receiver's
        clock, None: unchecked) and fuse the held scans it reaches (stamp <= its stamp), or
        skip them with their reason; a refused pose changes nothing. On ``RESET`` (a new
        odometry stream) the map, the poses and the held scans are cleared and the new
        stream's samples are kept. Returns None if accepted, else the verdict."""
        verdict = self.gate.check(pose, now)
        if verdict is OdometryVerdict.RESET:
            self.odometry_refused[verdict] += 1
            self._clear()
            for sample in self.gate.adopted:  # the new stream, already accepted by the gate
                self._keep(sample)  # type: ignore[arg-type]
            return verdict
        if verdict is not OdometryVerdict.ACCEPT:
            self.odometry_refused[verdict] += 1
            return verdict
        self._keep(pose)
        return None

    def _clear(self) -> None:
        """Forget the map, the odometry and the held scans (a new odometry stream)."""
        self.grid = self._new_grid()
        self._poses.clear()
        self.skipped[SkipReason.ODOMETRY_RESET] += len(self._held)
        self._held.clear()
        self._last_position = None
        self.last_fused_stamp = None

    def _new_grid(self) -> ElevationGrid:
        s = self.settings
        return ElevationGrid(s.resolution, s.cells, s.gate, s.drift, step=s.obstacle_height)

    def _keep(self, pose: Pose) -> None:
        """Append an accepted pose and fuse the held scans it reaches."""
        self._poses.append(pose)
        while self._poses and self._poses[0].stamp < pose.stamp - self.settings.odom_window:
            self._poses.popleft()
        if self._last_position is not None:
            self.grid.grow(float(np.linalg.norm(pose.position[:2] - self._last_position[:2])))
        self._last_position = pose.position
        self.grid.follow(float(pose.position[0]), float(pose.position[1]))
        while self._held and self._held[0].stamp <= pose.stamp:
            scan = self._held.pop(0)
            self._fuse(scan.points, scan.stamp)

    def pose_at(self, stamp: float) -> Pose | SkipReason:
        """The body pose at ``stamp`` [s], interpolated between the odometry samples around it
        (the rule of the module docstring), or why there is none yet or at all."""
        if not math.isfinite(stamp):
            return SkipReason.BAD_STAMP
        if not self._poses:
            return SkipReason.NO_ODOMETRY
        if stamp < self._poses[0].stamp:
            return SkipReason.STALE
        if stamp > self._poses[-1].stamp:
            return SkipReason.AHEAD_OF_ODOMETRY
        i = bisect_left(self._poses, stamp, key=lambda p: p.stamp)  # poses[i].stamp >= stamp
        after = self._poses[i]
        if after.stamp == stamp:
            return after
        before = self._poses[i - 1]
        if after.stamp - before.stamp > 2.0 * self.settings.pose_tolerance:
            return SkipReason.ODOMETRY_GAP
        return interpolate_pose(before, after, stamp)

    def add_scan(self, points: np.ndarray, stamp: float) -> ScanFate | SkipReason:
        """Fuse one scan (``(k, 3)`` scanner_link [m], stamp [s]) now, hold it for the odometry
        at its stamp, or skip it: the fate, or the reason when skipped."""
        if not math.isfinite(stamp):
            return self._skip(SkipReason.BAD_STAMP)
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if len(pts) == 0:
            return self._skip(SkipReason.EMPTY)
        finite = np.all(np.isfinite(pts), axis=1)
        if not finite.all():
            self.skipped[SkipReason.NON_FINITE_POINTS] += int((~finite).sum())
            pts = pts[finite]
            if len(pts) == 0:
                return self._skip(SkipReason.ALL_NON_FINITE)
        newest = self.latest_pose
        if newest is None or stamp <= newest.stamp:
            return self._fuse(pts, stamp)
        if stamp > newest.stamp + self.settings.pose_tolerance:
            return self._skip(SkipReason.AHEAD_OF_ODOMETRY)
        scan = _HeldScan(stamp, pts)
        insort(self._held, scan, key=lambda h: h.stamp)
        if len(self._held) > self.settings.scan_queue:  # drop the oldest held (maybe this one)
            dropped = self._held.pop(0)
            self._skip(SkipReason.QUEUE_FULL)
            if dropped is scan:
                return SkipReason.QUEUE_FULL
        return ScanFate.HELD

    def _fuse(self, pts: np.ndarray, stamp: float) -> ScanFate | SkipReason:
        pose = self.pose_at(stamp)
        if isinstance(pose, SkipReason):
            return self._skip(pose)
        p_m, var = returns_in_map(pts, self.mount, pose.rotation, pose.position,
                                  self.settings.noise)
        self.last_fuse = self.grid.fuse(p_m, var)
        self.scans_fused += 1
        self.last_fused_stamp = max(stamp, self.last_fused_stamp or -math.inf)
        return ScanFate.FUSED

    def _skip(self, reason: SkipReason) -> SkipReason:
        self.skipped[reason] += 1
        return reason

    def obstacles(self) -> np.ndarray:
        """Obstacle cells ``(rows y, cols x)`` by the rule of `obstacles`."""
        s, g = self.settings, self.grid
        return obstacle_cells(g.height, g.known, s.obstacle_height, self._radius_cells,
                              g.variance, s.confidence, face_cells(g.far, g.returns))

    @property
    def _radius_cells(self) -> int:
        return round(self.settings.ground_radius / self.settings.resolution)

    def occupancy(self) -> np.ndarray:
        """OccupancyGrid data (int8, rows y): 100 obstacle, 0 free, -1 unknown (or not below
        the threshold by the confidence margin: never free)."""
        g, s, obstacle = self.grid, self.settings, self.obstacles()
        uncertain = uncertain_cells(g.height, g.known, s.obstacle_height, self._radius_cells,
                                    obstacle, g.far, g.variance, s.confidence)
        return occupancy(g.known, obstacle, uncertain)
