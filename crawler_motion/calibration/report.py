"""The study's comparison for a simulated leg: selected poses, identification by every method
from (noisy) tracker readings of a "true" leg, errors on separate validation poses (pure)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crawler_motion.calibration import study, synthetic
from crawler_motion.calibration.identify import RLS_MAX_PASSES
from crawler_motion.calibration.jacobian import leg_feet
from crawler_motion.model.config import RobotConfig

#: Number of validation poses (uniform within the joint limits, separate from the selection).
VALIDATION_POSES = 100
#: The source study's figures, mean position error [mm] and iterations to converge, for the
#: same columns (its "RLS-DEH" is rls-de here; iterations of "before" do not apply).
STUDY = {"before": ("≈ 1", "-"), "rls": ("≤ 0.6", "300"), "de": ("≤ 0.3", "180"),
         "rls-de": ("≤ 0.05", "50")}


@dataclass(frozen=True)
class LegReport:
    """One leg at one tracker noise: the comparison and validation errors [m] by method."""

    leg: str
    noise: float  # [m] per axis
    selection: study.PoseSelection
    comparison: study.Comparison
    validation: dict[str, tuple[float, float]]  # method -> (mean, max) [m]


def leg_report(robot: RobotConfig, leg: int, true_params: np.ndarray, noise: float, seed: int,
               selection: study.PoseSelection | None = None,
               rls_passes: int = RLS_MAX_PASSES) -> LegReport:
    """Identify leg ``leg`` of ``robot`` (its current geometry is the start) from readings of
    ``true_params`` at the selected poses with tracker ``noise`` [m] per axis (RLS with at
    most ``rls_passes`` passes); validate on `VALIDATION_POSES` other poses (noise-free
    truth, never used by the identification)."""
    sel = selection or study.select_poses(robot, leg, 200, 50, seed)
    rng = np.random.default_rng(seed)
    measured = synthetic.measure(leg_feet(robot, leg, true_params, sel.poses), noise, rng)
    comp = study.compare(robot, leg, sel.poses, measured, seed, rls_passes)
    poses = rng.uniform(robot.lower, robot.upper, (VALIDATION_POSES, 3))
    truth = leg_feet(robot, leg, true_params, poses)
    validation = {}
    for name, fit in comp.fits.items():
        err = np.linalg.norm(leg_feet(robot, leg, fit.params, poses) - truth, axis=-1)
        validation[name] = (float(err.mean()), float(err.max()))
    return LegReport(robot.legs[leg], noise, sel, comp, validation)


def format_report(report: LegReport) -> str:
    """A Markdown table of ``report`` in mm with the study's figures beside it."""
    head = ("| method | ident. mean [mm] | ident. max [mm] | validation mean [mm] | "
            "validation max [mm] | iterations | evaluations | study: mean [mm] | "
            "study: iterations |")
    lines = [f"leg {report.leg}, tracker noise {report.noise * 1e3:g} mm per axis; condition "
             f"number {report.selection.condition:.2f} (selected 50 of 200) vs "
             f"{report.selection.random_median:.2f} (median of 101 random selections)", "",
             head, "|" + "---|" * (head.count("|") - 1)]
    for name, fit in report.comparison.fits.items():
        mean, worst = report.validation[name]
        lines.append(f"| {name} | {fit.mean * 1e3:.5f} | {fit.max * 1e3:.5f} | "
                     f"{mean * 1e3:.5f} | {worst * 1e3:.5f} | {fit.iterations} | "
                     f"{fit.evaluations} | {STUDY[name][0]} | {STUDY[name][1]} |")
    return "\n".join(lines)
