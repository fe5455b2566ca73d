"""Identification of one leg's geometry from measured foot positions: RLS on the linearised
model, differential evolution (DE) on the full model, and RLS seeding DE (RLS-DE).

Criterion: the RMS foot error over the poses through the full chain (the least-squares cost,
the maximum-likelihood one for Gaussian tracker noise). RLS minimises it on the linearised
model; DE's fitness is it, not the study's mean Euclidean error: minimising the mean
Euclidean error on 50 noisy poses moved RLS-DE away from the least-squares estimate and made
it worse than RLS on validation poses (docs/calibration.md). The tables report the mean and
largest Euclidean error, as the study does.

Settings (the study does not print them; chosen here, see docs/calibration.md): RLS with
forgetting factor `FORGET` = 1 (the parameters are constant) and P0 = `P0` I on the
column-normalised Jacobian (a weak prior: the first poses decide), re-linearised while the RMS
foot error falls by more than `RLS_IMPROVEMENT` (relative; at most `RLS_MAX_PASSES` passes);
DE on the identified parameters in the box `de_box` around the nominal leg, or, for RLS-DE,
in a box of `RLS_DE_SIGMAS` standard errors (at least `RLS_DE_FLOOR` of the DE box) around the
RLS estimate, which is a member of the first population. RLS-DE keeps DE's result only if it
lowers the RMS error on the identification poses by more than `RLS_IMPROVEMENT` (what RLS
itself resolves); otherwise it keeps the RLS estimate. Validation poses never take part.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from crawler_motion.calibration.evolution import evolve
from crawler_motion.calibration.jacobian import column_scale, leg_feet, stacked_jacobian
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.leg_geometry import PARAMS, Unit

FORGET = 1.0
P0 = 1e4
RLS_IMPROVEMENT = 1e-6
RLS_MAX_PASSES = 20
RLS_DE_SIGMAS = 5.0
RLS_DE_FLOOR = 1e-3
#: Half-widths of the DE box around the nominal leg: about twice the largest assembly errors.
BOX = {Unit.LINK: 2e-3, Unit.DISPLACEMENT: 1e-3, Unit.ANGLE: math.radians(0.5)}
JOINT_OFFSET_BOX = math.radians(1.5)


class Method(enum.Enum):
    """Identification method of ``crawler-motion calibrate identify``."""

    RLS = "rls"
    DE = "de"
    RLS_DE = "rls-de"


@dataclass(frozen=True)
class Fit:
    """An identified parameter vector, its foot errors on the poses [m], iterations (RLS
    passes or DE generations to within 1 % of the final cost) and model evaluations."""

    params: np.ndarray
    mean: float
    max: float
    iterations: int
    evaluations: int


@dataclass(frozen=True)
class Problem:
    """One leg's identification data: poses ``q`` (M, 3) [rad], measured feet (M, 3) [m],
    the starting (nominal) parameters and the identified columns."""

    robot: RobotConfig
    leg: int
    q: np.ndarray
    measured: np.ndarray
    start: np.ndarray
    columns: tuple[int, ...]

    def errors(self, params: np.ndarray) -> np.ndarray:
        """Foot errors [m]: ``(M,)`` for one ``params``, ``(P, M)`` for rows of them."""
        p = np.asarray(params)[..., None, :]
        return np.linalg.norm(leg_feet(self.robot, self.leg, p, self.q) - self.measured, axis=-1)

    def rms(self, params: np.ndarray) -> np.ndarray:
        """RMS foot error [m] (the identification criterion): a scalar for one ``params``,
        ``(P,)`` for rows of them."""
        return np.sqrt(np.mean(self.errors(params) ** 2, axis=-1))

    def fit(self, params: np.ndarray, iterations: int, evaluations: int) -> Fit:
        """`Fit` of ``params`` with its errors on this problem's poses."""
        err = self.errors(params)
        return Fit(params, float(err.mean()), float(err.max()), iterations, evaluations)


def rls(problem: Problem, max_passes: int = RLS_MAX_PASSES) -> tuple[Fit, np.ndarray]:
    """RLS passes over the poses (3 rows each), re-linearised after each pass (at most
    ``max_passes``); returns the fit and the standard errors of the identified parameters
    (model units)."""
    params = problem.start.copy()
    cols = list(problem.columns)
    best = float(problem.rms(params))
    passes, sigma = 0, np.zeros(len(cols))
    for passes in range(1, max_passes + 1):
        jac = stacked_jacobian(problem.robot, problem.leg, params, problem.q)[:, cols]
        scale = column_scale(jac)
        phi_all = (jac / scale).reshape(len(problem.q), 3, len(cols))
        resid = (problem.measured - leg_feet(problem.robot, problem.leg, params, problem.q))
        x, cov = np.zeros(len(cols)), P0 * np.eye(len(cols))
        for phi, y in zip(phi_all, resid, strict=True):
            gain = cov @ phi.T @ np.linalg.inv(FORGET * np.eye(3) + phi @ cov @ phi.T)
            x = x + gain @ (y - phi @ x)
            cov = (np.eye(len(cols)) - gain @ phi) @ cov / FORGET
        trial = params.copy()
        trial[cols] += x / scale
        err = float(problem.rms(trial))
        if err >= best:
            passes -= 1
            break
        dof = max(3 * len(problem.q) - len(cols), 1)
        s2 = float(np.sum((resid.reshape(-1) - (jac / scale) @ x) ** 2)) / dof
        sigma = np.sqrt(np.maximum(np.diag(cov), 0.0) * s2) / scale
        params, improvement, best = trial, (best - err) / best, err
        if improvement < RLS_IMPROVEMENT:
            break
    return problem.fit(params, passes, (passes + 1) * len(problem.q)), sigma


def de_box(problem: Problem) -> np.ndarray:
    """Half-widths of the DE-alone box of the identified parameters (model units)."""
    return np.array([JOINT_OFFSET_BOX if PARAMS[k].joint is not None else BOX[PARAMS[k].unit]
                     for k in problem.columns])


def de(problem: Problem, population: int, generations: int, rng: np.random.Generator,
       centre: np.ndarray | None = None, half_width: np.ndarray | None = None) -> Fit:
    """DE on the identified parameters in ``centre ± half_width`` (default: the start and
    `de_box`), ``centre`` seeding the first population when given."""
    cols = list(problem.columns)
    base = problem.start if centre is None else centre
    width = de_box(problem) if half_width is None else half_width

    def cost(points: np.ndarray) -> np.ndarray:
        full = np.broadcast_to(base, (len(points), len(base))).copy()
        full[:, cols] = points
        return problem.rms(full)

    mid = base[cols]
    result = evolve(cost, mid - width, mid + width, population, generations, rng,
                    seed_point=mid if centre is not None else None)
    params = base.copy()
    params[cols] = result.best
    final = result.history[-1]
    converged = int(np.argmax(result.history <= final * 1.01 + 1e-15))
    return problem.fit(params, converged, result.evaluations)


def rls_de(problem: Problem, population: int, generations: int, rng: np.random.Generator,
           max_passes: int = RLS_MAX_PASSES) -> tuple[Fit, Fit]:
    """RLS, then DE in a small box around its estimate; returns (RLS fit, RLS-DE fit). DE's
    result replaces the RLS estimate only if it lowers the identification RMS error by more
    than `RLS_IMPROVEMENT` (relative)."""
    first, sigma = rls(problem, max_passes)
    width = np.maximum(RLS_DE_SIGMAS * sigma, RLS_DE_FLOOR * de_box(problem))
    second = de(problem, population, generations, rng, first.params, width)
    better = problem.rms(second.params) < (1.0 - RLS_IMPROVEMENT) * problem.rms(first.params)
    chosen = second if better else first
    return first, Fit(chosen.params, chosen.mean, chosen.max,
                      first.iterations + second.iterations,
                      first.evaluations + second.evaluations)
