"""The float fast path of calibrated legs against the numpy reference (`model.calibrated`):
forward kinematics and Jacobian equal; the refined IK lands within `STEP_BOUND` (< 1e-6 m) for
random calibrations and reachable points, from cold and warm starts; joint rates; the errors it
hands to the reference; one chain evaluation per leg and tick while walking."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.errors import JointLimitError, UnreachableError
from crawler_motion.model import kinematics
from crawler_motion.model.calibration_file import LegCalibration
from crawler_motion.model.config import RobotConfig, load_config
from crawler_motion.model.leg_geometry import frames_forward, joint_frames
from crawler_motion.motion.fastchain import STEP_BOUND, WARM_START_MISS, ScalarLeg
from crawler_motion.motion.fastpath import FastKinematics, Track, joint_targets
from crawler_motion.motion.gait import WalkParams, plan_walk

CFG = load_config()
NOMINAL = CFG.robot
TRUE = perturbed_robot(NOMINAL, 21)
KIN = FastKinematics(TRUE)
#: Joint rates of the fast path vs the reference's at the same angles, relative to the leg's
#: rates (at least 0.01 rad/s): their Jacobian is up to a last Newton step (~2e-4 rad) away.
RATE_TOL = 1e-3


def _frames(leg: int, robot: RobotConfig = TRUE):
    assert robot.geometry is not None
    return joint_frames(robot.geometry.params[leg], robot.hips[leg],
                        float(robot.neutral_yaw[leg]))


def _poses(n: int, seed: int, knee: float = 0.3) -> np.ndarray:
    """Poses with the foot off the root axis and the knee bent by at least ``knee`` [rad]."""
    q = np.random.default_rng(seed).uniform([-0.7, -0.8, knee], [0.7, 1.2, 2.0],
                                            (max(4 * n, 50), 4, 3))
    rel = kinematics.forward_kinematics(NOMINAL, q) - NOMINAL.hips
    return q[(np.hypot(rel[..., 0], rel[..., 1]) > 0.04).all(-1)][:n]


def _scaled(seed: int, scale: float) -> RobotConfig:
    """A perturbed robot whose assembly errors are ``scale`` times the synthetic ones."""
    true = perturbed_robot(NOMINAL, seed)
    assert true.geometry is not None
    nominal = true.geometry.nominal
    table = nominal + scale * (true.geometry.params - nominal)
    return replace(true, geometry=LegCalibration(NOMINAL.legs, table, nominal, "scaled"))


def _foot_miss(robot: RobotConfig, q: list[float], feet: np.ndarray) -> float:
    """Largest foot distance [m] of the reference FK at ``q`` (flat) from ``feet``."""
    got = kinematics.forward_kinematics(robot, np.reshape(q, (4, 3)))
    return float(np.linalg.norm(got - np.reshape(feet, (4, 3)), axis=-1).max())


def _assert_rates(robot: RobotConfig, q: list[float], v: np.ndarray, qd: list[float]) -> None:
    ref = kinematics.joint_velocities(robot, np.reshape(q, (4, 3)), np.reshape(v, (4, 3)))
    err = np.linalg.norm(np.reshape(qd, (4, 3)) - ref, axis=-1)
    assert (err <= RATE_TOL * np.maximum(np.linalg.norm(ref, axis=-1), 0.01)).all(), err


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


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.0, 4.0), st.integers(0, 10_000),
       st.floats(-0.03, 0.03))
def test_ik_lands_within_the_bound_for_random_calibrations_and_points(seed, scale, pose, move):
    """Cold start, a warm start from a nearby solution, and one after a jump: every foot within
    `STEP_BOUND` of its target through the reference FK (the issue asks < 1e-6 m), at the
    pose's own angles. Knees bent by 0.8 rad or more: a target beyond the nominal leg's reach
    starts the refinement, here and in the reference, from a nearly straight knee, which may
    end on the other knee branch."""
    robot = _scaled(seed, scale)
    kin = FastKinematics(robot)
    q = _poses(2, pose, knee=0.8)
    assert len(q) == 2
    for angles in (q[0], q[0] + move, q[1]):  # cold, warm (nearby), after a jump
        feet = kinematics.forward_kinematics(robot, angles)
        got = kin.inverse(feet.reshape(-1).tolist(), check=False)
        assert _foot_miss(robot, got, feet) <= STEP_BOUND
        np.testing.assert_allclose(np.reshape(got, (4, 3)), angles, atol=1e-5)


WALKS = [{}, {"gait": "wave", "profile": "rest"},
         {"heading": -2.5, "turn": 0.2, "stride": 0.03, "lift": 0.015, "arc": 0.02}]


@pytest.mark.parametrize("overrides", WALKS, ids=lambda d: ",".join(d) or "defaults")
def test_walk_at_the_tick_rate_lands_within_the_bound_with_one_evaluation_per_leg(overrides):
    """The planner's use: 100 Hz along a walk. Feet within `STEP_BOUND`, angles as the
    reference's, rates as the reference's at the returned angles (checked every third tick);
    one chain evaluation per leg and tick (but a few)."""
    plan = plan_walk(CFG, WalkParams.defaults(CFG.gait, **overrides), 2)
    track = Track(plan.legs)
    kin = FastKinematics(TRUE)
    calls = [_Counted(chain) for chain in kin._chains]
    times = np.arange(0.0, plan.duration, 0.01)
    worst_foot = worst_q = 0.0
    for k, t in enumerate(times):
        pos, vel, _ = plan.evaluate(t)
        q, qd = joint_targets(track, kin, float(t))
        if k == 0:
            first = sum(c.calls for c in calls)
        if k % 3:
            continue
        worst_foot = max(worst_foot, _foot_miss(TRUE, q, pos[0]))
        ref_q = kinematics.inverse_kinematics(TRUE, pos[0])
        worst_q = max(worst_q, float(np.abs(np.reshape(q, (4, 3)) - ref_q).max()))
        _assert_rates(TRUE, q, vel[0], qd)
    assert worst_foot <= STEP_BOUND and worst_q < 1e-6
    per_leg = (sum(c.calls for c in calls) - first) / (4 * (len(times) - 1))
    assert per_leg < 1.05, per_leg


def test_calibrated_fast_path_is_not_the_nominal_one():
    feet = NOMINAL.standing_feet()
    q_cal = np.reshape(KIN.inverse(feet.reshape(-1).tolist()), (4, 3))
    q_nom = np.reshape(FastKinematics(NOMINAL).inverse(feet.reshape(-1).tolist()), (4, 3))
    assert np.abs(q_cal - q_nom).max() > 5e-3
    assert _foot_miss(TRUE, q_cal.reshape(-1).tolist(), feet) <= STEP_BOUND


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
    for kin in (FastKinematics(TRUE), KIN):  # cold, and after other targets
        if error is None:
            np.testing.assert_allclose(np.reshape(kin.inverse(flat), (4, 3)),
                                       kinematics.inverse_kinematics(TRUE, feet), atol=1e-6)
            assert _foot_miss(TRUE, kin.inverse(flat), feet) <= STEP_BOUND
            continue
        with pytest.raises(error) as fast:
            kin.inverse(flat)
        with pytest.raises(error) as reference:
            kinematics.inverse_kinematics(TRUE, feet)
        assert str(fast.value) == str(reference.value)


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
    """As `FastKinematics.inverse` does: the warm start, else the cold one."""
    q = chain.warm(*target)
    return q if q is not None else chain.cold(*target, _closed_form(leg, target),
                                              float(TRUE.knee_sign[leg]))


def _target(leg: int, q: np.ndarray) -> np.ndarray:
    angles = kinematics.inverse_kinematics(TRUE, NOMINAL.standing_feet())
    angles[leg] = q
    return kinematics.forward_kinematics(TRUE, angles)[leg]


@pytest.mark.parametrize(("move", "history", "evaluations"), [
    (0.0, True, 1),     # the same target again: one evaluation
    (0.01, True, 1),    # ~2 mm of foot travel per call, as walking at 100 Hz: one evaluation
    (0.01, False, 2),   # the same after a cold start (no correction known yet): two
    (0.5, True, None),  # a jump between far-apart targets: the warm start misses, cold start
])
def test_warm_start_is_used_only_near_the_last_solution(move, history, evaluations):
    """Targets ``move`` [rad per joint] apart: two solved (one with no ``history``), then the
    next one."""
    leg = 1
    q_a = np.array([0.2, 0.4, 1.2])
    step = move * np.array([1.0, -1.0, 1.0])
    chain = ScalarLeg(_frames(leg))
    if history:
        _solve(chain, leg, _target(leg, q_a - step))
    _solve(chain, leg, _target(leg, q_a))
    target_b = _target(leg, q_a + step)
    counted = _Counted(chain)
    solution = _solve(chain, leg, target_b)
    cold_chain = ScalarLeg(_frames(leg))
    cold = _Counted(cold_chain)
    cold_solution = _solve(cold_chain, leg, target_b)
    if evaluations is None:  # one refused warm evaluation more than the cold start
        assert counted.calls == cold.calls + 1 and cold.calls > 1
    else:
        assert counted.calls == evaluations < cold.calls
    np.testing.assert_allclose(solution, cold_solution, atol=1e-6)
    foot = ScalarLeg(_frames(leg)).forward(*solution)[0]
    assert np.linalg.norm(np.subtract(foot, target_b)) <= STEP_BOUND


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 3), st.integers(0, 99), st.integers(0, 99))
def test_solutions_do_not_depend_on_the_last_call_beyond_the_bound(leg, a, b):
    """Any pose after any other (near or far) lands within the bound, at the cold start's
    angles (to the bound), with its rates."""
    q = _poses(100, 8)
    feet = kinematics.forward_kinematics(TRUE, q)
    chain, fresh = ScalarLeg(_frames(leg)), ScalarLeg(_frames(leg))
    _solve(chain, leg, feet[a, leg])
    after = _solve(chain, leg, feet[b, leg])
    alone = _solve(fresh, leg, feet[b, leg])
    assert np.linalg.norm(np.subtract(chain.forward(*after)[0], feet[b, leg])) <= STEP_BOUND
    np.testing.assert_allclose(after, q[b, leg], atol=1e-6)
    np.testing.assert_allclose(after, alone, atol=1e-6)
    v = (0.1, -0.2, 0.05)
    exact = np.array(fresh.rates(after, v))
    assert np.linalg.norm(np.subtract(chain.rates_last(*v), exact)) <= RATE_TOL * max(
        float(np.linalg.norm(exact)), 0.01)


def test_an_unreachable_target_clears_the_state():
    leg = 0
    chain = ScalarLeg(_frames(leg))
    reachable = _target(leg, np.array([0.1, 0.3, 1.0]))
    assert _solve(chain, leg, reachable) is not None
    far = tuple(np.add(reachable, [0.0, 0.2, 0.0]))  # beyond the reach
    assert chain.warm(*far) is None and chain._state is None
    assert chain.rates_last(0.1, 0.0, 0.0) is None
    assert chain.cold(*far, _closed_form(leg, reachable), float(TRUE.knee_sign[leg])) is None
    assert chain.warm(*reachable) is None  # no state: the caller runs the cold start
    counted = _Counted(chain)
    assert _solve(chain, leg, reachable) is not None
    assert counted.calls >= 2


def test_a_prediction_beyond_the_warm_miss_is_refused():
    leg = 2
    chain = ScalarLeg(_frames(leg))
    target = _target(leg, np.array([0.1, 0.3, 1.0]))
    assert _solve(chain, leg, target) is not None
    counted = _Counted(chain)
    assert chain.warm(*np.add(target, [0.0, 0.0, 1.5 * WARM_START_MISS])) is not None
    assert counted.calls == 1
    assert chain.warm(*np.add(target, [0.0, 0.0, 0.02])) is None  # 2 cm: misses by more
    assert counted.calls == 2 and chain._state is None


def test_rates_reuse_the_last_jacobian_only_at_the_returned_angles():
    feet = NOMINAL.standing_feet().reshape(-1).tolist()
    kin = FastKinematics(TRUE)
    v = [0.05, -0.02, 0.01] * 4
    q, qd = kin.solve(feet, v)
    assert kin.velocities(q, v) == qd  # the same Jacobian, for the same angles
    _assert_rates(TRUE, q, np.array(v), qd)
    moved = [x + 0.01 for x in q]  # other angles: their own Jacobian, exactly
    reference = kinematics.joint_velocities(TRUE, np.reshape(moved, (4, 3)),
                                            np.reshape(v, (4, 3)))
    np.testing.assert_allclose(np.reshape(kin.velocities(moved, v), (4, 3)), reference,
                               atol=1e-12)
