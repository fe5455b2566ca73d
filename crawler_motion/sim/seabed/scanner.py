"""Forward range scanner: a fan of rays from the hull-front mount, cast with ``mj_multiRay``.

The scanner frame ``scanner_link`` is REP-103 (x along the central ray, y left, z up), placed in
``base_link`` by the ``scanner`` section of ``config/robot.yaml``. Rays form ``rows`` elevation
rows (``vertical_fov``, + up) of ``columns`` azimuths (``horizontal_fov``, + left), row-major,
bottom row first. The robot's geom group is excluded, so the robot never sees itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import ScannerConfig
from crawler_motion.model.rotations import rpy_matrix
from crawler_motion.sim.seabed.model import SeabedModel
from crawler_motion.sim.seabed.water import check_range


@dataclass(frozen=True)
class ScannerSettings:
    """Measurement imperfections of the scanner (SI units).

    ``range_noise``: standard deviation of the range error [m]; ``dropout``: probability that a
    ray returns nothing; ``max_range``: turbidity limit [m] (None: the mount's ``max_range``);
    ``seed``: of the noise generator (repeatable scans).
    """

    range_noise: float = 0.005
    dropout: float = 0.0
    max_range: float | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        check_range("range_noise", self.range_noise, 0.0, 1.0, "m")
        check_range("dropout", self.dropout, 0.0, 1.0, "")
        if self.max_range is not None:
            check_range("max_range", self.max_range, 1e-3, 1e3, "m")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise ConfigError(f"seed must be an integer, got {self.seed!r}")


def fan_directions(mount: ScannerConfig) -> np.ndarray:
    """Unit ray directions in scanner_link, ``(rows * columns, 3)``, bottom row first."""
    def spread(fov: float, n: int) -> np.ndarray:
        return np.linspace(-fov / 2, fov / 2, n) if n > 1 else np.zeros(1)

    elev, azim = np.meshgrid(spread(mount.vertical_fov, mount.rows),
                             spread(mount.horizontal_fov, mount.columns), indexing="ij")
    return np.stack((np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)),
                    axis=-1).reshape(-1, 3)


class RangeScanner:
    """Casts the fan from the robot's current pose and returns noisy points."""

    def __init__(self, sm: SeabedModel, mount: ScannerConfig,
                 settings: ScannerSettings | None = None) -> None:
        self.sm, self.mount = sm, mount
        self.settings = settings or ScannerSettings()
        self.max_range = float(self.settings.max_range or mount.max_range)
        self.directions = fan_directions(mount)
        self.rotation = rpy_matrix(mount.rpy)  # scanner_link -> base_link
        self.geomgroup = sm.world_groups()
        n = len(self.directions)
        self._geomid = np.zeros(n, dtype=np.int32)
        self._dist = np.zeros(n)
        self._rng = np.random.default_rng(self.settings.seed)

    def pose(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """Origin [m] and rotation (scanner_link -> world) of the scanner now."""
        rot = data.xmat[self.sm.base_body].reshape(3, 3)
        return data.xpos[self.sm.base_body] + rot @ self.mount.position, rot @ self.rotation

    def ranges(self, data: mujoco.MjData) -> np.ndarray:
        """Measured range of every ray ``(rows * columns,)`` [m]; NaN where nothing returns."""
        origin, rot = self.pose(data)
        vec = (self.directions @ rot.T).ravel()
        mujoco.mj_multiRay(self.sm.model, data, origin, vec, self.geomgroup, 1, -1,
                           self._geomid, self._dist, None, len(self.directions), self.max_range)
        s = self.settings
        noisy = self._dist + self._rng.normal(0.0, s.range_noise, self._dist.shape)
        lost = self._rng.random(self._dist.shape) < s.dropout
        valid = (self._geomid >= 0) & (self._dist <= self.max_range) & ~lost & (noisy > 0)
        return np.where(valid, noisy, np.nan)

    def points(self, data: mujoco.MjData) -> np.ndarray:
        """Returned points ``(k, 3)`` in scanner_link (x, y, z) [m]; lost rays left out."""
        rng = self.ranges(data)
        keep = np.isfinite(rng)
        return self.directions[keep] * rng[keep, None]
