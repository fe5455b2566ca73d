"""Excitation trajectory (Fourier series + quintic, the study's eqs. 15-16), optimised for the
condition number of the identification Jacobian, and the candidate poses sampled from it.

Per joint: q(t) = sum_k [a_k/(w k) sin(w k t) - b_k/(w k) cos(w k t)] + sum_j c_j t^j,
w = 2 pi / T, the quintic's c_j solved so that q(0) = q(T) = q0 and q' = q'' = 0 at both ends.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crawler_motion.calibration.evolution import evolve
from crawler_motion.calibration.jacobian import condition_number, leg_feet, stacked_jacobian
from crawler_motion.model.config import RobotConfig

PERIOD = 25.0  # T [s] (the study's)
HARMONICS = 5  # N
#: Joint acceleration limit of the excitation [rad/s^2] (robot.yaml has none).
MAX_ACCELERATION = 2.0
#: Workspace: the foot stays at least this far [m] outside the coxa, horizontally from the root
#: axis (r >= l1 + margin: never under the body or on the root axis).
WORKSPACE_MARGIN = 0.02
#: Samples of the trajectory: for the limit checks and for the optimised condition number.
CHECK_SAMPLES = 251
COND_SAMPLES = 50


@dataclass(frozen=True)
class Excitation:
    """Fourier coefficients ``a``, ``b`` ``(3, N)`` [rad/s], centre pose ``q0`` (3,) [rad],
    period [s]."""

    a: np.ndarray
    b: np.ndarray
    q0: np.ndarray
    period: float = PERIOD

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint angles [rad], rates [rad/s], accelerations [rad/s^2], each ``(len(t), 3)``."""
        t = np.asarray(t, dtype=float)[:, None, None]
        n = self.a.shape[1]
        wk = 2 * np.pi / self.period * np.arange(1, n + 1)
        s, c = np.sin(wk * t), np.cos(wk * t)
        q = np.sum(self.a / wk * s - self.b / wk * c, axis=-1)
        qd = np.sum(self.a * c + self.b * s, axis=-1)
        qdd = np.sum(-self.a * wk * s + self.b * wk * c, axis=-1)
        coeffs = self.quintic()
        tt = t[:, :, 0]
        powers = tt ** np.arange(6)
        q = q + np.einsum("tj,ij->ti", powers, coeffs)
        d1 = np.arange(6) * np.concatenate([np.zeros_like(tt), powers[:, :-1]], axis=1)
        d2 = np.arange(6) * (np.arange(6) - 1) * np.concatenate(
            [np.zeros_like(tt), np.zeros_like(tt), powers[:, :-2]], axis=1)
        return q, qd + np.einsum("tj,ij->ti", d1, coeffs), qdd + np.einsum("tj,ij->ti", d2,
                                                                              coeffs)

    def quintic(self) -> np.ndarray:
        """Quintic coefficients ``c`` ``(3, 6)`` meeting the boundary conditions."""
        n = self.a.shape[1]
        wk = 2 * np.pi / self.period * np.arange(1, n + 1)
        f0 = -np.sum(self.b / wk, axis=-1)  # Fourier part at 0 (and T: it is periodic)
        fd0 = np.sum(self.a, axis=-1)
        fdd0 = np.sum(self.b * wk, axis=-1)
        big_t = self.period
        rows = []
        for t in (0.0, big_t):
            rows.append([t ** j for j in range(6)])
            rows.append([j * t ** (j - 1) if j >= 1 else 0.0 for j in range(6)])
            rows.append([j * (j - 1) * t ** (j - 2) if j >= 2 else 0.0 for j in range(6)])
        rhs = np.stack([self.q0 - f0, -fd0, -fdd0, self.q0 - f0, -fd0, -fdd0], axis=1)
        return np.linalg.solve(np.array(rows), rhs.T).T


def violation(robot: RobotConfig, leg: int, exc: Excitation) -> float:
    """Total excess over the position, velocity, acceleration and workspace limits (0: ok)."""
    t = np.linspace(0.0, exc.period, CHECK_SAMPLES)
    q, qd, qdd = exc.evaluate(t)
    total = np.sum(np.maximum(robot.lower - q, 0) + np.maximum(q - robot.upper, 0))
    total += np.sum(np.maximum(np.abs(qd) - robot.velocity, 0))
    total += np.sum(np.maximum(np.abs(qdd) - MAX_ACCELERATION, 0))
    feet = leg_feet(robot, leg, robot_params(robot, leg), q) - robot.hips[leg]
    reach = np.hypot(feet[:, 0], feet[:, 1])
    total += np.sum(np.maximum(robot.l1 + WORKSPACE_MARGIN - reach, 0)) * 10.0
    return float(total)


def robot_params(robot: RobotConfig, leg: int) -> np.ndarray:
    """The current geometry of leg ``leg`` (nominal without a calibration)."""
    from crawler_motion.model.leg_geometry import nominal_params

    if robot.geometry is None:
        return nominal_params(robot.l1, robot.l2, robot.l3)
    return robot.geometry.params[leg]


def excitation_cost(robot: RobotConfig, leg: int, exc: Excitation, columns: list[int]
                    ) -> float:
    """Condition number of the stacked Jacobian over `COND_SAMPLES` samples, plus a penalty
    of 1e3 per unit of limit violation."""
    q = exc.evaluate(np.linspace(0.0, exc.period, COND_SAMPLES, endpoint=False))[0]
    jac = stacked_jacobian(robot, leg, robot_params(robot, leg), q)[:, columns]
    return min(condition_number(jac), 1e6) + 1e3 * violation(robot, leg, exc)


def optimise(robot: RobotConfig, leg: int, columns: list[int], rng: np.random.Generator,
             harmonics: int = HARMONICS, population: int = 20, generations: int = 40
             ) -> tuple[Excitation, float]:
    """The excitation with the smallest `excitation_cost` found by DE (coefficients within
    ``±0.1`` rad/s); returns it and its cost."""
    q0 = 0.5 * (robot.lower + robot.upper)
    dims = 2 * 3 * harmonics
    bound = np.full(dims, 0.1)

    def unpack(x: np.ndarray) -> Excitation:
        ab = x.reshape(2, 3, harmonics)
        return Excitation(ab[0], ab[1], q0)

    def cost(points: np.ndarray) -> np.ndarray:
        return np.array([excitation_cost(robot, leg, unpack(x), columns) for x in points])

    result = evolve(cost, -bound, bound, population, generations, rng)
    return unpack(result.best), result.cost


def candidates(exc: Excitation, count: int) -> np.ndarray:
    """``count`` poses ``(count, 3)`` [rad] evenly spaced in time over (0, T)."""
    t = (np.arange(count) + 0.5) * exc.period / count
    return exc.evaluate(t)[0]
