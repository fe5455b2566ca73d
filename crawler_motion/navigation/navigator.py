"""The navigator's core: goal, state, and per map update a heading and a twist (pure).

States (`NavState`): ``IDLE`` (no goal) -> ``ACTIVE`` (a goal) -> ``ARRIVED`` (within
``goal_tolerance``) or ``FAILED`` (with a reason: the goal lies inside an obstacle, no heading
clears the obstacles, the time ran out). Leaving ``ACTIVE`` asks for a stop (a zero twist; the
planner then stands). The methods' registry is `methods.METHODS`; this module holds the shared
types and the ``virtual_body`` method.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from crawler_motion.errors import CommandError
from crawler_motion.navigation.heading import (
    Decision,
    HeadingSettings,
    Rule,
    best_direction,
    decide,
)
from crawler_motion.navigation.steering import Steering, twist

#: Candidate directions of the best-direction search, goal frame [rad].
CANDIDATES = np.radians(np.arange(-90.0, 90.1, 10.0))


class NavState(Enum):
    """Navigation states, as ``navigation_status`` names them."""

    IDLE = "IDLE"
    ACTIVE = "ACTIVE"
    ARRIVED = "ARRIVED"
    FAILED = "FAILED"


class Method(Enum):
    """Obstacle-avoidance methods of the navigator."""

    VIRTUAL_BODY = "virtual_body"
    APF = "apf"


@dataclass(frozen=True)
class NavigatorSettings:
    """Steering and limits (SI units)."""

    steering: Steering = Steering.CRAB
    speed: float = 0.08  # [m/s]
    lever: float = 0.12  # S of the radius law [m]
    max_yaw_rate: float = 0.2  # [rad/s]
    goal_tolerance: float = 0.05  # [m]
    slow_radius: float = 0.2  # speed falls linearly to 1/4 within this distance [m]
    margin: float = 0.10  # added to the virtual radius [m]
    lookahead: float = 0.6  # [m]
    max_turn: float = math.radians(100.0)  # [rad]
    timeout: float = 300.0  # [s]
    standoff: float = 0.10  # apf: ρ_o, repulsion range and stand-off distance [m]
    path_lookahead: float = 0.25  # apf: steer to the path point this far along it [m]
    max_goal_distance: float = 10.0  # a goal farther from the body is refused [m]


def goal_error(x: float, y: float, body: tuple[float, float] | None,
               max_distance: float) -> str | None:
    """Why a goal at (``x``, ``y``) [m, odom] is refused with the body at ``body`` (None: no
    odometry yet, the origin is used): not finite, or farther than ``max_distance`` [m]
    (planning that far on the map window costs seconds per cycle and gigabytes); None if it
    is accepted."""
    if not (math.isfinite(x) and math.isfinite(y)):
        return f"goal ({x}, {y}) is not finite; give x and y in metres"
    bx, by = (0.0, 0.0) if body is None else body
    distance = math.hypot(x - bx, y - by)
    if not distance <= max_distance:
        far = f"{distance:.6g} m" if math.isfinite(distance) else "more than 1e308 m"
        return (f"goal ({x:.6g}, {y:.6g}) is {far} from the body, beyond max_goal_distance "
                f"{max_distance:g} m; send nearer goals (waypoints)")
    return None


@dataclass(frozen=True)
class TerrainView:
    """The map as the navigator sees it: origin (x, y of the corner) [m], cell size [m], and
    per cell (rows y, columns x) known flag, obstacle flag and height [m]."""

    origin: np.ndarray
    resolution: float
    known: np.ndarray
    obstacle: np.ndarray
    height: np.ndarray

    def centres(self, mask: np.ndarray) -> np.ndarray:
        """Cell centres ``(k, 2)`` [m] of the cells where ``mask``."""
        rows, cols = np.nonzero(mask)
        return self.origin + (np.column_stack((cols, rows)) + 0.5) * self.resolution


@dataclass
class Output:
    """One navigator cycle: the twist to send (None: send nothing) and the decision."""

    twist: tuple[float, float, float] | None
    decision: Decision | None = None
    heading: float | None = None  # world [rad]
    changed: bool = False


@dataclass
class VirtualBodyNavigator:
    """The virtual-body method: heading rules of `heading`, steering of `steering`."""

    settings: NavigatorSettings = field(default_factory=NavigatorSettings)
    state: NavState = NavState.IDLE
    reason: str = ""
    goal: np.ndarray | None = None
    heading: float | None = None
    distance: float | None = None
    rule: Rule | None = None
    _side: int = 0
    _since: float = 0.0

    def set_goal(self, x: float, y: float, now: float) -> None:
        """A new goal (odom frame [m]); raises `CommandError` for a non-finite one."""
        if not (math.isfinite(x) and math.isfinite(y)):
            raise CommandError(f"goal ({x}, {y}) is not finite; give x and y in metres")
        self.goal, self.state, self.reason = np.array([x, y]), NavState.ACTIVE, ""
        self._side, self._since, self.heading, self.rule = 0, now, None, None

    def cancel(self, reason: str = "cancelled") -> bool:
        """Drop the goal; True when a walk must be stopped (it was ACTIVE)."""
        was_active = self.state is NavState.ACTIVE
        self.state, self.reason, self.goal = NavState.IDLE, reason, None
        return was_active

    def fail(self, reason: str) -> bool:
        """End an ACTIVE goal as FAILED with ``reason``; True if it was ACTIVE."""
        if self.state is not NavState.ACTIVE:
            return False
        self._finish(NavState.FAILED, reason)
        return True

    def status(self) -> dict:
        """The ``navigation_status`` fields."""
        return {"state": self.state.value, "reason": self.reason,
                "method": Method.VIRTUAL_BODY.value,
                "goal": None if self.goal is None else [float(v) for v in self.goal],
                "heading": self.heading, "distance": self.distance,
                "rule": None if self.rule is None else self.rule.value}

    def _finish(self, state: NavState, reason: str) -> Output:
        self.state, self.reason = state, reason
        return Output(twist=(0.0, 0.0, 0.0), changed=True)

    def step(self, pose: tuple[float, float, float], radius: float, view: TerrainView,
             now: float) -> Output:
        """One cycle from the body pose (x, y [m], yaw [rad]), the virtual radius [m] and
        the map: the twist to send and what was decided."""
        if self.state is not NavState.ACTIVE or self.goal is None:
            return Output(twist=None)
        s = self.settings
        x, y, yaw = pose
        to_goal = self.goal - np.array([x, y])
        self.distance = float(np.hypot(*to_goal))
        if self.distance <= s.goal_tolerance:
            return self._finish(NavState.ARRIVED, f"within {s.goal_tolerance:g} m of the goal")
        if now - self._since > s.timeout:
            return self._finish(NavState.FAILED, f"not arrived within {s.timeout:g} s")
        clearance = radius + s.margin + view.resolution / math.sqrt(2.0)
        obstacles = view.centres(view.obstacle)
        if len(obstacles) and np.hypot(*(obstacles - self.goal).T).min() <= clearance:
            return self._finish(NavState.FAILED, "goal inside an obstacle: the virtual body "
                                f"(clearance {clearance:.3f} m) would overlap an obstacle cell")
        gamma = math.atan2(to_goal[1], to_goal[0])
        rot = np.array([[math.cos(gamma), math.sin(gamma)], [-math.sin(gamma), math.cos(gamma)]])
        local = (obstacles - [x, y]) @ rot.T
        best = 0.0
        if self._side == 0:
            known = (view.centres(view.known) - [x, y]) @ rot.T
            best = best_direction(known, view.height[view.known], radius, s.lookahead,
                                  CANDIDATES)
        decision = decide(local, self.distance, self._side,
                          best, HeadingSettings(clearance, s.lookahead, s.max_turn))
        self.rule, self._side = decision.rule, decision.side
        if decision.heading is None:
            out = self._finish(NavState.FAILED, "no heading clears the obstacles within "
                               f"{math.degrees(s.max_turn):.0f}° of the goal direction")
            out.decision = decision
            return out
        self.heading = gamma + decision.heading
        speed = s.speed * max(0.25, min(1.0, self.distance / s.slow_radius))
        cmd = twist(s.steering, self.heading - yaw, speed, s.lever, s.max_yaw_rate)
        return Output(twist=cmd, decision=decision, heading=self.heading)

