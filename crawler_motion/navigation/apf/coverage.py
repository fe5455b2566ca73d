"""Coverage of a rectangular seabed area in slices (the study's §3 on a 2-D map, pure).

The area is cut into ``n = ceil(height / spacing)`` parallel slices along x, evenly spread
(slice k at ``y0 + (k + ½) · height / n``, so neighbours are at most ``spacing`` apart). Slice
after slice, alternating direction (boustrophedon), the improved field with virtual goals plans
from the end of the previous slice to the start of this one and then along it; obstacles on the
slice are passed at the stand-off distance. *Rules:* a slice end where the disc is not ρ_o
clear of the obstacles moves along the slice towards the area's inside to the first point
where it is; a slice with no such point is skipped (and reported); a leg that ends trapped
keeps its path, is reported, and the route goes on from where it stopped. Covered: the free
cells of the area within ``footprint`` of the route (the sensor or tool footprint, a disc);
overlap: the share of the covered cells covered by more than one slice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from crawler_motion.errors import CommandError
from crawler_motion.navigation.apf.field import ObstacleField
from crawler_motion.navigation.apf.planner import ApfMethod, PlanSettings, densify, plan


@dataclass
class CoverageResult:
    """The route ``(n, 2)`` [m], the covered share and overlap of the area's free cells, the
    route length [m], and what went wrong on the way (skipped slices, trapped legs)."""

    route: np.ndarray
    share: float
    overlap: float
    length: float
    slices: int
    problems: list[str] = field(default_factory=list)


def _check_area(fld: ObstacleField, area: tuple[float, float, float, float], spacing: float,
                footprint: float) -> None:
    values = (*area, spacing, footprint)
    if not all(math.isfinite(v) for v in values):
        raise CommandError(f"area, spacing and footprint must be finite, got {values}")
    x0, y0, x1, y1 = area
    if not (x1 > x0 and y1 > y0 and spacing > 0 and footprint > 0):
        raise CommandError("the area needs x1 > x0 and y1 > y0, spacing and footprint > 0 m")
    if not (fld.grid.inside(np.array([x0, y0])) and fld.grid.inside(np.array([x1, y1]) - 1e-9)):
        raise CommandError(f"the area [{x0:g}, {x1:g}] x [{y0:g}, {y1:g}] m is not on the map")


def _slice_ends(fld: ObstacleField, y: float, x0: float, x1: float
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """The first and last points of the slice at ``y`` where the disc is ρ_o clear."""
    xs = np.arange(x0, x1 + 1e-9, fld.grid.resolution / 2)
    pts = np.column_stack((xs, np.full_like(xs, y)))
    ok = np.flatnonzero(fld.clearance(pts)[0] >= fld.settings.standoff)
    return None if not len(ok) else (pts[ok[0]], pts[ok[-1]])


def covered_cells(fld: ObstacleField, legs: list[np.ndarray], area: tuple[float, ...],
                  footprint: float) -> tuple[np.ndarray, np.ndarray]:
    """Per free cell of the area (centres ``(k, 2)``): how many legs cover it ``(k,)``."""
    x0, y0, x1, y1 = area
    c = fld.grid.centres()
    inside = ((c[..., 0] >= x0) & (c[..., 0] <= x1) & (c[..., 1] >= y0) & (c[..., 1] <= y1)
              & ~fld.grid.obstacle)
    cells = c[inside]
    count = np.zeros(len(cells), dtype=int)
    for leg in legs:
        pts = densify(leg, fld.grid.resolution / 2)
        hit = np.zeros(len(cells), dtype=bool)
        for k in range(0, len(pts), 256):
            diff = cells[:, None, :] - pts[None, k:k + 256, :]
            hit |= (np.hypot(diff[..., 0], diff[..., 1]) <= footprint).any(axis=1)
        count += hit
    return cells, count


def cover(fld: ObstacleField, area: tuple[float, float, float, float], spacing: float,
          footprint: float, settings: PlanSettings | None = None) -> CoverageResult:
    """The coverage route of ``area`` (x0, y0, x1, y1 [m]) with slices ``spacing`` apart."""
    _check_area(fld, area, spacing, footprint)
    x0, y0, x1, y1 = area
    n = math.ceil((y1 - y0) / spacing - 1e-9)
    route: list[np.ndarray] = []
    legs: list[np.ndarray] = []
    problems: list[str] = []
    for k in range(n):
        y = y0 + (k + 0.5) * (y1 - y0) / n
        ends = _slice_ends(fld, y, x0, x1)
        if ends is None:
            problems.append(f"slice {k} at y = {y:.3f} m skipped: no clear point")
            continue
        a, b = ends if k % 2 == 0 else ends[::-1]
        pieces = [a[None, :]]
        if route:
            res = plan(fld, route[-1][-1], a, ApfMethod.APF_VIRTUAL, settings)
            if not res.reached:
                problems.append(f"to slice {k}: trapped ({res.reason})")
            pieces = [res.path]
        res = plan(fld, pieces[-1][-1], b, ApfMethod.APF_VIRTUAL, settings)
        if not res.reached:
            problems.append(f"slice {k}: trapped ({res.reason})")
        leg = np.vstack([*pieces, res.path])
        legs.append(leg)
        route.append(leg)
    if not route:
        raise CommandError("no slice of the area has a point where the disc is ρ_o clear")
    path = np.vstack(route)
    _, count = covered_cells(fld, legs, area, footprint)
    covered = int((count > 0).sum())
    return CoverageResult(path, covered / max(len(count), 1),
                          float((count > 1).sum()) / max(covered, 1),
                          float(np.hypot(*np.diff(path, axis=0).T).sum()), len(legs), problems)
