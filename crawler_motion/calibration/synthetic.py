"""Synthetic "true" legs and tracker measurements, for the simulated calibration loop."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from crawler_motion.model.calibration_file import LegCalibration
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.leg_geometry import PARAMS, Unit

#: Injected errors (the issue's synthetic case): link lengths ±0.5–1 mm, joint offsets
#: ±0.3–0.8 deg, other angles (axis errors) up to ±0.2 deg, displacements up to ±0.5 mm.
LENGTH_ERROR = (0.5e-3, 1.0e-3)
OFFSET_ERROR = (np.radians(0.3), np.radians(0.8))
AXIS_ERROR = np.radians(0.2)
DISPLACEMENT_ERROR = 0.5e-3


def perturbed_params(nominal: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``nominal`` ``(N_PARAMS,)`` with random assembly errors of the sizes above."""
    params = np.array(nominal, dtype=float)
    for k, p in enumerate(PARAMS):
        sign = rng.choice((-1.0, 1.0))
        if p.unit is Unit.LINK:
            params[k] += sign * rng.uniform(*LENGTH_ERROR)
        elif p.joint is not None:
            params[k] += sign * rng.uniform(*OFFSET_ERROR)
        elif p.unit is Unit.ANGLE:
            params[k] += rng.uniform(-AXIS_ERROR, AXIS_ERROR)
        else:
            params[k] += rng.uniform(-DISPLACEMENT_ERROR, DISPLACEMENT_ERROR)
    return params


def perturbed_robot(robot: RobotConfig, seed: int) -> RobotConfig:
    """``robot`` with every leg perturbed (seeded): the "true" robot of a simulation."""
    from crawler_motion.model.calibration_file import nominal_calibration

    base = robot.geometry or nominal_calibration(robot.legs, (robot.l1, robot.l2, robot.l3))
    rng = np.random.default_rng(seed)
    table = np.stack([perturbed_params(n, rng) for n in base.nominal])
    return replace(robot, geometry=LegCalibration(robot.legs, table, base.nominal,
                                                  f"perturbed(seed={seed})"))


def measure(true_feet: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
    """Tracker readings of ``true_feet`` [m] with Gaussian noise ``noise`` [m] per axis."""
    if noise < 0.0:
        raise ValueError(f"tracker noise must be >= 0 m, got {noise}")
    return true_feet + rng.normal(0.0, noise, np.shape(true_feet)) if noise else true_feet.copy()
