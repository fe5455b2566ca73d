"""The text ``crawler-motion calibrate identify --measurements`` prints about a session: the
condition number, fixed parameters and why, outliers by row, the tracker's pose, per-leg foot
errors before and after (pure)."""

from __future__ import annotations

import math

import numpy as np

from crawler_motion.calibration import session
from crawler_motion.calibration.readings import Readings
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.rotations import roll_pitch, yaw_of


def outlier_line(readings: Readings, fit: session.SessionFit, label: str) -> str:
    rows = np.flatnonzero(fit.outliers)
    rule = (f"residual > {session.REJECT:g} sigma = {session.REJECT * fit.sigma * 1e3:.4g} mm; "
            f"robust sigma {fit.sigma * 1e3:.4g} mm per axis")
    if not rows.size:
        return f"outliers: none ({rule})"
    listed = ", ".join(f"{label} {int(readings.lines[i])} ({fit.residuals[i] * 1e3:.3g} mm)"
                       for i in rows)
    return f"outliers, excluded ({rule}): {listed}"


def _tracker(state: session.State) -> str:
    roll, pitch = roll_pitch(state.rotation)
    rpy = (roll, pitch, yaw_of(state.rotation))
    return ("tracker pose in base_link (p_base = R p_tracker + t): t = "
            f"[{', '.join(f'{v:.6f}' for v in state.translation)}] m, rpy = "
            f"[{', '.join(f'{v:.7f}' for v in rpy)}] rad "
            f"([{', '.join(f'{math.degrees(v):.5f}' for v in rpy)}] deg)")


def describe(robot: RobotConfig, readings: Readings, fit: session.SessionFit,
             before: session.State, offset: np.ndarray, label: str = "line") -> str:
    """The report of ``fit`` (``before``: the starting legs, with the tracker pose fitted to
    them); foot errors over the inlier readings, in mm."""
    lay = fit.layout
    fixed = "; ".join(f"{name} ({why})" for name, why in lay.fixed.items())
    lines = [f"condition number {fit.condition:.2f} (scaled columns; {lay.size} unknowns: "
             f"{len(lay.columns)} legs x 15 parameters"
             + (" + the tracker pose 6 - the body frame's gauge 6" if lay.tracker else "")
             + f"; {len(readings.q)} readings)",
             f"fixed at their current value: {fixed or 'none'}",
             outlier_line(readings, fit, label)]
    if lay.tracker:
        lines.append(_tracker(fit.state))
    if offset.any():
        lines.append(f"target offset from the foot tip (tibia frame): {list(offset)} m")
    inliers = readings.subset(~fit.outliers)
    errors = {name: session.residual_norms(robot, inliers, state, offset, lay)
              for name, state in (("before", before), ("after", fit.state))}
    lines += ["", "| leg | readings | before mean [mm] | before max [mm] | after mean [mm] | "
              "after max [mm] |", "|---|---|---|---|---|---|"]
    for leg in lay.columns:
        rows = inliers.legs == leg
        cells = [f"{errors[n][rows].mean() * 1e3:.5f} | {errors[n][rows].max() * 1e3:.5f}"
                 for n in ("before", "after")]
        lines.append(f"| {robot.legs[leg]} | {int(rows.sum())} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines)
