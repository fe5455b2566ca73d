"""Body motion of pair gaits planned from the zero-moment point (pure numpy).

On two stance feet the body is a linear inverted pendulum about their support line
(docs/gaits.md, "The field walk"). With the centre of mass ``c`` (horizontal, [m]) at the
height ``h`` above the ground, the zero-moment point of the cart-table model is

    p = c - c'' / w² + shift,    w² = g net / ((1 + added) h)

(`crawler_motion.model.medium.MediumConfig`: net weight, added mass, buoyancy offset). Two
point feet carry no moment about the line joining them, so ``p`` must lie **on the active
diagonal** at every instant of a swing, and at the crossing of both diagonals at each switch.
A body moving at constant velocity has ``p = c``, up to ~15 mm off the line: the rocking.

The plan: the body's walk (the stance feet's motion in the body frame, `motion.slot`) is kept
and a horizontal **sway** ``s(t)`` is added to it (every foot target in base_link is its
planned point minus ``s``, as for the crawl sway of `motion.sway`). ``s`` is a C² chain of
sextic segments with knots at the swing's phase junctions; its knot states (position,
velocity, acceleration) and each segment's mid-time position are the unknowns of a linear
least-squares problem over a horizon of this slot and a preview of the next one (the same
steady walk of the same stride and heading; Kalakrishnan et al. 2010 plan a trot's body
spline the same way):

- the ZMP's distance to the active support line at every sample (weight `ZmpWeights.line`);
- small terms that keep the sway and its acceleration small where the line leaves them free
  (along the line, and with every foot down);
- the first knot is the state the last slot ended in (C² across slots); a final slot ends at
  rest with no sway (the robot stands).

Only this slot's segments are kept; the next slot is planned again from where this one ends
(receding horizon). The plan is made when the slot is planned, never in the tick: the legs'
trajectories are polynomials as before (`trajectory.minus_path` splits them at the sway's
knots).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from crawler_motion.errors import GaitError
from crawler_motion.motion.trajectory import Piecewise, Segment, sextic_coefficients

#: Samples per knot interval of the least-squares problem (both ends included).
SAMPLES = 13
#: Slots planned ahead of the one being built (receding horizon), each as a steady slot: the
#: next one (the pair landing now) and the one after (the stance pair again, landed where a
#: steady walk lands it).
PREVIEW = 2
#: Unknowns per knot and dimension: position, velocity, acceleration.
_STATE = 3


@dataclass(frozen=True)
class ZmpWeights:
    """Weights of the least-squares terms: the ZMP's distance to the line [m], the sway [m]
    and its acceleration as a ZMP offset (``s'' / w²``, [m]). A refused slot is planned again
    with the sway terms multiplied by each of `FALLBACK_SCALES`."""

    line: float = 1.0
    sway: float = 0.1
    accel: float = 0.03


#: All-feet-down time added to the last slot of a walk [s]: the sway returns to zero (the
#: robot stands) with the ZMP anywhere inside the four feet, not during the last swing.
SETTLE_TIME = 0.3
#: Multipliers of the sway terms tried in turn when the joint limits or rates refuse a slot:
#: each gives a smaller sway that still starts from the last slot's state (C²).
FALLBACK_SCALES: tuple[float, ...] = (1.0, 4.0, 16.0, 64.0)
#: Knot-interval durations whose `_basis` is kept (a walk has a few; a new one drops the
#: oldest).
BASIS_CACHE = 256


@functools.lru_cache(maxsize=BASIS_CACHE)
def _basis(duration: float) -> np.ndarray:
    """``M`` ``(7, 7)``: sextic coefficients (normalised time) ``= M @ (s0, v0, a0, s1, v1,
    a1, s_mid)`` for a segment of ``duration`` [s] (`trajectory.sextic_coefficients`).
    Kept per duration (a walk's knot intervals repeat every slot); read-only."""
    eye = np.eye(7)
    m = sextic_coefficients(duration, *eye).T
    m.flags.writeable = False
    return m


_POWERS = np.arange(7)


def _rows(u: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """Position and acceleration of the 7 local unknowns at normalised times ``u``."""
    m = _basis(duration)
    upos = u[:, None] ** _POWERS
    uacc = np.zeros_like(upos)
    uacc[:, 2:] = _POWERS[2:] * (_POWERS[2:] - 1) * u[:, None] ** (_POWERS[2:] - 2)
    return upos @ m, uacc @ m / duration ** 2


@dataclass(frozen=True)
class SwayPlan:
    """A solved sway: one 2-D sextic per knot interval and the state ``(3, 2)`` (position
    [m], velocity [m/s], acceleration [m/s²]) at every knot."""

    knots: np.ndarray  # (K,) [s]
    coeffs: np.ndarray  # (K - 1, 2, 7)
    states: np.ndarray  # (K, 3, 2)

    def segments(self, upto: int, phase: str = "sway") -> list[Segment]:
        """The first ``upto`` intervals as 3-D segments (x, y, z = 0)."""
        return [Segment(np.vstack((self.coeffs[j], np.zeros((1, 7)))),
                        float(self.knots[j + 1] - self.knots[j]), phase)
                for j in range(upto)]


def solve_sway(knots: np.ndarray, start: np.ndarray, end: np.ndarray | None,
               samples: np.ndarray, normals: np.ndarray, targets: np.ndarray,
               active: np.ndarray, omega2: float, weights: ZmpWeights) -> SwayPlan:
    """The sway over ``knots`` ``(K,)`` [s] (from 0) starting in ``start`` ``(3, 2)`` and, if
    given, ending in ``end``, that minimises at ``samples`` ``(n,)`` [s] the ZMP terms
    ``normals @ (s - s'' / w²) - targets`` (``normals`` ``(n, 2)`` unit normals of the
    support line, ``targets`` ``(n,)`` [m]; only where ``active``) with the sway terms of
    ``weights``."""
    k = len(knots)
    nv = _STATE * k + (k - 1)  # unknowns per dimension
    interval = np.clip(np.searchsorted(knots, samples, side="right") - 1, 0, k - 2)
    rows_line, rows_sway = [], []
    rhs_line = []
    for j in range(k - 1):
        sel = interval == j
        if not sel.any():
            continue
        dur = float(knots[j + 1] - knots[j])
        pos, acc = _rows((samples[sel] - knots[j]) / dur, dur)
        local = [*range(_STATE * j, _STATE * j + 2 * _STATE), _STATE * k + j]
        full_pos = np.zeros((pos.shape[0], nv))
        full_acc = np.zeros_like(full_pos)
        full_pos[:, local], full_acc[:, local] = pos, acc
        zmp = full_pos - full_acc / omega2
        n = normals[sel]
        w = weights.line * active[sel]
        rows_line.append(np.hstack((w[:, None] * n[:, :1] * zmp, w[:, None] * n[:, 1:] * zmp)))
        rhs_line.append(w * targets[sel])
        for block in (weights.sway * full_pos, weights.accel * full_acc / omega2):
            zero = np.zeros_like(block)
            rows_sway += [np.hstack((block, zero)), np.hstack((zero, block))]
    a = np.vstack(rows_line + rows_sway)
    b = np.concatenate([*rhs_line, np.zeros(sum(r.shape[0] for r in rows_sway))])
    fixed = np.zeros(2 * nv, dtype=bool)
    values = np.zeros(2 * nv)
    for d in range(2):
        fixed[d * nv: d * nv + _STATE] = True
        values[d * nv: d * nv + _STATE] = start[:, d]
        if end is not None:
            last = d * nv + _STATE * (k - 1)
            fixed[last: last + _STATE] = True
            values[last: last + _STATE] = end[:, d]
    values[~fixed] = _least_squares(a[:, ~fixed], b - a[:, fixed] @ values[fixed])
    if not np.all(np.isfinite(values)):
        raise GaitError("the ZMP body plan has no finite solution for this slot")
    coeffs = np.zeros((k - 1, 2, 7))
    for j in range(k - 1):
        local = [*range(_STATE * j, _STATE * j + 2 * _STATE), _STATE * k + j]
        m = _basis(float(knots[j + 1] - knots[j]))
        for d in range(2):
            coeffs[j, d] = m @ values[d * nv + np.array(local)]
    states = np.stack([values[:nv][:_STATE * k].reshape(k, _STATE),
                       values[nv:][:_STATE * k].reshape(k, _STATE)], axis=-1)
    return SwayPlan(np.asarray(knots, dtype=float), coeffs, states)


def _least_squares(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``argmin |a x - b|`` by the normal equations of the column-scaled problem (a few
    hundred unknowns: ~1 ms, where `np.linalg.lstsq`'s SVD takes ~8 ms and a QR ~15 ms);
    `np.linalg.lstsq` if they are singular."""
    scale = 1.0 / np.maximum(np.linalg.norm(a, axis=0), 1e-300)
    scaled = a * scale
    try:
        return scale * np.linalg.solve(scaled.T @ scaled, scaled.T @ b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(a, b, rcond=None)[0]


def line_terms(first: np.ndarray, second: np.ndarray, accel: np.ndarray, omega2: float,
               shift: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals ``(n, 2)`` of the support lines through ``first`` and ``second`` ``(n,
    2)`` [m] (body plan frame) and the targets ``(n,)`` [m] of ``normals @ (s - s'' / w²)``:
    the ZMP ``s - (s'' + b'') / w² + shift`` on the line, with the plan frame's acceleration
    ``b''`` = ``-accel`` (``accel`` ``(n, 2)``: the stance feet's mean acceleration in it)."""
    d = second - first
    length = np.linalg.norm(d, axis=-1, keepdims=True)
    if np.any(length < 1e-6):
        raise GaitError("the two stance feet of a pair gait coincide: no support line")
    normals = np.stack((-d[:, 1], d[:, 0]), axis=-1) / length
    targets = np.einsum("ij,ij->i", normals, first - shift - accel / omega2)
    return normals, targets


def plan_slot_sway(contacts: Sequence[Piecewise], stance: Sequence[int], knots: np.ndarray,
                   swing_time: float, start: np.ndarray, final: bool, omega2: float,
                   shift: np.ndarray, weights: ZmpWeights,
                   ahead: Sequence[tuple[np.ndarray, np.ndarray]] = ()) -> SwayPlan:
    """The sway of one slot whose ``stance`` pair (leg indices) carries the body, from the
    contact points' plan-frame trajectories ``contacts`` (one per leg, slot time, no sway),
    the slot's ``knots`` ``(K,)`` [s] (0 to its end), ``swing_time`` [s] (after it every foot
    is down: no line) and the ``start`` state ``(3, 2)``. A ``final`` slot ends standing (no
    sway, at rest); another is planned over itself and the slots ``ahead``, each given by its
    stance pair's points ``(2, 2)`` [m] at its start and their velocity ``(2, 2)`` [m/s] in
    the plan frame (a steady walk ahead: each slot like this one in time)."""
    duration = float(knots[-1])
    per = np.linspace(0.0, 1.0, SAMPLES)
    times = np.concatenate([knots[j] + per * (knots[j + 1] - knots[j])
                            for j in range(len(knots) - 1)])
    pair = np.stack([contacts[i].evaluate(times)[0][:, :2] for i in stance])
    accel = np.mean([contacts[i].evaluate(times)[2][:, :2] for i in stance], axis=0)
    lines = [line_terms(pair[0], pair[1], accel, omega2, shift)]
    active = times <= swing_time + 1e-12
    if final:
        return solve_sway(knots, start, np.zeros((_STATE, 2)), times, *lines[0], active,
                          omega2, weights)
    for points, velocity in ahead:
        moving = points[:, None, :] + velocity[:, None, :] * times[:, None]
        lines.append(line_terms(moving[0], moving[1], np.zeros_like(accel), omega2, shift))
    count = len(lines)
    all_knots = np.concatenate([knots] + [knots[1:] + m * duration for m in range(1, count)])
    return solve_sway(all_knots, start, None,
                      np.concatenate([times + m * duration for m in range(count)]),
                      np.vstack([line[0] for line in lines]),
                      np.concatenate([line[1] for line in lines]),
                      np.tile(active, count), omega2, weights)


def zmp_of(centre: np.ndarray, accel: np.ndarray, omega2: float, shift: np.ndarray
           ) -> np.ndarray:
    """The zero-moment point ``(n, 2)`` [m] of the centre of mass ``centre`` ``(n, 2)`` [m]
    with acceleration ``accel`` ``(n, 2)`` [m/s²]."""
    return centre - accel / omega2 + shift


def line_distance(point: np.ndarray, first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Unsigned distance ``(n,)`` [m] of ``point`` from the line through ``first`` and
    ``second`` (each ``(n, 2)`` [m])."""
    d = second - first
    length = np.maximum(np.linalg.norm(d, axis=-1), 1e-12)
    return np.abs(d[:, 0] * (point[:, 1] - first[:, 1]) - d[:, 1] * (point[:, 0] - first[:, 0])
                  ) / length


def planned_distance(contacts: Sequence[Piecewise], stance: Sequence[int], swing_time: float,
                     omega2: float, shift: np.ndarray, samples: int = 61) -> np.ndarray:
    """Distance ``(samples,)`` [m] of the planned ZMP from the support line over a slot's
    swing, from the contact points' trajectories ``contacts`` in base_link (sway included):
    the stance feet stand still on the ground, so the body's acceleration is minus theirs
    (the body's rotation in a turn is neglected)."""
    times = np.linspace(0.0, swing_time, samples)
    evaluated = [contacts[i].evaluate(times) for i in stance]
    accel = np.mean([e[2][:, :2] for e in evaluated], axis=0)
    point = zmp_of(np.zeros_like(accel), -accel, omega2, shift)
    return line_distance(point, evaluated[0][0][:, :2], evaluated[1][0][:, :2])
