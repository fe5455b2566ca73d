"""Coverage of a rectangular seabed area in slices (the study's §3 on a 2-D map, pure).

The area is cut into ``n = ceil(height / spacing)`` parallel slices along x, evenly spread
(slice k at ``y0 + (k + ½) · height / n``, so neighbours are at most ``spacing`` apart). Slice
after slice, alternating direction (boustrophedon), the improved field with virtual goals plans
from the end of the previous slice to the start of this one and then along it; obstacles on the
slice are passed at the stand-off distance. *Rules:* a slice end where the disc is not ρ_o
clear of the obstacles moves along the slice towards the area's inside to the first point
where it is; a slice with no such point is skipped (and reported); a leg that ends trapped
keeps its path, is reported, and the route goes on from where it stopped. Then *clean-up
legs* (rule chosen, as a mission's cover task): from the route's end to a clear point within
the footprint of the nearest reachable cell not yet covered (`clear_spots`), until none is
left or `MAX_CLEANUPS` legs were planned; a cell no leg reaches is given up.

Reachable (`reachable`): a free cell within ``footprint`` of a point where the disc is ρ_o
clear (searched among points half a cell apart: a gap narrower than the disc reaches none).
Covered: the cells within ``footprint`` of the route (the sensor or tool footprint, a disc);
the share is of the reachable cells (``share_free``: of every free cell); overlap: the share
of the covered cells covered by more than one leg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from crawler_motion.errors import CommandError
from crawler_motion.navigation.apf.field import ObstacleField
from crawler_motion.navigation.apf.planner import ApfMethod, PlanSettings, densify, plan

#: Most clean-up legs of one route.
MAX_CLEANUPS = 60


def _lattice(fld: ObstacleField, centre: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Points ``(k, 2)`` half a cell apart, aligned to the grid, within ``half`` (x, y [m])
    of ``centre``."""
    step = fld.grid.resolution / 2
    lo = np.floor((centre - half - fld.grid.origin) / step) * step + fld.grid.origin
    xs = np.arange(lo[0], centre[0] + half[0] + 1e-9, step)
    ys = np.arange(lo[1], centre[1] + half[1] + 1e-9, step)
    gx, gy = np.meshgrid(xs, ys)
    return np.column_stack([gx.ravel(), gy.ravel()])


def reachable(fld: ObstacleField, cells: np.ndarray, footprint: float) -> np.ndarray:
    """Which cell centres ``(k, 2)`` lie within ``footprint`` [m] of a point where the disc is
    ρ_o clear (the points half a cell apart, as `clear_spots`): at once where ρ(cell) ≥ ρ_o,
    never where ρ(cell) + footprint < ρ_o (ρ grows at most 1 m/m), searched between."""
    if not len(cells):
        return np.zeros(0, dtype=bool)
    rho = fld.clearance(cells)[0]
    out = rho >= fld.settings.standoff
    band = ~out & (rho + footprint >= fld.settings.standoff)
    if band.any():
        inner = cells[band]
        mid, half = (inner.max(axis=0) + inner.min(axis=0)) / 2, np.ptp(inner, axis=0) / 2
        pts = _lattice(fld, mid, half + footprint)
        pts = pts[fld.clearance(pts)[0] >= fld.settings.standoff]
        found = np.zeros(len(inner), dtype=bool)
        for k in range(0, len(pts), 512):
            d = np.hypot(*(inner[:, None, :] - pts[None, k:k + 512, :]).transpose(2, 0, 1))
            found |= (d <= footprint).any(axis=1)
        out[band] = found
    return out


def clear_spots(fld: ObstacleField, cell: np.ndarray, footprint: float) -> np.ndarray:
    """Points ``(k, 2)`` within ``footprint`` [m] of ``cell`` where the disc is ρ_o clear:
    along the clearance's gradient (away from the nearest obstacle cell), on rings round the
    cell and half a cell apart (as `reachable`); empty when none is."""
    grad = fld.clearance(cell)[1]
    out = cell + grad * np.arange(0.0, footprint, footprint / 8)[:, None]
    angles = np.linspace(0.0, 2 * math.pi, 12, endpoint=False)
    ring = np.column_stack([np.cos(angles), np.sin(angles)])
    near = _lattice(fld, cell, np.full(2, footprint))
    near = near[np.hypot(*(near - cell).T) <= footprint]
    pts = np.vstack([out, near] + [cell + f * footprint * ring for f in (0.25, 0.5, 0.75, 0.95)])
    return pts[fld.clearance(pts)[0] >= fld.settings.standoff]


@dataclass
class CoverageResult:
    """The route ``(n, 2)`` [m], the covered share and overlap of the area's free cells, the
    route length [m], and what went wrong on the way (skipped slices, trapped legs)."""

    route: np.ndarray
    share: float  # of the reachable free cells
    overlap: float
    length: float
    slices: int
    problems: list[str] = field(default_factory=list)
    share_free: float = 0.0  # of every free cell of the area
    cleanups: int = 0  # clean-up legs planned


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
    slices = len(legs)
    cleanups = _cleanup(fld, legs, area, footprint, settings)
    path = np.vstack(legs)
    cells, count = covered_cells(fld, legs, area, footprint)
    reach = reachable(fld, cells, footprint)
    covered = int((count > 0).sum())
    return CoverageResult(path, float((count[reach] > 0).mean()) if reach.any() else 0.0,
                          float((count > 1).sum()) / max(covered, 1),
                          float(np.hypot(*np.diff(path, axis=0).T).sum()), slices, problems,
                          covered / max(len(count), 1), cleanups)


def _cleanup(fld: ObstacleField, legs: list[np.ndarray], area: tuple[float, ...],
             footprint: float, settings: PlanSettings | None) -> int:
    """Append clean-up legs to ``legs`` (see the module); the number appended."""
    cells, count = covered_cells(fld, legs, area, footprint)
    left = cells[reachable(fld, cells, footprint) & (count == 0)]
    done = 0
    while len(left) and done < MAX_CLEANUPS:
        end = legs[-1][-1]
        cell = left[int(np.argmin(np.hypot(*(left - end).T)))]
        spots = clear_spots(fld, cell, footprint)
        res = None
        if len(spots):
            spot = spots[int(np.argmin(np.hypot(*(spots - end).T)))]
            res = plan(fld, end, spot, ApfMethod.APF_VIRTUAL, settings)
        if res is None or not res.reached:
            left = left[np.any(left != cell, axis=1)]  # given up
            continue
        legs.append(res.path)
        done += 1
        hit = np.hypot(*(densify(res.path, fld.grid.resolution / 2)[None, :, :]
                         - left[:, None, :]).transpose(2, 0, 1)).min(axis=1) <= footprint
        left = left[~hit]
    return done
