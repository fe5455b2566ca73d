"""The rigid transform between two point sets (weighted Kabsch / Horn), pure numpy."""

from __future__ import annotations

import numpy as np


def fit_rigid(source: np.ndarray, target: np.ndarray, weights: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Rotation ``(3, 3)`` and translation ``(3,)`` [m] minimising the weighted squared
    distances ``|R source_i + t - target_i|^2`` (points ``(M, 3)`` [m], ``weights`` ``(M,)``
    >= 0, at least three non-collinear points with weight)."""
    w = np.asarray(weights, dtype=float) / np.sum(weights)
    mean_s, mean_t = w @ source, w @ target
    cov = ((target - mean_t) * w[:, None]).T @ (source - mean_s)
    u, _, vt = np.linalg.svd(cov)
    flip = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(u @ vt)) or 1.0)])
    rotation = u @ flip @ vt
    return rotation, mean_t - rotation @ mean_s
