"""The local-minimum test and the virtual goals of the study's §2.3, with its holes closed.

- **Trapped** (the study's test, with n−5 for its n+5): ``|p_n − T| > 2s`` and
  ``|p_n − p_{n−5}| < 1.5 s``, T the current target, s the step. *Rule:* the five points must
  all lie after the last change of target, so the test cannot fire again right after a switch.
- **Virtual goal** V for a local minimum L and target T: the perpendicular bisector of LT,
  through the midpoint M, is walked from M in both directions (samples every half cell). On
  each side: the first obstacle run the ray meets (M itself may lie inside it) and the point
  where the ray leaves that run (the far boundary); V is the first sample beyond it where the
  disc is at least ρ_o clear of every obstacle (for a straight wall: ρ_o + R beyond the
  boundary). *Rules:* a side whose ray leaves the map first gives no candidate; when neither
  side meets an obstacle, the candidates are the first samples at least ``|LT|/2`` from M that
  are ρ_o clear; a candidate within 2s of a virtual goal already used is dropped; of the two
  the one with the shorter detour ``|LV| + |VT|`` wins, ties to the left of L→T. No candidate:
  no virtual goal (the plan ends trapped).
- **Reached:** V counts as reached within 2s; the target then goes back to the goal G.
  Trapped on the way to V: the next V is placed on the bisector of the new L and V (the study's
  "bisect L and V").
"""

from __future__ import annotations

import math

import numpy as np

from crawler_motion.navigation.apf.field import ObstacleField

#: Steps of the progress window of the local-minimum test.
WINDOW = 5


def trapped(points: np.ndarray, target: np.ndarray, step: float) -> bool:
    """The local-minimum test on the points since the last target change ``(n, 2)``."""
    if len(points) <= WINDOW:
        return False
    p = points[-1]
    far = math.hypot(*(p - target)) > 2.0 * step
    return bool(far and math.hypot(*(p - points[-1 - WINDOW])) < 1.5 * step)


def _first_clear(field: ObstacleField, pts: np.ndarray) -> np.ndarray | None:
    """The first of ``pts`` where the disc is at least ρ_o clear, or None."""
    if not len(pts):
        return None
    clear = field.clearance(pts)[0] >= field.settings.standoff
    return pts[int(np.argmax(clear))] if clear.any() else None


def _side(field: ObstacleField, mid: np.ndarray, u: np.ndarray, reach: float,
          half: float) -> tuple[bool, np.ndarray | None]:
    """Along the ray ``mid + t u`` (t >= 0, on the map): whether it meets an obstacle, and the
    candidate (beyond the obstacle when it meets one, else at least ``half`` from ``mid``)."""
    grid = field.grid
    t = np.arange(0.0, reach, grid.resolution / 2)
    pts = mid + t[:, None] * u
    on_map = grid.inside(pts)
    if not on_map.all():
        pts, t = pts[:int(np.argmin(on_map))], t[:int(np.argmin(on_map))]
    occ = grid.occupied(pts)
    if not occ.any():
        return False, _first_clear(field, pts[int(np.searchsorted(t, half)):])
    enter = int(np.argmax(occ))
    free_after = ~occ[enter:]
    if not free_after.any():
        return True, None
    return True, _first_clear(field, pts[enter + int(np.argmax(free_after)):])


def place_virtual_goal(field: ObstacleField, local_min: np.ndarray, target: np.ndarray,
                       step: float, used: list[np.ndarray]) -> np.ndarray | None:
    """The virtual goal for the local minimum ``local_min`` and the current ``target`` [m]."""
    lt = np.asarray(target, float) - np.asarray(local_min, float)
    length = math.hypot(*lt)
    if length == 0.0:
        return None
    mid = (np.asarray(local_min, float) + np.asarray(target, float)) / 2
    left = np.array([-lt[1], lt[0]]) / length
    x0, x1, y0, y1 = field.grid.extent
    reach = math.hypot(x1 - x0, y1 - y0)
    sides = [_side(field, mid, u, reach, length / 2) for u in (left, -left)]
    met = any(m for m, _ in sides)
    best: tuple[float, np.ndarray] | None = None
    for hit, v in sides:
        if v is None or hit != met or any(math.hypot(*(v - w)) <= 2.0 * step for w in used):
            continue
        detour = math.hypot(*(v - local_min)) + math.hypot(*(target - v))
        if best is None or detour < best[0] - 1e-9:
            best = (detour, v)
    return None if best is None else best[1]
