"""Scanner returns into the map frame, and the height variance of each return (spec eq. 3).

A return ``p_S`` (scanner_link) goes to base_link and then to the map (odom) frame:
``p_B = R_BS p_S + t_BS``, ``p_M = R_MB p_B + t_MB``; its measured height is ``z`` of ``p_M``.
Its height variance is ``σ_p² = J_S Σ_S J_Sᵀ + J_q Σ_q J_qᵀ`` with ``Σ_S`` the sensor noise of
that return (range noise along the beam, lateral noise across it growing with range) and
``Σ_q`` the covariance of the body's roll and pitch (yaw does not move a height).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import ScannerConfig
from crawler_motion.model.rotations import roll_pitch, rpy_matrix


@dataclass(frozen=True)
class NoiseModel:
    """Sensor and attitude noise (standard deviations): ``range_noise`` [m] along the beam,
    ``lateral_noise`` [m per m of range] across it, ``attitude_noise`` [rad] of roll and
    pitch each."""

    range_noise: float = 0.005
    lateral_noise: float = 0.002
    attitude_noise: float = 0.005

    def __post_init__(self) -> None:
        for name in ("range_noise", "lateral_noise", "attitude_noise"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 1.0):
                raise ConfigError(f"{name} must be within [0, 1], got {value!r}")
        if self.range_noise == 0.0 and self.lateral_noise == 0.0 and self.attitude_noise == 0.0:
            raise ConfigError("range_noise, lateral_noise and attitude_noise are all 0: a "
                              "return would have zero variance; give at least one a value")


@dataclass(frozen=True)
class Mount:
    """The scanner's pose in base_link: ``rotation`` (scanner_link -> base_link) and
    ``position`` [m]."""

    rotation: np.ndarray
    position: np.ndarray

    @classmethod
    def from_config(cls, scanner: ScannerConfig) -> Mount:
        """The mount of robot.yaml's ``scanner`` section (fixed-axis roll, pitch, yaw)."""
        return cls(rpy_matrix(scanner.rpy), np.asarray(scanner.position, float))


def returns_in_map(points: np.ndarray, mount: Mount, body_rotation: np.ndarray,
                   body_position: np.ndarray, noise: NoiseModel
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Map positions ``(k, 3)`` [m] and height variances ``(k,)`` [m²] of scanner returns
    ``points`` ``(k, 3)`` (scanner_link [m]) for the body pose (rotation base_link -> map,
    position [m])."""
    p_b = points @ mount.rotation.T + mount.position
    p_m = p_b @ body_rotation.T + body_position
    rng = np.linalg.norm(points, axis=1)
    beam = points / np.maximum(rng, 1e-12)[:, None]  # unit beam in scanner_link
    j_s = body_rotation[2] @ mount.rotation  # dz / dp_S (3,)
    along = beam @ j_s  # component of J_S along the beam
    lateral_sq = np.maximum(j_s @ j_s - along**2, 0.0)  # |J_S (I - b bᵀ)|²
    var = noise.range_noise**2 * along**2 + (noise.lateral_noise * rng) ** 2 * lateral_sq
    if noise.attitude_noise > 0.0:
        var = var + noise.attitude_noise**2 * _attitude_jacobian_sq(p_b, body_rotation)
    return p_m, var


def _attitude_jacobian_sq(p_b: np.ndarray, body_rotation: np.ndarray) -> np.ndarray:
    """``|J_q|²`` per return: squared derivatives of the map height by body roll and pitch."""
    roll, pitch = roll_pitch(body_rotation)
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    x, y, z = p_b[:, 0], p_b[:, 1], p_b[:, 2]
    d_roll = cp * cr * y - cp * sr * z
    d_pitch = -cp * x - sp * sr * y - sp * cr * z
    return d_roll**2 + d_pitch**2
