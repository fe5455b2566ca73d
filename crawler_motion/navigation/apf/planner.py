"""Paths on the improved field: fixed-step descent, virtual goals, every-5th-point smoothing,
and following a structure at the stand-off distance (pure).

``p_{n+1} = p_n + s F/|F|`` with F = −∇U (`field`). The goal is reached when it is within one
step (the last point is the goal itself). The plan ends *trapped*, with the reason, when the
local-minimum test fires and no virtual goal is allowed or found, when the step budget or the
virtual-goal budget runs out, when a step would leave the map or make the disc overlap an
obstacle cell, or when F vanishes. The path kept is every 5th point of the small steps plus the
last one (the study's smoothing of the fixed step's saw-tooth).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from crawler_motion.errors import CommandError, ConfigError
from crawler_motion.navigation.apf.field import ObstacleField
from crawler_motion.navigation.apf.virtual import place_virtual_goal, trapped


class ApfMethod(Enum):
    """Plain field, or the field with virtual goals past local minima."""

    APF = "apf"
    APF_VIRTUAL = "apf-virtual"


@dataclass(frozen=True)
class PlanSettings:
    """Step and budgets."""

    step: float = 0.01  # s [m]
    keep_every: int = 5  # smoothing: every k-th point is kept
    max_steps: int = 20000
    max_virtual: int = 10
    open_check: int = 25  # steps between checks for an open line to the goal (`open_line`)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.step) and self.step > 0):
            raise ConfigError(f"step must be a finite number > 0 m, got {self.step}")
        if (self.keep_every < 1 or self.max_steps < 1 or self.max_virtual < 0
                or self.open_check < 1):
            raise ConfigError("keep_every, max_steps and open_check must be >= 1, "
                              "max_virtual >= 0")


@dataclass
class PlanResult:
    """A path [m] (kept points ``(n, 2)``), whether it reached the goal, why not, the
    virtual goals placed, and the small steps taken ``(m, 2)``."""

    path: np.ndarray
    reached: bool
    reason: str
    virtual_goals: list[np.ndarray] = field(default_factory=list)
    raw: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def length(self) -> float:
        """Length of the kept path [m]."""
        return path_length(self.path)


def path_length(path: np.ndarray) -> float:
    """Length of a polyline ``(n, 2)`` [m]."""
    return float(np.hypot(*np.diff(path, axis=0).T).sum()) if len(path) > 1 else 0.0


def densify(path: np.ndarray, spacing: float) -> np.ndarray:
    """Points along the polyline ``(n, 2)`` at most ``spacing`` apart (ends included)."""
    if len(path) < 2:
        return np.asarray(path, dtype=float)
    seg = np.diff(path, axis=0)
    n = np.maximum(np.ceil(np.hypot(*seg.T) / spacing).astype(int), 1)
    parts = [path[i] + np.outer(np.arange(k) / k, seg[i]) for i, k in enumerate(n)]
    return np.vstack([*parts, path[-1:]])


def min_clearance(fld: ObstacleField, path: np.ndarray) -> float:
    """Smallest disc clearance along the polyline (sampled every quarter cell) [m]."""
    return float(fld.clearance(densify(path, fld.grid.resolution / 4))[0].min())


def check_point(fld: ObstacleField, p: np.ndarray, what: str) -> np.ndarray:
    """``p`` as an array; `CommandError` when not finite, off the map or not clear."""
    p = np.asarray(p, dtype=float)
    if p.shape != (2,) or not np.isfinite(p).all():
        raise CommandError(f"{what} {p.tolist()} is not a finite x y pair in metres")
    if not fld.grid.inside(p):
        x0, x1, y0, y1 = fld.grid.extent
        raise CommandError(f"{what} ({p[0]:g}, {p[1]:g}) is outside the map "
                           f"[{x0:g}, {x1:g}] x [{y0:g}, {y1:g}] m")
    rho = float(fld.clearance(p)[0])
    if rho <= 0:
        raise CommandError(f"{what} ({p[0]:g}, {p[1]:g}) is inside an obstacle: the disc of "
                           f"radius {fld.radius:.3f} m overlaps an obstacle cell by {-rho:.3f} m")
    return p


def open_line(fld: ObstacleField, p: np.ndarray, goal: np.ndarray) -> bool:
    """Whether the segment from ``p`` to ``goal`` stays where the field is the goal's attraction
    alone: at least disc radius + ρ_a from every obstacle cell (centre distance less half a
    cell's diagonal: conservative). There the descent is the straight line to the goal, which
    `plan` then takes at once instead of step by step: far goals cost what the map window
    holds, not what the distance is."""
    if not len(fld.cells):
        return True
    seg = goal - p
    length2 = float(seg @ seg)
    t = np.clip(((fld.cells - p) @ seg) / length2, 0.0, 1.0) if length2 > 0 else 0.0
    near = fld.cells - (p + np.outer(t, seg))
    reach = fld.radius + fld.settings.band * fld.settings.standoff
    reach += fld.grid.resolution / math.sqrt(2.0)
    return bool(np.hypot(near[:, 0], near[:, 1]).min() >= reach)


def _straight(p: np.ndarray, goal: np.ndarray, step: float) -> list[np.ndarray]:
    """Steps of ``step`` [m] from ``p`` (excluded) towards ``goal``, then ``goal`` itself
    (the last step at most ``step``), as the step-by-step descent takes them."""
    d = math.hypot(*(goal - p))
    n = max(0, math.ceil(d / step) - 1)
    return [*(p + np.outer(np.arange(1, n + 1) * step / d, goal - p)), goal]


def _keep(raw: list[np.ndarray], every: int) -> np.ndarray:
    pts = np.array(raw)
    kept = pts[::every]
    return kept if (len(pts) - 1) % every == 0 else np.vstack([kept, pts[-1:]])


def _move(fld: ObstacleField, p: np.ndarray, direction: np.ndarray, step: float
          ) -> tuple[np.ndarray | None, str]:
    """One fixed step along ``direction``; None and the reason when it cannot be taken."""
    norm = math.hypot(*direction)
    if not math.isfinite(norm) or norm < 1e-12:
        return None, "the field vanishes (a saddle or a balanced point)"
    q = p + step * direction / norm
    if not fld.grid.inside(q):
        return None, f"the next step ({q[0]:.3f}, {q[1]:.3f}) leaves the map"
    if float(fld.clearance(q)[0]) <= 0:
        return None, f"the next step ({q[0]:.3f}, {q[1]:.3f}) would touch an obstacle"
    return q, ""


def plan(fld: ObstacleField, start: np.ndarray, goal: np.ndarray, method: ApfMethod,
         settings: PlanSettings | None = None) -> PlanResult:
    """Plan from ``start`` to ``goal`` (map frame [m]); both checked (`CommandError`)."""
    s = settings or PlanSettings()
    p, goal = check_point(fld, start, "start"), check_point(fld, goal, "goal")
    raw, since, target = [p], 0, goal
    used: list[np.ndarray] = []
    reason = f"step budget of {s.max_steps} steps used up"
    for k in range(s.max_steps):
        if math.hypot(*(p - goal)) <= s.step or (
                target is goal and k % s.open_check == 0 and open_line(fld, p, goal)):
            raw += _straight(p, goal, s.step)
            return PlanResult(_keep(raw, s.keep_every), True, "reached", used, np.array(raw))
        if target is not goal and math.hypot(*(p - target)) <= 2.0 * s.step:
            target, since = goal, len(raw) - 1
        if trapped(np.array(raw[since:]), target, s.step):
            if method is ApfMethod.APF:
                reason = f"local minimum at ({p[0]:.3f}, {p[1]:.3f})"
                break
            if len(used) >= s.max_virtual:
                reason = f"still trapped after {len(used)} virtual goals (the budget)"
                break
            v = place_virtual_goal(fld, p, target, s.step, used)
            if v is None:
                reason = f"local minimum at ({p[0]:.3f}, {p[1]:.3f}) and no virtual goal fits"
                break
            used.append(v)
            target, since = v, len(raw) - 1
        q, why = _move(fld, p, -fld.potential(p, target)[1], s.step)
        if q is None:
            reason = why
            break
        p = q
        raw.append(p)
    return PlanResult(_keep(raw, s.keep_every), False, reason, used, np.array(raw))


def follow(fld: ObstacleField, start: np.ndarray, length: float, side: int = 1,
           settings: PlanSettings | None = None) -> PlanResult:
    """Walk along the nearest structure for ``length`` metres of path, the structure on the
    right (``side`` +1) or left (−1): the step follows the tangent of the structure plus the
    obstacle terms of the field (repulsion below ρ_o, attraction above it). Beyond the band
    (ρ ≥ ρ_a) the step heads straight for the structure. Ends trapped as `plan` does."""
    s = settings or PlanSettings()
    if side not in (1, -1):
        raise CommandError(f"side must be +1 (structure on the right) or -1 (left), got {side}")
    if not (math.isfinite(length) and length > 0):
        raise CommandError(f"follow length must be a finite number > 0 m, got {length}")
    p = check_point(fld, start, "start")
    if not len(fld.cells):
        raise CommandError("there is no structure on the map to follow")
    raw, walked, band = [p], 0.0, fld.settings.band * fld.settings.standoff
    reason = f"step budget of {s.max_steps} steps used up"
    for _ in range(s.max_steps):
        if walked >= length - 1e-9:
            return PlanResult(_keep(raw, s.keep_every), True, "reached", [], np.array(raw))
        rho, grad = fld.clearance(p)
        tangent = side * np.array([grad[1], -grad[0]])
        direction = -grad if rho >= band else tangent + fld.obstacle_force(p)
        q, why = _move(fld, p, direction, min(s.step, length - walked))
        if q is None:
            reason = why
            break
        walked += math.hypot(*(q - p))
        p = q
        raw.append(p)
    return PlanResult(_keep(raw, s.keep_every), False, reason, [], np.array(raw))
