"""Body sway of crawl gaits: the body centre kept inside the support polygon by a margin.

A crawl (wave) gait lifts one leg at a time, so three feet carry the body during a swing. The
body centre (the base_link origin; the legs are symmetric about it) must lie inside their
triangle, by the **stability margin** ``m`` [m], at every instant. In the plan's frame (the
body frame without sway) the stance feet are fixed points sliding back as the body advances;
the sway ``s`` [m] is an extra horizontal body offset, so every foot target in base_link is
its planned point minus ``s`` and the centre's position relative to the feet is ``s``.

The sway moves with the same rest sextic as the stance feet (v = a = 0 at every swing and
transfer junction), so the foot trajectories stay C² and made of the same segments. Over a
segment the stance feet and the sway both move along ``h(tau)`` from their start to their end
points: relative to a translating support triangle the centre travels a straight line, so if
both ends are ``m`` inside the triangle, every point between is (the distance to the boundary
of a convex set is concave). Turning rotates the triangle a little: the plan adds `SLACK` and
the sequencer checks the margin on samples of every slot.

The targets: at the end of each swing, the point nearest the body centre (no sway) that is
``m + SLACK`` inside the support triangle; at the end of each transfer (all feet down, the
support is the quadrilateral containing both triangles), the point nearest the centre inside
the *next* swing's triangle. The swing order (`creep_order`) follows the direction of travel:
hind leg, front leg on the same side, then the other side, which keeps the sway short.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

#: Extra planning margin over the stability margin [m] (rotation of the support while
#: turning, rounding).
SLACK = 0.002
#: Scale of the sway's (x, y) in the distance it minimises: the legs reach out sideways, so a
#: lateral sway costs reach (a sideways walk would leave the workspace); fore-aft is cheaper.
SWAY_SCALE = np.array([1.0, 5.0])
#: Sign pattern ``(along, left)`` of the creep order: hind-left, front-left, hind-right,
#: front-right, relative to the direction of travel.
CREEP_PATTERN = np.array([[-1.0, 1.0], [1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull ``(k, 2)`` of ``points`` ``(n, 2)`` [m] (monotone chain)."""
    pts = sorted({(float(x), float(y)) for x, y in np.asarray(points, dtype=float)})
    if len(pts) < 3:
        return np.array(pts, dtype=float).reshape(-1, 2)

    def cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    upper: list[tuple[float, float]] = []
    for chain, seq in ((lower, pts), (upper, pts[::-1])):
        for p in seq:
            while len(chain) >= 2 and cross(chain[-2], chain[-1], p) <= 0:
                chain.pop()
            chain.append(p)
    return np.array(lower[:-1] + upper[:-1], dtype=float)


def halfplanes(points: np.ndarray, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The support polygon of ``points`` ``(n, 2)`` shrunk by ``margin`` [m] as ``A p <= b``
    (unit outward normals ``A`` ``(k, 2)``); empty (k = 0) for fewer than 3 distinct points."""
    hull = convex_hull(points)
    if len(hull) < 3:
        return np.zeros((0, 2)), np.zeros(0)
    edges = np.roll(hull, -1, axis=0) - hull
    normals = np.stack((edges[:, 1], -edges[:, 0]), axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    return normals, np.einsum("ij,ij->i", normals, hull) - margin


def support_margin(points: np.ndarray, centre: np.ndarray | None = None) -> float:
    """Signed distance [m] of ``centre`` (default origin) inside the convex hull of ``points``
    ``(n, 2)``: > 0 inside, < 0 outside (the nearest edge line); -inf below 3 points."""
    a, b = halfplanes(points)
    if not len(a):
        return -math.inf
    c = np.zeros(2) if centre is None else np.asarray(centre, dtype=float)
    return float(np.min(b - a @ c))


def closest_inside(a: np.ndarray, b: np.ndarray, target: np.ndarray) -> np.ndarray | None:
    """The point of ``{p: a p <= b}`` nearest ``target`` ``(2,)``; None if the set is empty
    (2-D: the nearest point is the target, a projection on one edge line, or a vertex)."""
    tol = 1e-12
    target = np.asarray(target, dtype=float)
    candidates = [target]
    candidates += [target - (a[i] @ target - b[i]) * a[i] for i in range(len(a))]
    for i, j in itertools.combinations(range(len(a)), 2):
        det = a[i, 0] * a[j, 1] - a[i, 1] * a[j, 0]
        if abs(det) > 1e-12:
            candidates.append(np.linalg.solve(a[[i, j]], b[[i, j]]))
    feasible = [p for p in candidates if np.all(a @ p <= b + tol)]
    if not feasible:
        return None
    return min(feasible, key=lambda p: float(np.sum((p - target) ** 2)))


def sway_target(supports: list[np.ndarray], margin: float, centre: np.ndarray | None = None
                ) -> np.ndarray | None:
    """The sway ``(2,)`` [m] nearest ``centre`` (default 0, distances scaled by `SWAY_SCALE`)
    that is ``margin + SLACK`` inside every support polygon of ``supports`` (each ``(n, 2)``
    foot points); None if none is. A support of two feet (a line: the diagonal gait) gives the
    nearest point of its segment, whatever the margin."""
    hulls = [convex_hull(points) for points in supports]
    if len(hulls) == 1 and len(hulls[0]) == 2:
        return _nearest_on_segment(hulls[0], centre)
    if any(len(hull) < 3 for hull in hulls):
        return None
    parts = [halfplanes(hull, margin + SLACK) for hull in hulls]
    a = np.concatenate([p[0] for p in parts]) / SWAY_SCALE  # in scaled coordinates
    b = np.concatenate([p[1] for p in parts])
    norm = np.linalg.norm(a, axis=-1)
    centre = np.zeros(2) if centre is None else np.asarray(centre, dtype=float)
    best = closest_inside(a / norm[:, None], b / norm, centre * SWAY_SCALE)
    return None if best is None else best / SWAY_SCALE


def _nearest_on_segment(ends: np.ndarray, centre: np.ndarray | None) -> np.ndarray:
    """The point of the segment ``ends`` ``(2, 2)`` nearest ``centre`` (scaled distances)."""
    c = np.zeros(2) if centre is None else np.asarray(centre, dtype=float)
    a, b = ends * SWAY_SCALE
    d = b - a
    u = float(np.clip((c * SWAY_SCALE - a) @ d / max(float(d @ d), 1e-18), 0.0, 1.0))
    return (a + u * d) / SWAY_SCALE


def line_sways(first: np.ndarray, second: np.ndarray, travel: np.ndarray, weight: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """The sways ``(2,)`` [m] of a gait standing on support lines (the diagonal pairs): ``s1``
    on the segment ``first`` ``(2, 2)`` (the support at the end of a swing) and ``s2`` on
    ``second`` (the next support, at the end of the transfer after it; a point when both ends
    are equal), minimising the body's travel over the ground in the transfer,
    ``|travel - (s2 - s1)|²`` (``travel`` [m]: the planned motion of the contact points
    relative to the body in it), plus ``weight`` times ``|S s1|² + |S s2|²`` (`SWAY_SCALE`).

    The body keeps its support line under it and moves along it during the swing, so the
    transfer carries only what the line's direction cannot (walking forward, the lateral sway
    zig-zags along the diagonals); a large ``weight`` gives the nearest points of the segments
    (no motion along the line, the whole step in the transfer)."""
    a1, d1 = first[0], first[1] - first[0]
    a2, d2 = second[0], second[1] - second[0]
    sq = SWAY_SCALE ** 2
    r0 = travel - a2 + a1  # the transfer's travel with both sways at the segments' first ends
    hess = np.array([[d1 @ d1 + weight * (sq @ (d1 * d1)), -(d1 @ d2)],
                     [-(d1 @ d2), d2 @ d2 + weight * (sq @ (d2 * d2))]])
    hess += 1e-15 * np.eye(2)  # a point (d = 0) keeps its one position
    grad = np.array([r0 @ d1 + weight * (sq @ (a1 * d1)), -(r0 @ d2) + weight * (sq @ (a2 * d2))])

    def cost(u: float, w: float) -> float:
        x = np.array([u, w])
        return float(x @ hess @ x + 2.0 * grad @ x)

    # a convex quadratic on the unit square: its free minimum if inside, else on an edge
    candidates = [tuple(np.clip(np.linalg.solve(hess, -grad), 0.0, 1.0))]
    for fixed in (0.0, 1.0):
        candidates.append((fixed, float(np.clip(-(grad[1] + hess[1, 0] * fixed) / hess[1, 1],
                                                0.0, 1.0))))
        candidates.append((float(np.clip(-(grad[0] + hess[0, 1] * fixed) / hess[0, 0],
                                         0.0, 1.0)), fixed))
    u, w = min(candidates, key=lambda c: cost(*c))
    return a1 + u * d1, a2 + w * d2


def creep_order(feet: np.ndarray, heading: float) -> tuple[int, ...]:
    """Leg indices in swing order for travel towards ``heading`` [rad] (base_link): hind-left,
    front-left, hind-right, front-right relative to the direction of travel, from the standing
    feet ``feet`` ``(4, 2)`` [m] (the assignment that best matches `CREEP_PATTERN`)."""
    d = np.array([math.cos(heading), math.sin(heading)])
    local = np.stack((feet @ d, feet @ np.array([-d[1], d[0]])), axis=-1)
    best = max(itertools.permutations(range(len(feet))),
               key=lambda perm: float(sum(CREEP_PATTERN[k] @ local[leg]
                                          for k, leg in enumerate(perm))))
    return tuple(best)
