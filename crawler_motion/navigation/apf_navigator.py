"""The ``apf`` method of the navigator: the improved potential field re-planned on every map
update, steered through a look-ahead point of the path (pure).

Every cycle the live map becomes the planner's grid: obstacle cells are obstacles, unknown and
free cells are passable (*choice*: the scanner only sees ahead, so unknown must be walkable or
the robot could never leave the seen patch; a wall that appears is planned around on the next
update), and the grid is padded with passable cells until it holds the robot and the goal with
a margin. The robot is the planner's disc of the virtual radius plus ``margin``.

- **goto** (`set_goal`): `plan` with virtual goals from the body to the goal, through the
  virtual goals still in use (those of the last plan the look-ahead point has not passed, and
  still clear), so that a detour once found is kept while the map grows instead of
  re-discovered from every new pose. A goal or body inside an obstacle (a body the map grew
  into is led out first: `ApfNavigator._field`): FAILED with the planner's reason, a zero
  twist (the planner stands). Trapped: the robot stands and the plan is made again on every
  map for `TRAP_PATIENCE`; still trapped then: FAILED with the planner's reason.
- **follow** (`set_follow`): `follow` walks along the nearest structure (on the right or the
  left) at the stand-off distance; ARRIVED once the body has walked the length (odometry).

The heading towards the look-ahead point becomes a twist through the same steering as the
virtual-body method (crab or turn).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from crawler_motion.errors import CommandError
from crawler_motion.model.joint_state import finite_float
from crawler_motion.navigation.apf.field import FieldSettings, Grid, ObstacleField
from crawler_motion.navigation.apf.planner import (
    ApfMethod,
    PlanResult,
    PlanSettings,
    follow,
    plan,
)
from crawler_motion.navigation.heading import Rule
from crawler_motion.navigation.navigator import (
    Method,
    NavigatorSettings,
    NavState,
    Output,
    TerrainView,
)
from crawler_motion.navigation.steering import twist

#: How much clear the body's disc is made when the margin gives way [m].
SQUEEZE = 0.005
#: Share of the virtual radius (the farthest foot) the disc may shrink to, to lead a body out
#: of obstacle cells the map grew into it: the inner half holds the hull and the hips.
ESCAPE_SHARE = 0.5
#: Most cells a plan's grid may hold (8 MB of flags; a 10 m goal on the 4 m map at 0.05 m
#: takes ~0.1 M): more means the body is far from its map, and the plan is refused.
PLAN_CELLS = 1_000_000
#: Virtual goals of successive plans closer than this count as one [m].
SAME_GOAL = 0.15
#: A trapped plan is made again on the next maps for this long [s], the robot standing,
#: before the goal fails: the first scans of a structure map part of it, and a partial map
#: can trap a plan that the fuller one does not (a U seen from its mouth, 1 real-time run
#: in 4 before).
TRAP_PATIENCE = 3.0


class Mode(Enum):
    """What an active apf navigator does."""

    GOTO = "goto"
    FOLLOW = "follow"


class Side(Enum):
    """Where the followed structure lies, seen in the direction of travel."""

    RIGHT = "right"
    LEFT = "left"


#: Longest follow_command text [characters].
MAX_FOLLOW_TEXT = 1000


@dataclass(frozen=True)
class FollowCommand:
    """Walk ``length`` [m] along the nearest structure, kept on ``side``."""

    length: float
    side: Side = Side.RIGHT

    @classmethod
    def from_json(cls, text: str) -> FollowCommand:
        """``{"length": L, "side": "right"|"left"}``; `CommandError` saying what is wrong
        (text longer than `MAX_FOLLOW_TEXT`, nested too deep, numbers beyond the float range
        included)."""
        if not isinstance(text, str) or len(text) > MAX_FOLLOW_TEXT:
            raise CommandError(f"follow command must be JSON text of at most {MAX_FOLLOW_TEXT} "
                               f'characters such as {{"length": 2.0, "side": "right"}}')
        try:
            data = json.loads(text)
        except (ValueError, RecursionError) as exc:  # JSONDecodeError is a ValueError
            raise CommandError(f"follow command is not JSON ({str(exc)[:80]}); send "
                               '{"length": 2.0, "side": "right"}') from None
        if not isinstance(data, dict) or set(data) - {"length", "side"} or "length" not in data:
            raise CommandError('follow command needs {"length": L} and optionally "side" '
                               f"(right or left), got {text!r}")
        length = finite_float(data["length"])
        if length is None or length <= 0.0:
            raise CommandError(f"follow length must be a finite number > 0 m, got "
                               f"{str(data['length'])[:40]}")
        try:
            side = Side(data.get("side", Side.RIGHT.value))
        except ValueError as exc:
            raise CommandError(f"follow side must be right or left, got {data['side']!r}"
                               ) from exc
        return cls(float(length), side)


def planning_grid(view: TerrainView, points: np.ndarray, margin: float) -> Grid:
    """The map's obstacle cells as a `Grid`, padded with passable cells to hold ``points``
    ``(k, 2)`` [m] with ``margin`` [m] around them; `CommandError` beyond `PLAN_CELLS` (the
    body far from the map it was given: a stale map or odometry that jumped)."""
    res = view.resolution
    rows, cols = view.obstacle.shape
    top = view.origin + np.array([cols, rows]) * res
    lo = np.minimum(points.min(axis=0) - margin, view.origin)
    hi = np.maximum(points.max(axis=0) + margin, top)
    cells = float(np.prod(np.ceil((hi - lo) / res)))
    if not cells <= PLAN_CELLS:
        raise CommandError(f"planning from ({points[0, 0]:.6g}, {points[0, 1]:.6g}) on the map "
                           f"at ({view.origin[0]:.6g}, {view.origin[1]:.6g}) would take "
                           f"{cells:.3g} cells, beyond the budget of {PLAN_CELLS:g}: the body "
                           "is far from its map")
    before = np.ceil((view.origin - lo) / res - 1e-9).astype(int)
    after = np.ceil((hi - top) / res - 1e-9).astype(int)
    obstacle = np.pad(view.obstacle, ((before[1], after[1]), (before[0], after[0])))
    return Grid(obstacle, view.origin - before * res, res)


def carrot(path: np.ndarray, distance: float) -> np.ndarray:
    """The point ``distance`` [m] along the polyline ``(n, 2)`` (its end when shorter)."""
    along = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))))
    k = int(np.searchsorted(along, distance))
    return path[min(k, len(path) - 1)]


@dataclass
class ApfNavigator:
    """The ``apf`` method: goto and follow on the improved potential field."""

    settings: NavigatorSettings = field(default_factory=NavigatorSettings)
    state: NavState = NavState.IDLE
    reason: str = ""
    goal: np.ndarray | None = None
    heading: float | None = None
    distance: float | None = None  # to the goal, or of the length still to follow [m]
    rule: Rule | None = None  # the virtual-body rules do not apply: always None
    mode: Mode = Mode.GOTO
    command: FollowCommand | None = None
    virtual_goals: list[np.ndarray] = field(default_factory=list)  # in use [m]
    distinct: list[np.ndarray] = field(default_factory=list)  # used since the goal [m]
    path_length: float | None = None  # of the last plan [m]
    walked: float = 0.0  # along the structure [m]
    disc: float = 0.0  # the field's disc radius of the last cycle (virtual radius + margin) [m]
    _since: float = 0.0
    _last: np.ndarray | None = None
    _trapped_at: float | None = None  # since when the plans are trapped [s]
    tolerance: float = NavigatorSettings.goal_tolerance  # the goal's, of set_goal [m]

    def _start(self, mode: Mode, now: float) -> None:
        self.mode, self.state, self.reason, self._since = mode, NavState.ACTIVE, "", now
        self.virtual_goals, self.distinct, self.walked, self._last = [], [], 0.0, None
        self.heading, self.distance, self.path_length = None, None, None
        self._trapped_at = None

    def set_goal(self, x: float, y: float, now: float, tolerance: float | None = None
                 ) -> None:
        """A new goal (odom frame [m]), arrived within ``tolerance`` [m] (None: the settings'
        ``goal_tolerance``); raises `CommandError` for a non-finite goal or a tolerance not
        > 0."""
        if not (math.isfinite(x) and math.isfinite(y)):
            raise CommandError(f"goal ({x}, {y}) is not finite; give x and y in metres")
        if tolerance is not None and not (math.isfinite(tolerance) and tolerance > 0):
            raise CommandError(f"goal tolerance {tolerance} must be a finite number > 0 [m]")
        self._start(Mode.GOTO, now)
        self.goal, self.command = np.array([x, y]), None
        self.tolerance = self.settings.goal_tolerance if tolerance is None else tolerance

    def set_follow(self, command: FollowCommand, now: float) -> None:
        """Follow the nearest structure from the body's pose at the next map update."""
        self._start(Mode.FOLLOW, now)
        self.goal, self.command = None, command

    def cancel(self, reason: str = "cancelled") -> bool:
        """Drop the goal; True when a walk must be stopped (it was ACTIVE)."""
        was_active = self.state is NavState.ACTIVE
        self.state, self.reason, self.goal, self.command = NavState.IDLE, reason, None, None
        self.virtual_goals = []
        return was_active

    def fail(self, reason: str) -> bool:
        """End an ACTIVE goal as FAILED with ``reason``; True if it was ACTIVE."""
        if self.state is not NavState.ACTIVE:
            return False
        self._finish(NavState.FAILED, reason)
        return True

    def status(self) -> dict:
        """The ``navigation_status`` fields."""
        c = self.command
        return {"state": self.state.value, "reason": self.reason, "method": Method.APF.value,
                "mode": self.mode.value,
                "goal": None if self.goal is None else [float(v) for v in self.goal],
                "heading": self.heading, "distance": self.distance, "rule": None,
                "virtual_goals": [[round(float(v), 3) for v in g] for g in self.virtual_goals],
                "virtual_goals_used": len(self.distinct), "path_length": self.path_length,
                "disc_radius": round(self.disc, 4), "tolerance": self.tolerance,
                "follow": None if c is None else {"length": c.length, "side": c.side.value,
                                                   "walked": round(self.walked, 3)}}

    def _finish(self, state: NavState, reason: str) -> Output:
        self.state, self.reason = state, reason
        return Output(twist=(0.0, 0.0, 0.0), changed=True)

    def _goto(self, fld: ObstacleField, xy: np.ndarray) -> PlanResult:
        """Plan through the virtual goals still in use (farther than the look-ahead and still
        ρ_o clear on the grown map) to the goal; when that is trapped, once more straight to
        the goal with fresh virtual goals."""
        ahead, standoff = self.settings.path_lookahead, fld.settings.standoff
        pending = [v for v in self.virtual_goals
                   if math.hypot(*(v - xy)) > ahead and float(fld.clearance(v)[0]) >= standoff]
        res = self._chain(fld, xy, pending)
        return self._chain(fld, xy, []) if pending and not res.reached else res

    def _chain(self, fld: ObstacleField, xy: np.ndarray, pending: list[np.ndarray]
               ) -> PlanResult:
        assert self.goal is not None
        raw, used, p = [xy[None, :]], [], xy
        for target in [*pending, self.goal]:
            res = plan(fld, p, target, ApfMethod.APF_VIRTUAL, PlanSettings())
            raw.append(res.raw[1:])
            used += res.virtual_goals + ([target] if target is not self.goal else [])
            self._remember(used)
            if not res.reached:
                return PlanResult(np.vstack(raw), False, res.reason, used, np.vstack(raw))
            p = target
        self.virtual_goals = used
        path = np.vstack(raw)
        return PlanResult(path, True, "reached", used, path)

    def _field(self, grid: Grid, xy: np.ndarray, radius: float) -> ObstacleField:
        """The field of the disc radius + margin; when the body is already closer to an
        obstacle than that, the disc gives way to the one that just clears (by `SQUEEZE`) so
        the plan leads out: the margin first, then, when the map grew into the bare virtual
        radius (a face revealed as the robot came near), down to `ESCAPE_SHARE` of it. A body
        closer still is refused by the planner."""
        fs = FieldSettings(standoff=self.settings.standoff)
        fld = ObstacleField(grid, radius + self.settings.margin, fs)
        rho = float(fld.clearance(xy)[0])
        if rho > 0:
            return fld
        return ObstacleField(grid, max(ESCAPE_SHARE * radius, fld.radius + rho - SQUEEZE), fs)

    def _remember(self, goals: list[np.ndarray]) -> None:
        """Count a virtual goal once: re-plans place it again a little apart (within
        `SAME_GOAL`)."""
        for v in goals:
            if all(math.hypot(*(v - w)) > SAME_GOAL for w in self.distinct):
                self.distinct.append(v)

    def _progress(self, xy: np.ndarray) -> Output | None:
        """Distance left; the finishing output when arrived."""
        s = self.settings
        if self.mode is Mode.GOTO:
            assert self.goal is not None
            self.distance = float(np.hypot(*(self.goal - xy)))
            if self.distance <= self.tolerance:
                return self._finish(NavState.ARRIVED, f"within {self.tolerance:g} m of the "
                                    "goal")
            return None
        assert self.command is not None
        if self._last is not None:
            self.walked += float(np.hypot(*(xy - self._last)))
        self._last = xy
        self.distance = max(self.command.length - self.walked, 0.0)
        if self.distance <= s.goal_tolerance:
            return self._finish(NavState.ARRIVED, f"walked {self.walked:.3f} m along the "
                                "structure")
        return None

    def _trapped(self, reason: str, now: float) -> Output:
        """A trapped plan: stand and plan again on the next maps, FAILED after
        `TRAP_PATIENCE`."""
        if self._trapped_at is None:
            self._trapped_at = now
        if now - self._trapped_at >= TRAP_PATIENCE:
            return self._finish(NavState.FAILED, f"trapped: {reason}")
        self.reason = f"trapped, planning again for up to {TRAP_PATIENCE:g} s: {reason}"
        return Output(twist=(0.0, 0.0, 0.0), changed=True)

    def step(self, pose: tuple[float, float, float], radius: float, view: TerrainView,
             now: float) -> Output:
        """One cycle from the body pose (x, y [m], yaw [rad]), the virtual radius [m] and
        the map: the twist to send."""
        if self.state is not NavState.ACTIVE:
            return Output(twist=None)
        s = self.settings
        xy = np.array(pose[:2], dtype=float)
        done = self._progress(xy)
        if done is not None:
            return done
        if now - self._since > s.timeout:
            return self._finish(NavState.FAILED, f"not arrived within {s.timeout:g} s")
        points = xy[None, :] if self.goal is None else np.vstack((xy, self.goal))
        margin = radius + s.margin + 2.0 * s.standoff + 0.5
        try:
            fld = self._field(planning_grid(view, points, margin), xy, radius)
            self.disc = fld.radius
            if self.mode is Mode.GOTO:
                res = self._goto(fld, xy)
            else:
                assert self.command is not None
                side = 1 if self.command.side is Side.RIGHT else -1
                res = follow(fld, xy, min(self.distance or 0.0, 4.0 * s.path_lookahead) + 0.02,
                             side)
        except CommandError as exc:
            return self._finish(NavState.FAILED, str(exc))
        self.path_length = round(res.length, 3)
        if not res.reached:
            return self._trapped(res.reason, now)
        self._trapped_at, self.reason = None, ""
        aim = carrot(res.raw, s.path_lookahead) - xy
        self.heading = math.atan2(aim[1], aim[0])
        slow = 1.0 if self.mode is Mode.FOLLOW else min(1.0, self.distance / s.slow_radius)
        speed = s.speed * max(0.25, slow)
        cmd = twist(s.steering, self.heading - pose[2], speed, s.lever, s.max_yaw_rate)
        return Output(twist=cmd, heading=self.heading)
