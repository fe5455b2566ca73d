"""The weighted rigid fit: exact for a rigid copy, zero weight ignores a row, no reflection."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.calibration.rigid import fit_rigid
from crawler_motion.model.rotations import rotation_vector_matrix


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_rigid_copy_is_fitted_exactly_and_zero_weight_rows_are_ignored(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rotation = rotation_vector_matrix(rng.normal(size=3))
    translation = rng.normal(size=3)
    source = rng.normal(size=(20, 3))
    target = source @ rotation.T + translation
    target[3] += 5.0  # an outlier with no weight
    weights = np.ones(20)
    weights[3] = 0.0
    r, t = fit_rigid(source, target, weights)
    np.testing.assert_allclose(r, rotation, atol=1e-12)
    np.testing.assert_allclose(t, translation, atol=1e-12)


def test_mirrored_points_still_give_a_rotation() -> None:
    source = np.random.default_rng(3).normal(size=(10, 3))
    r, _ = fit_rigid(source, source * np.array([1.0, 1.0, -1.0]), np.ones(10))
    assert np.linalg.det(r) == pytest.approx(1.0)
