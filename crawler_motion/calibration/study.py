"""One leg's calibration run as the study reports it: poses selected from the optimised
excitation, identification by every method, the comparison table."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crawler_motion.calibration import excitation, selection
from crawler_motion.calibration.identify import (
    RLS_MAX_PASSES,
    Fit,
    Method,
    Problem,
    de,
    rls_de,
)
from crawler_motion.calibration.jacobian import (
    Identifiability,
    condition_number,
    identifiable_set,
    require_rank,
    stacked_jacobian,
)
from crawler_motion.errors import CalibrationError, JointLimitError
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.kinematics import check_limits

#: DE settings of identification: population, generations of RLS-DE's refinement.
POPULATION = 20
GENERATIONS = 50


def leg_index(robot: RobotConfig, leg: str) -> int:
    """Row of ``leg``; `CalibrationError` naming the legs when it does not exist."""
    if leg not in robot.legs:
        raise CalibrationError(f"leg '{leg}' does not exist; the legs are {list(robot.legs)}",
                               key=leg)
    return robot.legs.index(leg)


def check_poses(robot: RobotConfig, poses: np.ndarray, what: str) -> None:
    """Refuse poses outside the joint limits, naming the first."""
    lower, upper = robot.lower, robot.upper
    bad = np.flatnonzero(np.any((poses < lower) | (poses > upper), axis=1))
    if bad.size:
        try:
            check_limits(robot, poses[bad[0]][None, :].repeat(robot.n_legs, 0))
        except JointLimitError as exc:
            reason = str(exc).split(": ", 1)[1].split(" (")[0]
        raise CalibrationError(f"{what}: pose {bad[0] + 1} is outside the joint limits: "
                               f"{reason}")


@dataclass(frozen=True)
class PoseSelection:
    """Selected poses (rad), their condition number and the random baseline's median."""

    poses: np.ndarray
    condition: float
    random_median: float
    excitation_cost: float


def select_poses(robot: RobotConfig, leg: int, n_candidates: int, count: int, seed: int,
                 harmonics: int = excitation.HARMONICS, generations: int = 40
                 ) -> PoseSelection:
    """Optimise the excitation, sample ``n_candidates`` poses, select ``count`` of them."""
    rng = np.random.default_rng(seed)
    params = excitation.robot_params(robot, leg)
    spread = rng.uniform(robot.lower, robot.upper, (200, 3))
    columns = list(identifiable_set(stacked_jacobian(robot, leg, params, spread)).columns)
    exc, cost = excitation.optimise(robot, leg, columns, rng, harmonics,
                                    generations=generations)
    cand = excitation.candidates(exc, n_candidates)
    jac = stacked_jacobian(robot, leg, params, cand)[:, columns]
    picks = selection.select(jac, count)
    rows = stacked_jacobian(robot, leg, params, cand[picks])[:, columns]
    baseline = selection.random_conditions(jac, count, 101, rng)
    return PoseSelection(cand[picks], condition_number(rows), float(np.median(baseline)),
                         cost)


@dataclass(frozen=True)
class Comparison:
    """Identifiability and the fit of every method (``before``: the starting geometry)."""

    identifiability: Identifiability
    fits: dict[str, Fit]


def compare(robot: RobotConfig, leg: int, poses: np.ndarray, measured: np.ndarray, seed: int,
            rls_passes: int = RLS_MAX_PASSES) -> Comparison:
    """Identify leg ``leg`` by RLS (at most ``rls_passes`` re-linearisations), DE alone (the
    RLS-DE evaluation budget) and RLS-DE."""
    if len(poses) != len(measured):
        raise CalibrationError(f"{len(poses)} poses but {len(measured)} measured feet: one "
                               f"measurement per pose")
    start = excitation.robot_params(robot, leg).copy()
    jac = stacked_jacobian(robot, leg, start, poses)
    ident = identifiable_set(stacked_jacobian(
        robot, leg, start, np.random.default_rng(0).uniform(robot.lower, robot.upper, (200, 3))))
    require_rank(jac[:, list(ident.columns)], len(poses), len(ident.columns))
    problem = Problem(robot, leg, poses, measured, start, ident.columns)
    first, hybrid = rls_de(problem, POPULATION, GENERATIONS, np.random.default_rng(seed),
                           rls_passes)
    budget = max(hybrid.evaluations // POPULATION - 1, 1)
    alone = de(problem, POPULATION, budget, np.random.default_rng(seed))
    before = problem.fit(start, 0, 1)
    return Comparison(ident, {"before": before, Method.RLS.value: first,
                              Method.DE.value: alone, Method.RLS_DE.value: hybrid})


def format_table(comp: Comparison, validation: dict[str, tuple[float, float]] | None = None
                 ) -> str:
    """The comparison as a Markdown table in mm (validation columns when given)."""
    head = "| method | mean [mm] | max [mm] | iterations | evaluations |"
    if validation:
        head += " validation mean [mm] | validation max [mm] |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for name, fit in comp.fits.items():
        row = (f"| {name} | {fit.mean * 1e3:.5f} | {fit.max * 1e3:.5f} | {fit.iterations} | "
               f"{fit.evaluations} |")
        if validation:
            mean, worst = validation[name]
            row += f" {mean * 1e3:.5f} | {worst * 1e3:.5f} |"
        lines.append(row)
    return "\n".join(lines)
