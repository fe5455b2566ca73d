"""A synthetic scanner for the mapping tests: the configured mount, a denser fan, an analytic
world of a plane at z = 0 and axis-aligned boxes."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from crawler_motion.mapping.points import Mount
from crawler_motion.model.config import load_scanner
from crawler_motion.model.rotations import rpy_matrix

Box = tuple[tuple[float, float, float], tuple[float, float, float]]  # (min xyz, max xyz) [m]


def fan(rows: int = 21, columns: int = 61, vfov: float = 0.5, hfov: float = 1.6) -> np.ndarray:
    elev, azim = np.meshgrid(np.linspace(-vfov / 2, vfov / 2, rows),
                             np.linspace(-hfov / 2, hfov / 2, columns), indexing="ij")
    return np.stack((np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)),
                    axis=-1).reshape(-1, 3)


def cast(origin: np.ndarray, dirs: np.ndarray, boxes: list[Box], max_range: float = 3.0
         ) -> np.ndarray:
    """Range along each unit ray ``dirs`` (world) from ``origin`` to the first hit (inf: none)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(dirs[:, 2] < 0, -origin[2] / dirs[:, 2], np.inf)
        for lo, hi in boxes:
            t1 = (np.array(lo) - origin) / dirs
            t2 = (np.array(hi) - origin) / dirs
            near = np.nanmax(np.minimum(t1, t2), axis=1)
            far = np.nanmin(np.maximum(t1, t2), axis=1)
            hit = (far >= near) & (near > 0)
            t = np.where(hit & (near < t), near, t)
    return np.where(t <= max_range, t, np.inf)


@pytest.fixture
def mount() -> Mount:
    sc = load_scanner()
    return Mount(rotation=rpy_matrix(sc.rpy), position=sc.position)


@pytest.fixture
def scan_at(mount: Mount) -> Callable[..., np.ndarray]:
    """Points in scanner_link seen from body position (x, y, z) with yaw 0 (or the body
    ``rotation`` base_link -> world), with range noise."""
    dirs = fan()

    def scan(body: tuple[float, float, float], boxes: list[Box], noise: float = 0.0,
             rng: np.random.Generator | None = None, rotation: np.ndarray | None = None
             ) -> np.ndarray:
        body_rot = np.eye(3) if rotation is None else rotation
        origin = np.array(body) + body_rot @ mount.position
        world = dirs @ (body_rot @ mount.rotation).T
        t = cast(origin, world, boxes)
        keep = np.isfinite(t)
        r = t[keep]
        if noise > 0:
            r = r + (rng or np.random.default_rng(0)).normal(0.0, noise, r.shape)
        return dirs[keep] * r[:, None]

    return scan
