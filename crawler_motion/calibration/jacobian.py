"""The identification Jacobian of one leg: stacked over poses, scaled, its rank and the
identifiable parameter set."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from crawler_motion.errors import CalibrationError
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.leg_geometry import INDEX, N_PARAMS, NAMES, leg_chain, to_base

#: The order in which parameters are kept when some are linearly dependent: physical links and
#: joint offsets first, then positions and axis angles; the foot-tip and shoulder-height
#: displacements, which the others absorb, last.
PREFERENCE: tuple[str, ...] = (
    "l1", "l2", "l3", "root_offset", "shoulder_offset", "knee_offset", "hip_x", "hip_y",
    "hip_z", "root_tilt_x", "root_tilt_y", "shoulder_twist", "knee_twist", "knee_yaw",
    "foot_y", "shoulder_dz", "foot_z")
#: Singular values below this fraction of the largest (column-normalised) count as zero.
RANK_TOL = 1e-8


def leg_feet(robot: RobotConfig, leg: int, params: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Foot positions ``(..., 3)`` [m] in base_link of leg ``leg`` with geometry ``params``
    ``(..., N_PARAMS)`` at joint angles ``q`` ``(..., 3)`` [rad] (broadcast)."""
    return to_base(leg_chain(params, q)[0], robot.hips[leg], float(robot.neutral_yaw[leg]))


def stacked_jacobian(robot: RobotConfig, leg: int, params: np.ndarray, q: np.ndarray
                     ) -> np.ndarray:
    """``d feet / d params`` stacked over the poses ``q`` ``(M, 3)``: ``(3 M, N_PARAMS)``,
    rows x, y, z of pose 0, then pose 1, ... (base_link; m per m and m per rad)."""
    jac = leg_chain(params, q)[1]  # (M, 3, N)
    base = to_base(np.swapaxes(jac, -1, -2), 0.0, float(robot.neutral_yaw[leg]))
    return np.swapaxes(base, -1, -2).reshape(-1, N_PARAMS)


def column_scale(jac: np.ndarray) -> np.ndarray:
    """Euclidean norms of the columns of ``jac`` (1 for a zero column): dividing by them makes
    metres and radians comparable before any rank or condition number."""
    norms = np.linalg.norm(jac, axis=0)
    return np.where(norms > 0.0, norms, 1.0)


def condition_number(jac: np.ndarray) -> float:
    """Condition number of ``jac`` with normalised columns (inf when rank deficient)."""
    s = np.linalg.svd(jac / column_scale(jac), compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > RANK_TOL * s[0] else float("inf")


def _rank(jac: np.ndarray) -> int:
    if jac.shape[1] == 0:
        return 0
    s = np.linalg.svd(jac / column_scale(jac), compute_uv=False)
    return int(np.sum(s > RANK_TOL * s[0]))


@dataclass(frozen=True)
class Identifiability:
    """Which parameters the poses identify: ``columns`` (indices, `PREFERENCE` order), the
    numerical ``rank`` of all candidates and, per fixed parameter, why."""

    columns: tuple[int, ...]
    rank: int
    fixed: dict[str, str] = field(default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        """The identified parameters' names."""
        return tuple(NAMES[k] for k in self.columns)

    def describe(self) -> str:
        """One paragraph: rank, identified set, fixed parameters with their reasons."""
        fixed = "; ".join(f"{name} ({why})" for name, why in self.fixed.items())
        return (f"rank {self.rank} of {N_PARAMS} candidate parameters; identified "
                f"{', '.join(self.names)}; fixed at their current value: {fixed or 'none'}")


def identifiable_set(jac: np.ndarray) -> Identifiability:
    """Keep each parameter in `PREFERENCE` order that raises the numerical rank of the scaled
    stacked Jacobian ``jac`` ``(3 M, N_PARAMS)``; a fixed parameter's reason names the kept
    ones its column is a combination of."""
    kept: list[int] = []
    fixed: dict[str, str] = {}
    scaled = jac / column_scale(jac)
    for name in PREFERENCE:
        k = INDEX[name]
        if _rank(jac[:, [*kept, k]]) > len(kept):
            kept.append(k)
            continue
        coef = np.linalg.lstsq(scaled[:, kept], scaled[:, k], rcond=None)[0]
        big = [NAMES[kept[i]] for i in np.argsort(-np.abs(coef)) if abs(coef[i]) > 1e-3][:3]
        fixed[name] = f"same motion as {' + '.join(big) or 'nothing: no effect'}"
    return Identifiability(tuple(kept), _rank(jac), fixed)


def require_rank(jac: np.ndarray, n_poses: int, needed: int) -> None:
    """Raise `CalibrationError` unless the poses give the Jacobian at least ``needed`` rank."""
    rank = _rank(jac)
    if rank < needed:
        raise CalibrationError(f"{n_poses} poses give the identification Jacobian rank {rank}; "
                               f"the leg's {needed} identifiable parameters need rank {needed} "
                               f"(at least {-(-needed // 3)} poses, spread over the joint ranges)")
