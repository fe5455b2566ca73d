"""The ``cover`` task of a mission on the live map (pure): slices, waypoints, a clean-up pass
and the covered share measured from the walked path.

Slices ``spacing`` apart cross the area (a rectangle or a polygon), walked in alternating
directions through waypoints `WAYPOINT_STEP` apart. *Re-planned on the live map:* each next
waypoint is chosen when the last is reached, among the slice's points where the disc is ρ_o
clear of the obstacles mapped so far (`CoverTask._clear_points`: a slice bends by up to half
the spacing round an obstacle), so an obstacle discovered during the task moves or drops
waypoints and the navigator's field walks round it. Then a *clean-up pass* visits what the
slices left: the nearest reachable cell not yet covered (measured), from a clear point within
half the tool width of it with an arrival tolerance that covers the cell (`CoverTask._spot`),
until none is left or `MAX_CLEANUPS` goals were sent; a clean-up goal ends when its cell is
covered and is given up after `CLEANUP_LIMIT`. A waypoint the navigator cannot reach
(trapped, or inside an obstacle found later) is skipped and counted, not a failure of the task,
unless `STUCK_FAILS` goals in a row fail from one place (`CoverTask._stuck`).

Covered share, measured: the free cells of the area the tool can reach (within half the tool
width of a point where the navigator's disc is ρ_o clear: `CoverageTracker.reachable`)
within half the tool width of the walked path.
"""

from __future__ import annotations

import math

import numpy as np

from crawler_motion.navigation.apf.coverage import clear_spots, reachable
from crawler_motion.navigation.apf.field import FieldSettings, ObstacleField
from crawler_motion.navigation.apf_navigator import ApfNavigator, planning_grid
from crawler_motion.navigation.mission import Task
from crawler_motion.navigation.navigator import NavState, TerrainView

#: How often the covered share is measured while covering [s].
COVERED_PERIOD = 1.0
#: Spacing of the waypoints along a slice [m]; most clean-up goals of one task.
WAYPOINT_STEP = 0.3
MAX_CLEANUPS = 40
#: A clean-up goal not covering its cell within this time is given up [s].
CLEANUP_LIMIT = 30.0
#: Tightest arrival tolerance of a clean-up goal [m] (the walk's placement, a few cm/slot).
MIN_TOLERANCE = 0.02
#: Kept between the arrival tolerance and the tool's edge [m].
TOLERANCE_SLACK = 0.005
#: Goals failed in a row with the body within this distance [m] fail the task.
STUCK_FAILS = 3
STUCK_DISTANCE = 0.05


def inside_polygon(points: np.ndarray, polygon: list[tuple[float, float]]) -> np.ndarray:
    """Which of ``points`` ``(k, 2)`` lie inside ``polygon`` (even-odd rule)."""
    poly = np.asarray(polygon, dtype=float)
    x, y = points[:, 0:1], points[:, 1:2]
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    crosses = ((y0 > y) != (y1 > y)) & (
        x < (x1 - x0) * (y - y0) / np.where(y1 != y0, y1 - y0, 1e-12) + x0)
    return (crosses.sum(axis=1) % 2) == 1


def area_cells(view: TerrainView, polygon: list[tuple[float, float]]) -> tuple[np.ndarray,
                                                                                np.ndarray]:
    """Centres ``(k, 2)`` of the map cells inside the polygon and their obstacle flags."""
    rows, cols = view.obstacle.shape
    xs = view.origin[0] + (np.arange(cols) + 0.5) * view.resolution
    ys = view.origin[1] + (np.arange(rows) + 0.5) * view.resolution
    gx, gy = np.meshgrid(xs, ys)
    centres = np.column_stack([gx.ravel(), gy.ravel()])
    keep = inside_polygon(centres, polygon)
    return centres[keep], view.obstacle.ravel()[keep]


class CoverageTracker:
    """The cells (of ``resolution`` [m], aligned to the map's grid) within half the tool width
    of the walked path, marked pose by pose."""

    def __init__(self, resolution: float, tool_width: float) -> None:
        self.resolution, self.half = resolution, tool_width / 2
        r = math.ceil(self.half / resolution) + 1
        dj, di = np.meshgrid(np.arange(-r, r + 1), np.arange(-r, r + 1))
        self._offsets = np.column_stack([dj.ravel(), di.ravel()])
        self.cells: set[tuple[int, int]] = set()
        self._reach: tuple[tuple, np.ndarray] | None = None  # the last `reachable`, its key

    def mark(self, xy: np.ndarray) -> None:
        """Mark the cells whose centre lies within half the tool width of ``xy`` [m]."""
        base = np.floor(xy / self.resolution).astype(int)
        keys = base + self._offsets
        centres = (keys + 0.5) * self.resolution
        near = np.hypot(*(centres - xy).T) <= self.half
        self.cells.update(map(tuple, keys[near].tolist()))

    def share(self, view: TerrainView, polygon: list[tuple[float, float]],
              field: ObstacleField) -> float:
        """Covered share of the area's free cells that the tool can reach (`reachable`)
        (0..1)."""
        cells = self.reachable(view, polygon, field)
        if not len(cells):
            return 0.0
        return float(self.covered(cells).mean())

    def covered(self, cells: np.ndarray) -> np.ndarray:
        """Which cell centres ``(k, 2)`` are covered."""
        keys = np.floor(cells / self.resolution).astype(int)
        return np.array([tuple(k) in self.cells for k in keys.tolist()], dtype=bool)

    def reachable(self, view: TerrainView, polygon: list[tuple[float, float]],
                  field: ObstacleField) -> np.ndarray:
        """Centres ``(k, 2)`` of the area's free cells the tool can reach: within half the
        tool width of a point where the navigator's disc (``field``) is ρ_o clear, i.e.
        ρ(cell) + half width >= ρ_o (the clearance grows at 1 m/m away from the nearest
        obstacle cell)."""
        centres, obstacle = area_cells(view, polygon)
        free = centres[~obstacle]
        if not len(free):
            return free
        key = (free.tobytes(), field.cells.tobytes(), field.radius, field.settings.standoff)
        if self._reach is None or self._reach[0] != key:  # the map's obstacles changed
            self._reach = (key, free[reachable(field, free, self.half)])
        return self._reach[1]


def cover_field(view: TerrainView, points: np.ndarray, disc: float,
                standoff: float) -> ObstacleField:
    """The navigator's field of the disc radius ``disc`` [m] (virtual radius + margin) and
    stand-off ρ_o [m] on the map, holding ``points`` ``(k, 2)``."""
    grid = planning_grid(view, points, disc + 0.5)
    return ObstacleField(grid, disc, FieldSettings(standoff=standoff))


def _key(xy: np.ndarray, resolution: float) -> tuple[int, int]:
    return tuple(np.floor(np.asarray(xy) / resolution).astype(int).tolist())  # type: ignore[return-value]


class CoverTask:
    """One cover task on one navigator: `start`, `mark` every pose, `after` every cycle."""

    def __init__(self, task: Task, nav: ApfNavigator, tool_width: float,
                 resolution: float) -> None:
        self.task, self.nav, self.tool_width = task, nav, tool_width
        self.tracker = CoverageTracker(resolution, tool_width)
        self.covered = 0.0
        self.skipped = 0
        self._slices_done = 0
        self._along: float | None = None  # signed x of the slice's last waypoint
        self._goal: np.ndarray | None = None
        self._cell: np.ndarray | None = None  # the clean-up goal's cell
        self.failed: str | None = None  # why the task cannot go on (`_stuck`)
        self._fail_at: np.ndarray | None = None  # where a run of failed goals began
        self._fails = 0
        self._sent = 0.0
        self._covered_at = -1e9
        self._cleanups = 0
        self._given_up: set[tuple[int, int]] = set()
        self._xy = np.zeros(2)

    @property
    def progress(self) -> float:
        """Slices walked over slices (0..1)."""
        return min(1.0, self._slices_done / len(self._slices(self.task)))

    def mark(self, xy: np.ndarray) -> None:
        """The body's position now [m]."""
        self._xy = xy
        self.tracker.mark(xy)

    def start(self, view: TerrainView, disc: float, now: float) -> bool:
        """Send the first goal; False when there is nothing to walk."""
        return self._next_goal(view, disc, now)

    def after(self, view: TerrainView, disc: float, now: float) -> bool:
        """After a navigator cycle: measure, and on arrival (or failure) send the next goal;
        False when the task is done. A clean-up goal ends as soon as its cell is covered,
        and is given up after `CLEANUP_LIMIT`."""
        if now - self._covered_at >= COVERED_PERIOD or self.nav.state is not NavState.ACTIVE:
            self._covered_at = now
            self.covered = self.tracker.share(view, self.task.polygon, self._field(view, disc))
        cell = self._cell
        done = cell is not None and bool(self.tracker.covered(cell[None, :])[0])
        if self.nav.state is NavState.ACTIVE:
            if cell is None or not (done or now - self._sent > CLEANUP_LIMIT):
                return True
            self.nav.cancel("clean-up cell covered" if done else "clean-up goal given up")
        if self.nav.state is NavState.FAILED and self._stuck(self.nav.reason):
            return False
        if self.nav.state is NavState.FAILED or (cell is not None and not done):
            self.skipped += 1
            if cell is not None:
                self._given_up.add(_key(cell, view.resolution))
        if self._slices_done < len(self._slices(self.task)) and self._goal is not None:
            sign = 1.0 if self._slices_done % 2 == 0 else -1.0
            self._along = float(self._goal[0]) * sign  # reached or given up: go on past it
        return self._next_goal(view, disc, now)

    def _stuck(self, reason: str) -> bool:
        """Count a failed goal; True (and `failed` says why) when `STUCK_FAILS` goals in a
        row failed with the body within `STUCK_DISTANCE` of where the first did: the body,
        not the waypoints, is the problem, and skipping on would skip every one."""
        if self._fail_at is None or np.hypot(*(self._xy - self._fail_at)) > STUCK_DISTANCE:
            self._fail_at, self._fails = self._xy.copy(), 0
        self._fails += 1
        if self._fails < STUCK_FAILS:
            return False
        self.failed = (f"{self._fails} goals in a row failed from ({self._xy[0]:.3f}, "
                       f"{self._xy[1]:.3f}): {reason}")
        return True

    def _field(self, view: TerrainView, disc: float) -> ObstacleField:
        return cover_field(view, np.asarray(self.task.polygon, dtype=float), disc,
                           self.nav.settings.standoff)

    def _next_goal(self, view: TerrainView, disc: float, now: float) -> bool:
        if self._next_end(view, disc, now):
            return True
        return self._cleanup(view, disc, now)

    def _send(self, target: np.ndarray, now: float, cell: np.ndarray | None = None,
              tolerance: float | None = None) -> bool:
        self._goal, self._cell, self._sent = target, cell, now
        self.nav.set_goal(float(target[0]), float(target[1]), now, tolerance)
        return True

    def _cleanup(self, view: TerrainView, disc: float, now: float) -> bool:
        """A goal from which the nearest reachable uncovered cell is covered; False when
        none is left (or `MAX_CLEANUPS` were sent)."""
        if self._cleanups >= MAX_CLEANUPS:
            return False
        fld = self._field(view, disc)
        cells = self.tracker.reachable(view, self.task.polygon, fld)
        cells = cells[~self.tracker.covered(cells)] if len(cells) else cells
        keys = [_key(c, view.resolution) for c in cells]
        cells = cells[[k not in self._given_up for k in keys]] if len(cells) else cells
        for cell in cells[np.argsort(np.hypot(*(cells - self._xy).T))][:5]:
            spot = self._spot(fld, cell)
            if spot is not None:
                self._cleanups += 1
                return self._send(spot[0], now, cell, spot[1])
            self._given_up.add(_key(cell, view.resolution))
        return False

    def _spot(self, fld: ObstacleField, cell: np.ndarray) -> tuple[np.ndarray, float] | None:
        """A ρ_o-clear point within half the tool width of ``cell`` and the arrival tolerance
        [m] that covers the cell from it: nearest the body among the points from which the
        navigator's own tolerance does, else the point nearest the cell (a tighter
        tolerance, at least `MIN_TOLERANCE`); None when no point is clear."""
        half, tol = self.tracker.half, self.nav.settings.goal_tolerance
        pts = clear_spots(fld, cell, half)
        if not len(pts):
            return None
        gap = np.hypot(*(pts - cell).T)
        easy = gap <= half - tol
        if easy.any():
            pts = pts[easy]
            return pts[int(np.argmin(np.hypot(*(pts - self._xy).T)))], tol
        k = int(np.argmin(gap))
        return pts[k], max(MIN_TOLERANCE, half - float(gap[k]) - TOLERANCE_SLACK)

    def _slices(self, task: Task) -> list[float]:
        poly = np.asarray(task.polygon)
        y0, y1 = float(poly[:, 1].min()), float(poly[:, 1].max())
        n = max(1, math.ceil((y1 - y0) / task.values["spacing"] - 1e-9))
        return [y0 + (k + 0.5) * (y1 - y0) / n for k in range(n)]

    def _clear_points(self, task: Task, view: TerrainView, disc: float,
                      y: float) -> np.ndarray:
        """The slice at ``y`` on this map: for each x (half a cell apart) the point inside
        the area where the disc is ρ_o clear of the obstacles, at ``y`` or shifted by the
        least offset up to half the spacing (the slice bends round an obstacle to cover up to
        it); x where none is clear are left out. Sorted by x."""
        poly = np.asarray(task.polygon)
        step = view.resolution / 2
        xs = np.arange(poly[:, 0].min(), poly[:, 0].max() + 1e-9, step)
        reach = np.arange(step, task.values["spacing"] / 2 + 1e-9, step)
        offsets = np.concatenate([[0.0], np.ravel(np.column_stack([reach, -reach]))])
        cand = np.stack([np.column_stack([xs, np.full_like(xs, y + d)]) for d in offsets])
        flat = cand.reshape(-1, 2)
        ok = inside_polygon(flat, task.polygon)
        if not ok.any():
            return np.zeros((0, 2))
        fld = cover_field(view, flat[ok], disc, self.nav.settings.standoff)
        clear = np.zeros(len(flat), dtype=bool)
        clear[ok] = fld.clearance(flat[ok])[0] >= fld.settings.standoff
        clear = clear.reshape(len(offsets), len(xs))
        has = clear.any(axis=0)
        first = np.argmax(clear, axis=0)  # the least offset that is clear, per x
        return cand[first[has], np.flatnonzero(has)]

    def _next_end(self, view: TerrainView, disc: float, now: float) -> bool:
        """Send the navigator to the next waypoint still clear on this map: along slice k
        (direction +x for even k) by `_waypoint`; False when every slice is walked."""
        task = self.task
        slices = self._slices(task)
        while self._slices_done < len(slices):
            k = self._slices_done
            sign = 1.0 if k % 2 == 0 else -1.0
            pts = self._clear_points(task, view, disc, slices[k])
            along = pts[:, 0] * sign if len(pts) else np.zeros(0)
            order = np.argsort(along)
            pts, along = pts[order], along[order]
            target = self._waypoint(pts, along, view.resolution)
            if target is not None:
                return self._send(target, now)
            self._slices_done, self._along = self._slices_done + 1, None
        return False

    def _waypoint(self, pts: np.ndarray, along: np.ndarray, res: float) -> np.ndarray | None:
        """The next waypoint among the slice's clear points ``pts`` (sorted by ``along``, the
        signed x): the first one at the slice's start; then `WAYPOINT_STEP` further on, or
        sooner the last clear point before a gap (an obstacle: the tool reaches up to it),
        or past a gap the first clear point after it; None at the slice's end."""
        if not len(pts):
            return None
        if self._along is None:
            return pts[0]
        gap = res / 2 + 1e-9  # clear points closer than this are one run (no obstacle between)
        idx = np.flatnonzero(along > self._along + 1e-9)
        if not len(idx):
            return None
        j = int(idx[0])
        if along[j] - self._along > gap:  # a gap right after the last waypoint: jump it
            return pts[j]
        step_to = self._along + WAYPOINT_STEP - 1e-9
        while j + 1 < len(pts) and along[j] < step_to and along[j + 1] - along[j] <= gap:
            j += 1
        if along[j] - self._along <= self.nav.settings.goal_tolerance:  # the run ends here
            return pts[j + 1] if j + 1 < len(pts) else None
        return pts[j]
