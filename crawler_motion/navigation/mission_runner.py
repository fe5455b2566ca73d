"""Running a mission on the live map with the ``apf`` navigator (pure: no ROS).

`MissionRunner.before` is called on every map before the navigator's cycle and
`MissionRunner.after` after it; together they walk the tasks in order:

- ``goto`` / ``home``: a goal for the navigator (home: the body's position when the mission
  started, or `home_goal`'s nearest point clear by the stand-off when the map has since seen
  an obstacle there); done when it arrives.
- ``follow``: the navigator's follow command with the task's stand-off (the navigator's own
  stand-off again after the task); done when it has walked the length.
- ``cover``: `mission_cover.CoverTask` (slices re-planned on the live map, a clean-up pass,
  the covered share measured from the walked path).

A task that fails (navigator FAILED, or its ``timeout``) fails the mission with its reason; the
rest does not run and the robot stands (the navigator's zero twist).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum

import numpy as np

from crawler_motion.navigation.apf.coverage import clear_spots
from crawler_motion.navigation.apf_navigator import (
    ApfNavigator,
    FollowCommand,
    Side,
)
from crawler_motion.navigation.mission import Mission, Task, TaskKind
from crawler_motion.navigation.mission_cover import CoverTask, cover_field
from crawler_motion.navigation.navigator import NavState, TerrainView, goal_error


def home_goal(view: TerrainView, disc: float, standoff: float, start: np.ndarray
              ) -> tuple[np.ndarray, str]:
    """Where ``home`` walks to [m], and a note when it is not ``start`` itself.

    The robot stood at ``start``, yet the map may since have seen an obstacle nearer than the
    navigator's disc (radius ``disc`` [m]: virtual radius + margin) allows there (a rock
    between the legs, a face seen closer), and the field cannot bring the body to a goal
    nearer an obstacle than the stand-off ρ_o (``standoff`` [m]): its repulsion balances the
    attraction short of it. Home is then the nearest point within ``disc`` of ``start`` where
    the disc is ρ_o clear (`apf.coverage.clear_spots`, as the cover's clean-up goals); when
    there is none, ``start`` (the navigator refuses it, or stops short of it, with the
    reason)."""
    start = np.asarray(start, dtype=float)
    fld = cover_field(view, start[None, :], disc, standoff)
    if float(fld.clearance(start)[0]) >= standoff - 1e-9:
        return start, ""
    clear = clear_spots(fld, start, disc)  # the cover's rule: within disc, ρ_o clear
    if not len(clear):
        return start, ""
    home = clear[np.argmin(np.hypot(*(clear - start).T))]
    return home, (f"home ({start[0]:.3f}, {start[1]:.3f}) is nearer an obstacle than the disc "
                  f"and stand-off allow; walking to ({home[0]:.3f}, {home[1]:.3f}), "
                  f"{float(np.hypot(*(home - start))):.3f} m from it")


class MissionState(Enum):
    """A mission's state."""

    RUNNING = "RUNNING"
    DONE = "DONE"
    FAILED = "FAILED"
    CANCELLED = "CANCELLED"


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
    _cover: CoverTask | None = None
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
        if self._cover is not None:
            self._cover.mark(xy)
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
        if self._cover is not None:
            more = self._cover.after(view, disc, now)
            self.covered, self.skipped = self._cover.covered, self._cover.skipped
            self.progress = self._cover.progress
            if self._cover.failed is not None:
                self._fail(f"task {self.index + 1} ({task.kind.value}): {self._cover.failed}")
            elif not more:
                self._next(now)
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
        self._cover = None
        far = self._too_far(task, xy)
        if far is not None:
            self._fail(f"task {self.index + 1} ({task.kind.value}): {far}")
            return
        if task.kind is TaskKind.GOTO:
            self.nav.set_goal(task.values["x"], task.values["y"], now)
        elif task.kind is TaskKind.HOME:
            home, self.reason = home_goal(view, disc, self.nav.settings.standoff, self.start)
            self.nav.set_goal(float(home[0]), float(home[1]), now)
        elif task.kind is TaskKind.FOLLOW:
            standoff = task.values.get("standoff", self._base_standoff)
            self.nav.settings = replace(self.nav.settings, standoff=standoff)
            self.nav.set_follow(FollowCommand(task.values["length"],
                                              Side(task.values["side"])), now)
        else:
            self._cover = CoverTask(task, self.nav, self.tool_width, view.resolution)
            self._cover.mark(xy)
            self.covered = 0.0
            if not self._cover.start(view, disc, now):
                self._next(now)

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
        self._cover = None
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
