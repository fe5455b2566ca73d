"""The study's comparison on a simulated leg: validation on separate poses, the table."""

from __future__ import annotations

import pytest

from crawler_motion.calibration import report, study
from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.model.config import load_config

ROBOT = load_config().robot


@pytest.fixture(scope="module")
def selection() -> study.PoseSelection:
    """The report's selection (40 generations of the excitation's DE): with the 15-parameter
    leg, 10 generations left a selection whose noisy validation mean was 0.057 mm."""
    return study.select_poses(ROBOT, 1, 200, 50, 0, generations=40)


@pytest.fixture(scope="module")
def quick_selection() -> study.PoseSelection:
    return study.select_poses(ROBOT, 1, 200, 50, 0, generations=10)


@pytest.mark.parametrize(("noise", "bound"), [(0.0, 0.02e-3), (0.02e-3, 0.05e-3)])
def test_validation_errors_meet_the_targets(selection: study.PoseSelection, noise: float,
                                            bound: float) -> None:
    true = perturbed_robot(ROBOT, 8).geometry
    assert true is not None
    rep = report.leg_report(ROBOT, 1, true.params[1], noise, 0, selection)
    before = rep.validation["before"][0]
    assert before > 1e-3  # millimetres before calibration
    assert rep.validation["rls-de"][0] <= min(bound, 0.05 * before)
    assert rep.validation["rls-de"][0] <= rep.validation["rls"][0]
    assert rep.validation["de"][0] > rep.validation["rls-de"][0]
    assert selection.condition < selection.random_median
    text = report.format_report(rep)
    assert text.count("\n| ") == 5 and "| ≤ 0.05 | 50 |" in text and "leg lb" in text


def test_the_studys_single_rls_pass_leaves_de_something_to_improve(
        quick_selection: study.PoseSelection) -> None:
    true = perturbed_robot(ROBOT, 8).geometry
    assert true is not None
    rep = report.leg_report(ROBOT, 1, true.params[1], 0.0, 0, quick_selection,
                             rls_passes=1)
    fits = rep.comparison.fits
    assert fits["rls"].iterations == 1 and fits["rls-de"].iterations > 1
    assert rep.validation["rls-de"][0] < 0.9 * rep.validation["rls"][0]
    assert rep.validation["rls-de"][0] < rep.validation["de"][0]
