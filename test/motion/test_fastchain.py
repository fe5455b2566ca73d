"""The float fast path of calibrated legs equals the numpy reference (`model.calibrated`):
forward kinematics, Newton-refined IK, joint rates, and the errors it hands to the reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.errors import JointLimitError, UnreachableError
from crawler_motion.model import kinematics
from crawler_motion.model.config import load_config
from crawler_motion.model.leg_geometry import frames_forward, joint_frames
from crawler_motion.motion.fastchain import ScalarLeg
from crawler_motion.motion.fastpath import FastKinematics, Track, joint_targets
from crawler_motion.motion.gait import (
    WalkParams,
    plan_walk,
)

CFG = load_config()
NOMINAL = CFG.robot
TRUE = perturbed_robot(NOMINAL, 21)
KIN = FastKinematics(TRUE)


def _frames(leg: int):
    assert TRUE.geometry is not None
    return joint_frames(TRUE.geometry.params[leg], TRUE.hips[leg],
                        float(TRUE.neutral_yaw[leg]))


def _poses(n: int, seed: int) -> np.ndarray:
    q = np.random.default_rng(seed).uniform([-0.7, -0.8, 0.3], [0.7, 1.2, 2.0], (4 * n, 4, 3))
    rel = kinematics.forward_kinematics(NOMINAL, q) - NOMINAL.hips
    return q[(np.hypot(rel[..., 0], rel[..., 1]) > 0.04).all(-1)][:n]


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 3), st.floats(-1.0, 1.0), st.floats(-1.0, 1.4), st.floats(0.1, 2.2))
def test_scalar_forward_and_jacobian_equal_the_reference(leg, q0, q1, q2):
    q = np.array([q0, q1, q2])
    angles = np.zeros((4, 3))
    angles[leg] = q
    foot, cols = ScalarLeg(_frames(leg)).forward(q0, q1, q2)
    reference = kinematics.calibrated._leg_fk(TRUE, leg, q)
    np.testing.assert_allclose(foot, kinematics.forward_kinematics(TRUE, angles)[leg], atol=1e-15)
    np.testing.assert_allclose(foot, frames_forward(_frames(leg), q), atol=1e-15)
    np.testing.assert_allclose(np.array(cols).T, reference[1], atol=1e-14)


def test_fast_ik_and_rates_equal_the_reference_over_a_walk():
    plan = plan_walk(CFG, WalkParams.defaults(CFG.gait), 2)
    track = Track(plan.legs)
    worst_q = worst_v = worst_foot = 0.0
    for t in np.linspace(0.0, plan.duration, 150):
        pos, vel, _ = plan.evaluate(t)
        q, qd = joint_targets(track, KIN, float(t))
        ref_q = kinematics.inverse_kinematics(TRUE, pos[0])
        ref_v = kinematics.joint_velocities(TRUE, ref_q, vel[0])
        worst_q = max(worst_q, float(np.abs(np.reshape(q, (4, 3)) - ref_q).max()))
        worst_v = max(worst_v, float(np.abs(np.reshape(qd, (4, 3)) - ref_v).max()))
        feet = kinematics.forward_kinematics(TRUE, np.reshape(q, (4, 3)))
        worst_foot = max(worst_foot, float(np.abs(feet - pos[0]).max()))
    assert worst_foot < 1e-9  # the issue asks < 1e-6 m
    assert worst_q < 1e-9 and worst_v < 1e-9


def test_calibrated_fast_path_is_not_the_nominal_one():
    feet = NOMINAL.standing_feet()
    q_cal = np.reshape(KIN.inverse(feet.reshape(-1).tolist()), (4, 3))
    q_nom = np.reshape(FastKinematics(NOMINAL).inverse(feet.reshape(-1).tolist()), (4, 3))
    assert np.abs(q_cal - q_nom).max() > 5e-3
    np.testing.assert_allclose(kinematics.forward_kinematics(TRUE, q_cal), feet, atol=1e-9)


def _feet_at(q_lf: tuple[float, float, float]) -> np.ndarray:
    q = kinematics.inverse_kinematics(TRUE, NOMINAL.standing_feet())
    q[0] = q_lf
    return kinematics.forward_kinematics(TRUE, q)


@pytest.mark.parametrize(("feet", "error"), [
    (NOMINAL.standing_feet() + np.array([0.0, 0.2, 0.0]) * [[1], [0], [0], [0]],
     UnreachableError),                               # lf 0.2 m beyond its reach
    (NOMINAL.standing_feet(), None),                  # standing: solved
    (_feet_at((0.95, 0.3, 1.0)), JointLimitError),    # root 0.05 rad beyond its limit
    (_feet_at((0.899, 0.3, 1.0)), None),              # root just inside
    (_feet_at((0.3, 0.3, 0.08)), JointLimitError),    # knee below its lower limit
])
def test_errors_are_the_references(feet, error):
    flat = feet.reshape(-1).tolist()
    if error is None:
        np.testing.assert_allclose(np.reshape(KIN.inverse(flat), (4, 3)),
                                   kinematics.inverse_kinematics(TRUE, feet), atol=1e-9)
        return
    with pytest.raises(error) as fast:
        KIN.inverse(flat)
    with pytest.raises(error) as reference:
        kinematics.inverse_kinematics(TRUE, feet)
    assert str(fast.value) == str(reference.value)


def test_random_poses_round_trip():
    q = _poses(100, 5)
    feet = kinematics.forward_kinematics(TRUE, q)
    for k in range(len(q)):
        back = np.reshape(KIN.inverse(feet[k].reshape(-1).tolist(), check=False), (4, 3))
        np.testing.assert_allclose(back, q[k], atol=1e-9)


class _Counted:
    """A leg's chain function that counts its evaluations."""

    def __init__(self, leg: ScalarLeg) -> None:
        self.local, self.calls = leg._local, 0
        leg._local = self

    def __call__(self, *q):
        self.calls += 1
        return self.local(*q)


def _closed_form(leg: int, target: np.ndarray) -> tuple[float, float, float]:
    feet = NOMINAL.standing_feet().copy()
    feet[leg] = target
    return tuple(kinematics.inverse_kinematics(NOMINAL, feet, check=False)[leg])


def _solve(chain: ScalarLeg, leg: int, target: np.ndarray):
    return chain.solve(tuple(target), _closed_form(leg, target), float(TRUE.knee_sign[leg]))


def _target(leg: int, q: np.ndarray) -> np.ndarray:
    angles = kinematics.inverse_kinematics(TRUE, NOMINAL.standing_feet())
    angles[leg] = q
    return kinematics.forward_kinematics(TRUE, angles)[leg]


@pytest.mark.parametrize(("move", "warm"), [
    (0.0, True),     # the same target again: the warm start is right
    (0.003, True),   # a 100 Hz walking step (~3 mm of foot travel): warm
    (0.15, False),   # a jump between far-apart targets: the warm start misses, cold start
])
def test_warm_start_is_used_only_near_the_last_solution(move, warm):
    leg = 1
    q_a = np.array([0.2, 0.4, 1.2])
    target_a = _target(leg, q_a)
    target_b = _target(leg, q_a + move * np.array([1.0, -1.0, 1.0]) / 0.3)
    chain = ScalarLeg(_frames(leg))
    _solve(chain, leg, target_a)
    counted = _Counted(chain)
    solution = _solve(chain, leg, target_b)
    cold_chain = ScalarLeg(_frames(leg))
    cold = _Counted(cold_chain)
    cold_solution = _solve(cold_chain, leg, target_b)
    # warm: fewer evaluations than the cold start; cold: one refused warm evaluation more
    assert (counted.calls < cold.calls) if warm else (counted.calls == cold.calls + 1)
    np.testing.assert_allclose(solution[:3], cold_solution[:3], atol=1e-12)
    foot = ScalarLeg(_frames(leg)).forward(*solution[:3])[0]
    assert np.linalg.norm(np.subtract(foot, target_b)) < 1e-12


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 3), st.integers(0, 99), st.integers(0, 99))
def test_solutions_do_not_depend_on_the_last_call(leg, a, b):
    """Any pose after any other (near or far) gives the cold start's solution and its rates."""
    q = _poses(100, 8)
    feet = kinematics.forward_kinematics(TRUE, q)
    chain, fresh = ScalarLeg(_frames(leg)), ScalarLeg(_frames(leg))
    _solve(chain, leg, feet[a, leg])
    after = _solve(chain, leg, feet[b, leg])
    alone = _solve(fresh, leg, feet[b, leg])
    np.testing.assert_allclose(after[:3], q[b, leg], atol=1e-9)
    np.testing.assert_allclose(after[:3], alone[:3], atol=1e-12)
    v = (0.1, -0.2, 0.05)
    np.testing.assert_allclose(chain.rates_at(after, v), fresh.rates(tuple(alone[:3]), v),
                               rtol=1e-10, atol=1e-12)


def test_an_unreachable_target_clears_the_warm_start():
    leg = 0
    chain = ScalarLeg(_frames(leg))
    reachable = _target(leg, np.array([0.1, 0.3, 1.0]))
    assert _solve(chain, leg, reachable) is not None
    far = tuple(np.add(reachable, [0.0, 0.2, 0.0]))  # beyond the reach, from the last start
    assert chain.solve(far, _closed_form(leg, reachable), float(TRUE.knee_sign[leg])) is None
    assert chain._warm is None
    counted = _Counted(chain)
    assert _solve(chain, leg, reachable) is not None
    assert counted.calls >= 3  # a cold start again


def test_rates_reuse_the_solved_jacobian_only_at_the_returned_angles():
    feet = NOMINAL.standing_feet().reshape(-1).tolist()
    kin = FastKinematics(TRUE)
    q = kin.inverse(feet)
    v = [0.05, -0.02, 0.01] * 4
    reference = kinematics.joint_velocities(TRUE, np.reshape(q, (4, 3)), np.reshape(v, (4, 3)))
    np.testing.assert_allclose(np.reshape(kin.velocities(q, v), (4, 3)), reference, atol=1e-12)
    moved = [x + 0.01 for x in q]  # other angles: their own Jacobian, not the cached one
    reference = kinematics.joint_velocities(TRUE, np.reshape(moved, (4, 3)),
                                            np.reshape(v, (4, 3)))
    np.testing.assert_allclose(np.reshape(kin.velocities(moved, v), (4, 3)), reference,
                               atol=1e-12)
