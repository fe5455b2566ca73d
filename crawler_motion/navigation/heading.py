"""The heading rules of the virtual body (spec §4), in the goal frame: x from the robot towards
the goal, y to its left; angles [rad], + counter-clockwise.

- **Clearance radius** ``Rc``: the virtual radius plus a margin plus half a cell diagonal, so a
  circle ``Rc`` from a cell centre keeps the virtual circle off the whole cell.
- **Too close**: an obstacle cell N with ``|ON| <= Rc``: head perpendicular to ON (turn away
  by 90°), of the two perpendiculars the one nearer the goal direction (ties: the chosen side).
- **Tangent law**: each obstacle cell ahead (x > 0) within ``lookahead`` and not beyond the
  goal blocks the headings ``atan2(y_N, x_N) ± asin(Rc/|ON|)``; when the blocked intervals'
  union covers the goal direction, the heading is its edge on the chosen side: the tangent
  ``φ = atan2(y_N, x_N) ± asin(Rc/|ON|)`` of the boundary point N that defines that edge.
- **Side**: the side of the best direction T (lowest mean height of the known cells inside
  the virtual circle moved ``lookahead`` along each candidate; ties within ``tolerance`` go to
  the candidate nearest the goal direction); kept while the same blockage lasts; when T is
  straight ahead, the side of the smaller turn.
- **Back to the goal**: once no cell ahead blocks (the boundary point is behind, x_N < 0),
  the heading is the goal direction.
- **No way**: both edges more than ``max_turn`` from the goal direction: no heading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np


class Rule(Enum):
    """Which rule gave the heading."""

    GOAL = "goal"
    TANGENT = "tangent"
    TOO_CLOSE = "too_close"
    BLOCKED = "blocked"


@dataclass(frozen=True)
class Decision:
    """A heading in the goal frame [rad] (None when blocked), the rule, the side (+1 left,
    -1 right, 0 none) and the boundary point N in the goal frame [m] (None: no obstacle)."""

    heading: float | None
    rule: Rule
    side: int
    boundary: tuple[float, float] | None


@dataclass(frozen=True)
class HeadingSettings:
    """Clearance radius [m], look-ahead [m], largest turn from the goal direction [rad]."""

    clearance: float
    lookahead: float = 0.6
    max_turn: float = math.radians(100.0)


def blocked_interval(points: np.ndarray, clearance: float
                     ) -> tuple[float, float, int, int] | None:
    """The union of blocked heading intervals that contains 0: (low, high, index of the cell
    of the low edge, of the high edge); None when the goal direction is free."""
    d = np.hypot(points[:, 0], points[:, 1])
    theta = np.arctan2(points[:, 1], points[:, 0])
    alpha = np.arcsin(np.clip(clearance / d, 0.0, 1.0))
    lo, hi = theta - alpha, theta + alpha
    order = np.argsort(lo)
    low = high = None
    i_low = i_high = -1
    for k in order:  # merge the intervals sweeping up from the lowest
        if high is None or lo[k] > high:
            if high is not None and low <= 0.0 <= high:
                break
            low, high, i_low, i_high = lo[k], hi[k], k, k
        elif hi[k] > high:
            high, i_high = hi[k], k
    if high is None or not low <= 0.0 <= high:
        return None
    return float(low), float(high), int(i_low), int(i_high)


def decide(cells: np.ndarray, goal_distance: float, side: int, best: float,
           settings: HeadingSettings) -> Decision:
    """The heading for obstacle cells ``cells`` ``(k, 2)`` in the goal frame [m]; ``side`` the
    side kept from the last decision (0: none), ``best`` the best direction T [rad]."""
    rc = settings.clearance
    d = np.hypot(cells[:, 0], cells[:, 1]) if len(cells) else np.zeros(0)
    if len(cells) and d.min() <= rc:
        n = int(np.argmin(d))
        theta = math.atan2(cells[n, 1], cells[n, 0])
        options = [_wrap(theta + math.pi / 2), _wrap(theta - math.pi / 2)]
        gap = abs(abs(options[0]) - abs(options[1]))
        pick = (0 if side >= 0 else 1) if gap < 1e-9 else int(abs(options[1]) < abs(options[0]))
        return Decision(options[pick], Rule.TOO_CLOSE, side or (1 if pick == 0 else -1),
                        (float(cells[n, 0]), float(cells[n, 1])))
    ahead = (cells[:, 0] > 0.0) & (d <= settings.lookahead) & (d <= goal_distance + rc) \
        if len(cells) else np.zeros(0, dtype=bool)
    block = blocked_interval(cells[ahead], rc) if ahead.any() else None
    if block is None:
        return Decision(0.0, Rule.GOAL, 0, None)
    low, high, i_low, i_high = block
    if side == 0:
        side = (1 if best > 0 else -1) if abs(best) > 1e-9 else (1 if high <= -low else -1)
    ahead_cells = cells[ahead]
    for s in (side, -side):
        heading, k = (high, i_high) if s > 0 else (low, i_low)
        if abs(heading) <= settings.max_turn:
            n = ahead_cells[k]
            return Decision(heading, Rule.TANGENT, s, (float(n[0]), float(n[1])))
    return Decision(None, Rule.BLOCKED, side, None)


def best_direction(centres: np.ndarray, heights: np.ndarray, radius: float, lookahead: float,
                   candidates: np.ndarray, tolerance: float = 0.005) -> float:
    """The candidate [rad, goal frame] whose circle of ``radius`` moved ``lookahead`` along it
    covers known cells (``centres`` ``(k, 2)``, goal frame, ``heights`` ``(k,)``) of the lowest
    mean height; 0 when no candidate covers a known cell."""
    means = np.full(len(candidates), np.inf)
    for j, psi in enumerate(candidates):
        centre = lookahead * np.array([math.cos(psi), math.sin(psi)])
        inside = np.hypot(*(centres - centre).T) <= radius
        if inside.any():
            means[j] = heights[inside].mean()
    if not np.isfinite(means).any():
        return 0.0
    near = np.flatnonzero(means <= means.min() + tolerance)
    return float(candidates[near[np.argmin(np.abs(candidates[near]))]])


def _wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))
