"""Running a mission on the live map with the ``apf`` navigator (pure: no ROS).

`MissionRunner.before` is called on every map before the navigator's cycle and
`MissionRunner.after` after it; together they walk the tasks in order:

- ``goto`` / ``home``: a goal for the navigator (home: the body's position when the mission
  started); done when it arrives.
- ``follow``: the navigator's follow command with the task's stand-off (the navigator's own
  stand-off again after the task); done when it has walked the length.
- ``cover``: slices ``spacing`` apart across the area (a rectangle or a polygon), walked in
  alternating directions through waypoints `WAYPOINT_STEP` apart. *Re-planned on the live
  map:* each next waypoint is chosen when the last is reached, among the slice's points where
  the disc is ρ_o clear of the obstacles mapped so far, so an obstacle discovered during the
  task moves or drops waypoints (the next clear point beyond it is taken, and the navigator's
  field walks round it). A waypoint the navigator cannot reach (trapped, or inside an obstacle
  found later) is skipped and counted (``skipped``), not a failure of the task. Done when no
  slice is left.

A task that fails (navigator FAILED, or its ``timeout``) fails the mission with its reason; the
rest does not run and the robot stands (the navigator's zero twist). The covered share is
measured (`CoverageTracker`), not planned: the free cells of the area that the tool can reach
(at least the navigator's disc radius, virtual radius + margin, plus its stand-off ρ_o minus
half the tool width from every obstacle cell: where the waypoints may lie) within half the
tool width of the walked path (odometry).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np

from crawler_motion.navigation.apf.field import FieldSettings, ObstacleField
from crawler_motion.navigation.apf_navigator import (
    ApfNavigator,
    FollowCommand,
    Side,
    planning_grid,
)
from crawler_motion.navigation.mission import Mission, Task, TaskKind
from crawler_motion.navigation.navigator import NavState, TerrainView, goal_error

#: How often the covered share is measured while covering [s].
COVERED_PERIOD = 1.0
#: Spacing of the waypoints along a slice [m].
WAYPOINT_STEP = 0.3


class MissionState(Enum):
    """A mission's state."""

    RUNNING = "RUNNING"
    DONE = "DONE"
    FAILED = "FAILED"
    CANCELLED = "CANCELLED"


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

    def mark(self, xy: np.ndarray) -> None:
        """Mark the cells whose centre lies within half the tool width of ``xy`` [m]."""
        base = np.floor(xy / self.resolution).astype(int)
        keys = base + self._offsets
        centres = (keys + 0.5) * self.resolution
        near = np.hypot(*(centres - xy).T) <= self.half
        self.cells.update(map(tuple, keys[near].tolist()))

    def share(self, view: TerrainView, polygon: list[tuple[float, float]],
              disc_radius: float) -> float:
        """Covered share of the area's free cells that the tool can reach: at least
        ``disc_radius`` minus half the tool width from every obstacle cell (0..1)."""
        centres, obstacle = area_cells(view, polygon)
        free = centres[~obstacle]
        if not len(free):
            return 0.0
        obst = _obstacle_centres(view)
        reach = np.ones(len(free), dtype=bool)
        near = obst[np.all(np.abs(obst - free.mean(axis=0)) <= np.ptp(free, axis=0) / 2
                           + disc_radius + view.resolution, axis=1)] if len(obst) else obst
        if len(near):
            gap = np.hypot(*(free[:, None, :] - near[None, :, :]).transpose(2, 0, 1)).min(
                axis=1) - view.resolution / 2
            reach = gap >= disc_radius - self.half
        cells = free[reach]
        if not len(cells):
            return 0.0
        keys = np.floor(cells / self.resolution).astype(int)
        return float(np.mean([tuple(k) in self.cells for k in keys.tolist()]))


def _obstacle_centres(view: TerrainView) -> np.ndarray:
    rows, cols = np.nonzero(view.obstacle)
    return view.origin + (np.column_stack([cols, rows]) + 0.5) * view.resolution


@dataclass
class MissionRunner:
    """One mission on one `ApfNavigator`; ``start`` the body's position at its start [m]."""

    mission: Mission
    nav: ApfNavigator
    start: np.ndarray
    began: float
    tool_width: float
    state: MissionState = MissionState.RUNNING
    index: int = 0  # the task running (0-based)
    reason: str = ""
    distance: float = 0.0  # walked since the mission started [m]
    covered: float | None = None  # measured share of the running or last cover task
    progress: float = 0.0  # of the running task (0..1)
    skipped: int = 0  # slice ends the navigator could not reach
    _task_began: float = 0.0
    _started: bool = False
    _slices_done: int = 0
    _along: float | None = None  # signed x of the last waypoint of the slice (None: at start)
    _goal: np.ndarray | None = None  # the waypoint sent
    _tracker: CoverageTracker | None = None
    _covered_at: float = -1e9
    _last: np.ndarray | None = None
    _base_standoff: float = 0.0

    def __post_init__(self) -> None:
        self._base_standoff = self.nav.settings.standoff

    @property
    def task(self) -> Task | None:
        """The running task."""
        return self.mission.tasks[self.index] if self.index < len(self.mission.tasks) else None

    def cancel(self, reason: str = "cancelled") -> None:
        """End the mission; the navigator's goal with it."""
        if self.state is MissionState.RUNNING:
            self.state, self.reason = MissionState.CANCELLED, reason
            self.nav.cancel(reason)
            self._restore()

    def before(self, pose: tuple[float, float, float], view: TerrainView, disc: float,
               now: float) -> None:
        """Track the walked path; start the next task or the next slice end."""
        if self.state is not MissionState.RUNNING:
            return
        xy = np.array(pose[:2], dtype=float)
        if self._last is not None:
            self.distance += float(np.hypot(*(xy - self._last)))
        self._last = xy
        if self._tracker is not None:
            self._tracker.mark(xy)
        task = self.task
        assert task is not None
        if not self._started:
            self._begin(task, view, disc, xy, now)
        elif now - self._task_began > task.timeout:
            self._fail(f"task {self.index + 1} ({task.kind.value}) not done within "
                       f"{task.timeout:g} s")

    def after(self, view: TerrainView, disc: float, now: float) -> None:
        """Read the navigator's outcome: next task, next slice end, or the mission's end."""
        if self.state is not MissionState.RUNNING or not self._started:
            return
        task = self.task
        assert task is not None
        if task.kind is TaskKind.COVER:
            self._cover_after(task, view, disc, now)
            return
        if self.nav.state is NavState.ARRIVED:
            self._next(now)
        elif self.nav.state is NavState.FAILED:
            self._fail(f"task {self.index + 1} ({task.kind.value}): {self.nav.reason}")
        else:
            self._progress(task)

    def _begin(self, task: Task, view: TerrainView, disc: float, xy: np.ndarray,
               now: float) -> None:
        self._started, self._task_began, self.progress = True, now, 0.0
        self._tracker = None
        far = self._too_far(task, xy)
        if far is not None:
            self._fail(f"task {self.index + 1} ({task.kind.value}): {far}")
            return
        if task.kind is TaskKind.GOTO:
            self.nav.set_goal(task.values["x"], task.values["y"], now)
        elif task.kind is TaskKind.HOME:
            self.nav.set_goal(float(self.start[0]), float(self.start[1]), now)
        elif task.kind is TaskKind.FOLLOW:
            standoff = task.values.get("standoff", self._base_standoff)
            self.nav.settings = replace(self.nav.settings, standoff=standoff)
            self.nav.set_follow(FollowCommand(task.values["length"],
                                              Side(task.values["side"])), now)
        else:
            self._slices_done, self._along, self.covered = 0, None, 0.0
            self._tracker = CoverageTracker(view.resolution, self.tool_width)
            self._tracker.mark(xy)
            self._next_end(task, view, disc, now)

    def _too_far(self, task: Task, xy: np.ndarray) -> str | None:
        """Why the task's goal or area lies beyond the navigator's ``max_goal_distance``."""
        limit = self.nav.settings.max_goal_distance
        if task.kind is TaskKind.GOTO:
            return goal_error(task.values["x"], task.values["y"], tuple(xy), limit)
        if task.kind is TaskKind.HOME:
            return goal_error(float(self.start[0]), float(self.start[1]), tuple(xy), limit)
        if task.kind is TaskKind.COVER:
            far = max(float(np.hypot(*(np.asarray(p) - xy))) for p in task.polygon)
            if far > limit:
                return (f"the area reaches {far:.3g} m from the body, beyond max_goal_distance "
                        f"{limit:g} m; go nearer first")
        return None

    def _progress(self, task: Task) -> None:
        if task.kind is TaskKind.FOLLOW and self.nav.command is not None:
            self.progress = min(1.0, self.nav.walked / self.nav.command.length)

    def _next(self, now: float) -> None:
        self._restore()
        self.progress, self._started = 1.0, False
        self.index += 1
        if self.index >= len(self.mission.tasks):
            self.state, self.reason = MissionState.DONE, "every task done"
            self.index = len(self.mission.tasks) - 1

    def _fail(self, reason: str) -> None:
        self.state, self.reason = MissionState.FAILED, reason
        if self.nav.state is NavState.ACTIVE:
            self.nav.fail(reason)
        self._restore()

    def _restore(self) -> None:
        self.nav.settings = replace(self.nav.settings, standoff=self._base_standoff)

    # --- cover ------------------------------------------------------------------------------

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
        grid = planning_grid(view, flat[ok], disc + 0.5)
        fld = ObstacleField(grid, disc, FieldSettings(standoff=self.nav.settings.standoff))
        clear = np.zeros(len(flat), dtype=bool)
        clear[ok] = fld.clearance(flat[ok])[0] >= fld.settings.standoff
        clear = clear.reshape(len(offsets), len(xs))
        has = clear.any(axis=0)
        first = np.argmax(clear, axis=0)  # the least offset that is clear, per x
        return cand[first[has], np.flatnonzero(has)]

    def _next_end(self, task: Task, view: TerrainView, disc: float, now: float) -> None:
        """Send the navigator to the next waypoint still clear on this map: along slice k
        (direction +x for even k) by `_waypoint`; then the next slice."""
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
                self._goal = target
                self.nav.set_goal(float(target[0]), float(target[1]), now)
                return
            self._slices_done, self._along = self._slices_done + 1, None
        self._next(now)

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

    def _cover_after(self, task: Task, view: TerrainView, disc: float, now: float) -> None:
        if self._tracker is not None and (now - self._covered_at >= COVERED_PERIOD
                                          or self.nav.state is not NavState.ACTIVE):
            self._covered_at = now
            self.covered = self._tracker.share(view, task.polygon,
                                               disc + self.nav.settings.standoff)
        slices = self._slices(task)
        self.progress = min(1.0, self._slices_done / len(slices))
        if self.nav.state is NavState.ACTIVE:
            return
        if self.nav.state is NavState.FAILED:
            self.skipped += 1
        sign = 1.0 if self._slices_done % 2 == 0 else -1.0
        self._along = float(self._goal[0]) * sign  # reached or given up: go on past it
        self._next_end(task, view, disc, now)

    def status(self) -> dict:
        """The ``mission_status`` fields."""
        task = self.task
        return {"mission": self.mission.id, "task_index": self.index + 1,
                "tasks": len(self.mission.tasks),
                "task_kind": None if task is None else task.kind.value,
                "state": self.state.value, "progress": round(self.progress, 3),
                "covered": None if self.covered is None else round(self.covered, 4),
                "distance": round(self.distance, 3), "skipped_ends": self.skipped,
                "reason": self.reason}
