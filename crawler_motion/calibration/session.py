"""One calibration session: every measured leg and, when the readings are in the tracker's own
frame, the tracker-to-body transform, identified together by robust least squares (pure numpy).

Model of a reading: the target (the foot tip plus ``offset`` [m] in the tibia frame, i.e. the
chain with ``l3, foot_y, foot_z`` shifted by it; ``foot_z`` stays fixed, so that frame's x
runs from the knee axis to the foot tip, y along the knee axis) in base_link, ``p``; read as
``p`` in the body frame or as ``R^T (p - t)`` in the tracker's, ``(R, t)`` being the tracker's
pose in base_link (6 unknowns shared by every leg of the session, updated as ``R exp([w])``,
``t + v``).

Identifiability (`layout`): each leg identifies its 15 parameters (`jacobian.identifiable_set`).
With the tracker's pose free, a rigid motion of the tracker together with the same motion of
every leg's root gives the same readings (6 directions): base_link is then defined as the frame
in which the measured legs' root errors (their ``DATUM`` parameters) have no common rigid
motion, six linear constraints ``C b = 0`` (`gauge_constraints`; least squares, angles
weighted by the leg's reach). The legs' root parameters are identified in the null space of
``C``. Poses that leave any unknown unidentifiable (scaled Jacobian's rank below the count)
are refused, naming the parameter the null direction moves most.

Bad readings (`robust_fit`): IRLS with a Huber weight on each row's residual norm (threshold
`HUBER` robust sigmas; sigma from the median residual norm, the median of a 3-D Gaussian's
norm being `MAXWELL_MEDIAN` sigma, at least ``floor``), then a row whose residual exceeds
`REJECT` sigmas is an outlier, excluded, and the rest refitted by plain least squares, sigma
now the inliers' RMS residual per degree of freedom (at least ``floor``); repeated until the
outlier set no longer changes. A good row's chance of exceeding 6 sigma: P(chi2_3 > 36) =
7e-8.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crawler_motion.calibration.jacobian import (
    RANK_TOL,
    column_scale,
    identifiable_set,
    stacked_jacobian,
)
from crawler_motion.calibration.jacobian import leg_feet as chain_feet
from crawler_motion.calibration.readings import Readings
from crawler_motion.calibration.rigid import fit_rigid
from crawler_motion.errors import CalibrationError
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.leg_geometry import INDEX, NAMES
from crawler_motion.model.rotations import rotation_vector_matrix

TRACKER = ("tracker_rx", "tracker_ry", "tracker_rz", "tracker_x", "tracker_y", "tracker_z")
DATUM = ("hip_x", "hip_y", "hip_z", "root_tilt_x", "root_tilt_y", "root_offset")
TIP = (INDEX["l3"], INDEX["foot_y"], INDEX["foot_z"])
HUBER = 3.0
REJECT = 6.0
MAXWELL_MEDIAN = 1.5382
IRLS_ROUNDS = 8
GN_MAX = 40
GN_TOL = 1e-12
#: Default smallest noise sigma [m] the outlier rule assumes (below: the tracker's resolution).
FLOOR = 1e-6


@dataclass(frozen=True)
class Layout:
    """The session's unknowns: per measured leg its identified parameter indices, whether the
    tracker pose is free, each fixed parameter ("leg.name") with its reason, and ``basis``
    ``(natural, size)``: the natural step (tracker, then every leg's columns) is
    ``basis @ unknowns`` (the gauge's null space; the identity without a tracker)."""

    columns: dict[int, tuple[int, ...]]
    tracker: bool
    fixed: dict[str, str]
    basis: np.ndarray

    @property
    def size(self) -> int:
        """Number of unknowns."""
        return int(self.basis.shape[1])

    def names(self, robot: RobotConfig) -> list[str]:
        """Natural unknowns' names in step order ("tracker_*", then "leg.param")."""
        legs = [f"{robot.legs[leg]}.{NAMES[k]}" for leg, cols in self.columns.items()
                for k in cols]
        return [*TRACKER, *legs] if self.tracker else legs


@dataclass(frozen=True)
class State:
    """Leg parameters ``(n_legs, N_PARAMS)`` (of the target when an offset is set) and the
    tracker's pose in base_link: rotation ``(3, 3)``, translation ``(3,)`` [m]."""

    params: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray


def gauge_constraints(robot: RobotConfig, legs: tuple[int, ...]) -> np.ndarray:
    """``C`` ``(6, 6 len(legs))``: row-wise, the legs' `DATUM` parameters ``b`` (stacked) with
    ``C b = 0`` have no common rigid motion. A body twist (w, v) changes a leg's ``b`` by
    ``A (w, v)`` (leg frame: hip by ``v + w x hip``, axis angles by ``w``); ``C`` stacks
    ``A^T W``, ``W`` weighting angles by the squared reach l1 + l2 + l3."""
    reach = robot.l1 + robot.l2 + robot.l3
    weight = np.diag([1.0, 1.0, 1.0, reach ** 2, reach ** 2, reach ** 2])
    blocks = []
    for leg in legs:
        yaw = float(robot.neutral_yaw[leg])
        rot_t = rotation_vector_matrix(np.array([0.0, 0.0, -yaw]))
        h = np.asarray(robot.hips[leg], dtype=float)
        hx = np.array([[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]])
        a = np.block([[-rot_t @ hx, rot_t], [rot_t, np.zeros((3, 3))]])
        blocks.append(a.T @ weight)
    return np.hstack(blocks)


def _basis(robot: RobotConfig, columns: dict[int, tuple[int, ...]]) -> np.ndarray:
    """The gauge's null-space basis over the natural step (tracker 6, then leg columns)."""
    natural = 6 + sum(len(c) for c in columns.values())
    select = np.zeros((6 * len(columns), natural))
    col, row = 6, 0
    for cols in columns.values():
        for name in DATUM:
            select[row, col + cols.index(INDEX[name])] = 1.0
            row += 1
        col += len(cols)
    constraint = gauge_constraints(robot, tuple(columns)) @ select
    _, _, vt = np.linalg.svd(constraint)
    return vt[6:].T


def layout(robot: RobotConfig, readings: Readings, start: np.ndarray, tracker: bool) -> Layout:
    """The unknowns for ``readings`` from the ``start`` geometry (structural rank per leg at
    200 poses spread over the joint limits)."""
    spread = np.random.default_rng(0).uniform(robot.lower, robot.upper, (200, 3))
    columns, fixed = {}, {}
    for leg in readings.measured_legs():
        ident = identifiable_set(stacked_jacobian(robot, leg, start[leg], spread))
        columns[leg] = ident.columns
        fixed.update({f"{robot.legs[leg]}.{k}": v for k, v in ident.fixed.items()})
    if not tracker:
        return Layout(columns, False, fixed, np.eye(sum(len(c) for c in columns.values())))
    fixed["6 combinations of " + ", ".join(DATUM)] = (
        "with the tracker's pose free, a common rigid motion of every root is the same motion "
        "as the tracker's; base_link is the frame in which the roots' errors have none")
    return Layout(columns, True, fixed, _basis(robot, columns))


def predict(robot: RobotConfig, readings: Readings, state: State, offset: np.ndarray,
            lay: Layout) -> tuple[np.ndarray, np.ndarray]:
    """Predicted readings ``(M, 3)`` [m] and their Jacobian ``(3 M, lay.size)`` w.r.t. the
    unknowns (rows x, y, z of reading 0, then 1, ...; natural Jacobian times ``lay.basis``)."""
    m = len(readings.q)
    body = np.empty((m, 3))
    jac = np.zeros((m, 3, lay.basis.shape[0]))
    col = 6 * lay.tracker
    for leg, cols in lay.columns.items():
        rows = readings.legs == leg
        params = state.params[leg].copy()
        params[list(TIP)] += offset
        body[rows] = chain_feet(robot, leg, params, readings.q[rows])
        j = stacked_jacobian(robot, leg, params, readings.q[rows])[:, list(cols)]
        jac[rows, :, col:col + len(cols)] = j.reshape(-1, 3, len(cols))
        col += len(cols)
    if not lay.tracker:
        return body, jac.reshape(3 * m, -1) @ lay.basis
    rot_t = state.rotation.T
    local = (body - state.translation) @ rot_t.T
    jac[:, :, 6:] = np.einsum("ij,mjk->mik", rot_t, jac[:, :, 6:])
    skew = np.zeros((m, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -local[:, 2], local[:, 1], -local[:, 0]
    jac[:, :, :3] = skew - np.swapaxes(skew, 1, 2)
    jac[:, :, 3:6] = -rot_t
    return local, jac.reshape(3 * m, -1) @ lay.basis


def _apply(state: State, lay: Layout, unknowns: np.ndarray) -> State:
    step = lay.basis @ unknowns
    params = state.params.copy()
    col = 6 * lay.tracker
    for leg, cols in lay.columns.items():
        params[leg, list(cols)] += step[col:col + len(cols)]
        col += len(cols)
    if not lay.tracker:
        return State(params, state.rotation, state.translation)
    return State(params, state.rotation @ rotation_vector_matrix(step[:3]),
                 state.translation + step[3:6])


def gauss_newton(robot: RobotConfig, readings: Readings, state: State, offset: np.ndarray,
                 lay: Layout, weights: np.ndarray) -> State:
    """Weighted least squares (``weights`` ``(M,)`` per reading) by Gauss-Newton on the
    scaled Jacobian, halving a step that does not lower the cost; stops when the cost falls by
    less than `GN_TOL` (relative) or after `GN_MAX` steps."""
    w = np.repeat(np.sqrt(weights), 3)

    def cost(s: State) -> tuple[float, np.ndarray, np.ndarray]:
        pred, jac = predict(robot, readings, s, offset, lay)
        resid = (readings.points - pred).reshape(-1) * w
        return float(resid @ resid), resid, jac * w[:, None]

    value, resid, jac = cost(state)
    for _ in range(GN_MAX):
        scale = column_scale(jac)
        step = np.linalg.lstsq(jac / scale, resid, rcond=None)[0] / scale
        for _ in range(30):
            trial = _apply(state, lay, step)
            new, new_resid, new_jac = cost(trial)
            if new <= value:
                break
            step = step / 2
        else:
            return state
        done = value - new <= GN_TOL * max(value, 1e-300)
        state, value, resid, jac = trial, new, new_resid, new_jac
        if done:
            break
    return state


def residual_norms(robot: RobotConfig, readings: Readings, state: State, offset: np.ndarray,
                   lay: Layout) -> np.ndarray:
    """Distance [m] of each reading from its prediction ``(M,)``."""
    return np.linalg.norm(readings.points - predict(robot, readings, state, offset, lay)[0],
                          axis=-1)


def start_state(robot: RobotConfig, readings: Readings, start: np.ndarray, offset: np.ndarray,
                tracker: bool) -> State:
    """``start`` legs; the tracker pose (when free) fitted to the predicted targets by a
    Huber-weighted rigid fit (Kabsch, 5 rounds)."""
    if not tracker:
        return State(start.copy(), np.eye(3), np.zeros(3))
    body = np.empty_like(readings.points)
    for leg in readings.measured_legs():
        rows = readings.legs == leg
        params = start[leg].copy()
        params[list(TIP)] += offset
        body[rows] = chain_feet(robot, leg, params, readings.q[rows])
    weights = np.ones(len(body))
    for _ in range(5):
        rotation, translation = fit_rigid(readings.points, body, weights)
        norms = np.linalg.norm(readings.points @ rotation.T + translation - body, axis=-1)
        sigma = max(float(np.median(norms)) / MAXWELL_MEDIAN, FLOOR)
        weights = np.minimum(1.0, HUBER * sigma / np.maximum(norms, 1e-300))
    return State(start.copy(), rotation, translation)


def check_identifiable(robot: RobotConfig, jac: np.ndarray, lay: Layout) -> float:
    """Condition number of the scaled ``jac``; `CalibrationError` naming the unknown the
    poses leave unidentifiable (rank below `Layout.size`)."""
    if jac.shape[0] < jac.shape[1]:
        raise CalibrationError(f"{jac.shape[0] // 3} readings give {jac.shape[0]} equations "
                               f"for {jac.shape[1]} unknowns ({jac.shape[1] // 3 + 1} poses "
                               f"at least, spread over the joint ranges)")
    _, s, vt = np.linalg.svd(jac / column_scale(jac), full_matrices=False)
    if s[-1] <= RANK_TOL * s[0]:
        rank = int(np.sum(s > RANK_TOL * s[0]))
        null = lay.basis @ (vt[-1] / column_scale(jac)) if lay.tracker else vt[-1]
        name = lay.names(robot)[int(np.argmax(np.abs(null)))]
        raise CalibrationError(f"the poses leave {name} unidentifiable (rank {rank} of "
                               f"{lay.size} unknowns): measure poses spread over every joint's "
                               f"range")
    return float(s[0] / s[-1])


def sigma_of(norms: np.ndarray, floor: float) -> float:
    """Robust noise sigma per axis [m] of residual norms (median / `MAXWELL_MEDIAN`)."""
    return max(float(np.median(norms)) / MAXWELL_MEDIAN, floor) if norms.size else floor


@dataclass(frozen=True)
class SessionFit:
    """The identified session: state, layout, outlier mask ``(M,)``, robust noise sigma [m],
    condition number, and the residual norms ``(M,)`` [m]."""

    state: State
    layout: Layout
    outliers: np.ndarray
    sigma: float
    condition: float
    residuals: np.ndarray


def robust_fit(robot: RobotConfig, readings: Readings, start: np.ndarray, offset: np.ndarray,
               tracker: bool, floor: float = FLOOR) -> SessionFit:
    """Identify the session from ``start`` (see the module docstring for the rule)."""
    lay = layout(robot, readings, start, tracker)
    for leg, cols in lay.columns.items():
        count, need = int(np.sum(readings.legs == leg)), -(-len(cols) // 3)
        if count < need:
            raise CalibrationError(f"leg {robot.legs[leg]}: {count} poses, fewer than its "
                                   f"{len(cols)} identifiable parameters need ({need} poses of "
                                   f"3 coordinates each)")
    state = start_state(robot, readings, start, offset, tracker)
    condition = check_identifiable(robot, predict(robot, readings, state, offset, lay)[1], lay)
    weights = np.ones(len(readings.q))
    for _ in range(IRLS_ROUNDS):
        state = gauss_newton(robot, readings, state, offset, lay, weights)
        norms = residual_norms(robot, readings, state, offset, lay)
        sigma = sigma_of(norms, floor)
        weights = np.minimum(1.0, HUBER * sigma / np.maximum(norms, 1e-300))
    outliers = norms > REJECT * sigma
    for _ in range(5):
        inliers = readings.subset(~outliers)
        state = gauss_newton(robot, inliers, state, offset, lay, np.ones(len(inliers.q)))
        norms = residual_norms(robot, readings, state, offset, lay)
        dof = max(3 * int(np.sum(~outliers)) - lay.size, 1)
        sigma = max(math.sqrt(float(np.sum(norms[~outliers] ** 2)) / dof), floor)
        again = norms > REJECT * sigma
        if np.array_equal(again, outliers):
            break
        outliers = again
    inliers = readings.subset(~outliers)
    condition = check_identifiable(robot, predict(robot, inliers, state, offset, lay)[1], lay)
    return SessionFit(state, lay, outliers, sigma, condition, norms)


def rms_per_axis(norms: np.ndarray) -> float:
    """RMS residual per axis [m] of residual norms."""
    return math.sqrt(float(np.mean(norms ** 2)) / 3.0) if norms.size else 0.0


#: A session with more outliers than this fraction, or a robust sigma above the caller's
#: bound, does not fit one model (wrong frame, a moved tracker, mislabelled legs): refused.
MAX_OUTLIER_FRACTION = 0.2


def check_fit(fit: SessionFit, readings: Readings, max_sigma: float, where: str,
              label: str = "line") -> None:
    """`CalibrationError` naming the worst reading (``label`` and its number) when ``fit`` does
    not describe the session: too many outliers or a robust sigma above ``max_sigma`` [m]."""
    worst = int(np.argmax(fit.residuals))
    line = f"{label} {int(readings.lines[worst])}"
    count = int(np.sum(fit.outliers))
    if count > MAX_OUTLIER_FRACTION * len(fit.outliers) or fit.sigma > max_sigma:
        raise CalibrationError(
            f"{where} {line}: the readings do not fit one model (residual "
            f"{fit.residuals[worst] * 1e3:.3g} mm; {count} of {len(fit.outliers)} rows beyond "
            f"{REJECT:g} sigma; sigma {fit.sigma * 1e3:.3g} mm per axis, bound "
            f"{max_sigma * 1e3:.3g} mm): wrong --frame, a tracker moved during the session or "
            f"mislabelled legs")
