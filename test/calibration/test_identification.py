"""Calibration: rank and identifiable set, identification recovering injected errors with and
without tracker noise, RLS-DE no worse than RLS, the excitation's boundary conditions and
limits, pose selection."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.calibration import excitation, selection
from crawler_motion.calibration.identify import Problem, de, rls, rls_de
from crawler_motion.calibration.jacobian import (
    condition_number,
    identifiable_set,
    leg_feet,
    require_rank,
    stacked_jacobian,
)
from crawler_motion.calibration.synthetic import measure, perturbed_robot
from crawler_motion.errors import CalibrationError
from crawler_motion.model.config import load_config

ROBOT = load_config().robot
LOW, HIGH = np.array([-0.8, -0.9, 0.2]), np.array([0.8, 1.3, 2.0])


def _problem(seed: int, leg: int, noise: float, n: int = 50) -> tuple[Problem, Problem]:
    true = perturbed_robot(ROBOT, seed).geometry
    assert true is not None
    rng = np.random.default_rng(seed)
    q, qv = rng.uniform(LOW, HIGH, (n, 3)), rng.uniform(LOW, HIGH, (100, 3))
    nominal = true.nominal[leg]
    cols = identifiable_set(stacked_jacobian(ROBOT, leg, nominal, q)).columns
    feet = measure(leg_feet(ROBOT, leg, true.params[leg], q), noise, rng)
    return (Problem(ROBOT, leg, q, feet, nominal.copy(), cols),
            Problem(ROBOT, leg, qv, leg_feet(ROBOT, leg, true.params[leg], qv), nominal, cols))


def test_rank_and_the_fixed_parameters_say_why() -> None:
    q = np.random.default_rng(0).uniform(LOW, HIGH, (50, 3))
    ident = identifiable_set(stacked_jacobian(ROBOT, 0, excitation.robot_params(ROBOT, 0), q))
    assert ident.rank == 15 and len(ident.columns) == 15
    assert ident.fixed == {"shoulder_dz": "same motion as hip_z",
                           "foot_z": "same motion as knee_offset"}


@pytest.mark.parametrize(("n", "ok"), [(4, False), (5, True)])
def test_too_few_poses_for_the_rank(n: int, ok: bool) -> None:
    q = np.random.default_rng(0).uniform(LOW, HIGH, (n, 3))
    jac = stacked_jacobian(ROBOT, 0, excitation.robot_params(ROBOT, 0), q)
    cols = list(identifiable_set(jac if n >= 5 else stacked_jacobian(
        ROBOT, 0, excitation.robot_params(ROBOT, 0),
        np.random.default_rng(1).uniform(LOW, HIGH, (50, 3)))).columns)
    if ok:
        require_rank(jac[:, cols], n, len(cols))
    else:
        with pytest.raises(CalibrationError, match="rank"):
            require_rank(jac[:, cols], n, len(cols))


@pytest.mark.parametrize(("leg", "seed"), [(0, 1), (1, 2), (2, 3), (3, 4)])
def test_noise_free_identification_recovers_the_leg(leg: int, seed: int) -> None:
    prob, val = _problem(seed, leg, 0.0)
    before = val.errors(prob.start).mean()
    first, hybrid = rls_de(prob, 10, 10, np.random.default_rng(seed))
    after = val.errors(hybrid.params).mean()
    assert after <= 0.02e-3 and after <= 0.05 * before
    assert prob.rms(hybrid.params) <= prob.rms(first.params)


@pytest.mark.parametrize("leg", [0, 3])
def test_noisy_identification_within_the_target(leg: int) -> None:
    prob, val = _problem(10 + leg, leg, 0.02e-3)
    _, hybrid = rls_de(prob, 10, 10, np.random.default_rng(0))
    assert val.errors(hybrid.params).mean() <= 0.05e-3
    alone = de(prob, 10, max(hybrid.evaluations // 10 - 1, 1), np.random.default_rng(0))
    assert hybrid.mean < alone.mean


@pytest.mark.parametrize(("seed", "leg"), [(10, 0), (10, 1), (10, 2), (10, 3), (11, 2),
                                         (12, 0)])
def test_rls_de_is_no_worse_than_rls_on_validation_with_tracker_noise(seed: int,
                                                                      leg: int) -> None:
    """The report's DE settings (population 20, 50 generations). With DE minimising the mean
    Euclidean error these cases came out worse than RLS on validation (by 14-32 %): DE fitted
    the noise of the 50 poses. Now DE minimises the RMS error (least squares, as RLS) and its
    result is kept only when it lowers that on the identification poses."""
    prob, val = _problem(seed, leg, 0.02e-3)
    first, hybrid = rls_de(prob, 20, 50, np.random.default_rng(0))
    assert prob.rms(hybrid.params) <= prob.rms(first.params)
    assert val.errors(hybrid.params).mean() <= val.errors(first.params).mean()


@pytest.mark.parametrize("noise", [0.0, 0.02e-3])
def test_de_improves_an_unconverged_rls_estimate(noise: float) -> None:
    """One RLS pass (as the study's RLS, not re-linearised to convergence) leaves the
    linearisation error; the DE stage lowers the identification RMS and the validation error,
    so its result replaces the RLS estimate."""
    prob, val = _problem(1, 0, noise)
    first, hybrid = rls_de(prob, 20, 50, np.random.default_rng(0), max_passes=1)
    assert first.iterations == 1
    assert prob.rms(hybrid.params) < 0.9 * prob.rms(first.params)
    assert val.errors(hybrid.params).mean() < 0.9 * val.errors(first.params).mean()
    assert hybrid.evaluations == first.evaluations + 20 * 51


def test_rls_alone_moves_towards_the_truth() -> None:
    prob, val = _problem(7, 1, 0.0)
    fit, sigma = rls(prob)
    assert fit.iterations >= 1 and val.errors(fit.params).mean() < 1e-6
    assert sigma.shape == (len(prob.columns),)


def _excitation(seed: int) -> excitation.Excitation:
    rng = np.random.default_rng(seed)
    return excitation.Excitation(rng.uniform(-0.02, 0.02, (3, 5)),
                                 rng.uniform(-0.02, 0.02, (3, 5)),
                                 0.5 * (ROBOT.lower + ROBOT.upper))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_excitation_starts_and_ends_at_rest_on_q0(seed: int) -> None:
    exc = _excitation(seed)
    q, qd, qdd = exc.evaluate(np.array([0.0, exc.period]))
    np.testing.assert_allclose(q, [exc.q0, exc.q0], atol=1e-12)
    np.testing.assert_allclose(qd, 0.0, atol=1e-12)
    np.testing.assert_allclose(qdd, 0.0, atol=1e-12)
    t, h = np.array([3.0, 11.0]), 1e-5
    num = (exc.evaluate(t + h)[0] - exc.evaluate(t - h)[0]) / (2 * h)
    np.testing.assert_allclose(exc.evaluate(t)[1], num, atol=1e-7)


def test_excitation_limits_are_checked() -> None:
    exc = _excitation(0)
    assert excitation.violation(ROBOT, 0, exc) == 0.0
    big = excitation.Excitation(exc.a * 40, exc.b * 40, exc.q0)
    assert excitation.violation(ROBOT, 0, big) > 0.0


def test_optimised_selection_beats_the_random_median() -> None:
    rng = np.random.default_rng(3)
    params = excitation.robot_params(ROBOT, 0)
    cols = list(identifiable_set(stacked_jacobian(
        ROBOT, 0, params, rng.uniform(LOW, HIGH, (100, 3)))).columns)
    exc, cost = excitation.optimise(ROBOT, 0, cols, rng, population=8, generations=5)
    assert excitation.violation(ROBOT, 0, exc) == 0.0 and cost < 1e3
    jac = stacked_jacobian(ROBOT, 0, params, excitation.candidates(exc, 80))[:, cols]
    picks = selection.select(jac, 20)
    assert len(set(picks)) == 20
    chosen = condition_number(jac.reshape(80, 3, -1)[picks].reshape(-1, len(cols)))
    assert chosen < np.median(selection.random_conditions(jac, 20, 31, rng))
