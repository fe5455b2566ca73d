"""Tests of crawler_motion.motion.fastpath: the float fast path equals the numpy path.

The reference is the public numpy API (`Piecewise.evaluate` / `WalkPlan.evaluate`,
`inverse_kinematics`, `joint_velocities`); the fast path must give the same numbers to 1e-12
over whole walks and raise the same errors (type and message) for the same inputs.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.errors import (
    CrawlerMotionError,
    JointLimitError,
    KinematicsError,
    TrajectoryError,
    UnreachableError,
)
from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    joint_velocities,
)
from crawler_motion.motion.continuous import continuous_step_cycle
from crawler_motion.motion.fastpath import FastKinematics, Track, joint_targets
from crawler_motion.motion.gait import GaitSequencer, WalkParams, plan_walk
from crawler_motion.motion.trajectory import Piecewise, Segment, SwingShape, rest_segment

CFG = load_config()
ROBOT = CFG.robot
KIN = FastKinematics(ROBOT)
TOL = 1e-12

WALKS = [
    {},
    {"gait": "wave", "profile": "rest"},
    {"heading": 1.5708, "stride": 0.04},
    {"heading": -2.5, "turn": 0.2, "stride": 0.03, "lift": 0.015, "arc": 0.02},
    {"turn": -0.3, "stride": 0.0},
    {"gait": "diagonal", "swing_time": 0.3, "stance_time": 0.9, "body_height": 0.08},
    {"gait": "diagonal_sway"},
]


def times_of(legs: tuple[Piecewise, ...], period: float = 0.002) -> np.ndarray:
    """A 500 Hz grid over the span, every breakpoint, and times before and after it."""
    t0, t1 = legs[0].t0, legs[0].t_end
    grid = np.arange(t0, t1, period)
    breaks = np.concatenate([leg.breaks for leg in legs])
    return np.concatenate((grid, breaks, [t0 - 0.5, t0 - 1e-9, t1, t1 + 1e-9, t1 + 0.5]))


def reference(plan_legs: tuple[Piecewise, ...], t: float) -> tuple[np.ndarray, ...]:
    pos = np.stack([leg.evaluate(t)[0][0] for leg in plan_legs])
    vel = np.stack([leg.evaluate(t)[1][0] for leg in plan_legs])
    q = inverse_kinematics(ROBOT, pos)
    return pos, vel, q, joint_velocities(ROBOT, q, vel)


def outcome(func, *args):
    """The result of ``func(*args)`` as an array, or the (type, message) of its error."""
    try:
        return np.asarray(func(*args), dtype=float).reshape(-1)
    except CrawlerMotionError as exc:
        return type(exc), str(exc)


def assert_same(fast, ref) -> None:
    if isinstance(ref, tuple) or isinstance(fast, tuple):
        assert fast == ref
    else:
        # relative too: near a singular pose a joint rate of ~5e3 rad/s differs in its last
        # bits (7.6e-10 absolute, 1.4e-13 relative, seen with feet at the joint limits)
        np.testing.assert_allclose(fast, ref, rtol=TOL, atol=TOL)


@pytest.mark.parametrize("overrides", WALKS, ids=lambda d: ",".join(d) or "defaults")
def test_whole_walk_equals_the_numpy_path(overrides):
    params = WalkParams.defaults(CFG.gait, **overrides)
    plan = plan_walk(CFG, params, 2)
    evaluator = Track(plan.legs)
    times = times_of(plan.legs)
    pos_ref, vel_ref, _ = plan.evaluate(times)
    q_ref = inverse_kinematics(ROBOT, pos_ref)
    qd_ref = joint_velocities(ROBOT, q_ref, vel_ref)
    for order in (np.arange(len(times)), np.random.default_rng(3).permutation(len(times))):
        # in time order (the active-segment cache) and shuffled
        got = np.array([np.concatenate((*evaluator.evaluate(times[i]),
                                        *joint_targets(evaluator, KIN, times[i])))
                        for i in order])
        want = np.concatenate([a[order].reshape(len(order), -1)
                               for a in (pos_ref, vel_ref, q_ref, qd_ref)], axis=1)
        np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


def test_slot_by_slot_as_the_planner_uses_it():
    seq = GaitSequencer(CFG, WalkParams.defaults(CFG.gait, turn=0.1))
    for _ in range(6):
        slot = seq.next_slot()
        assert slot is not None
        evaluator = Track(slot.legs)
        for t in times_of(slot.legs, 0.01):
            pos, _, q, qd = reference(slot.legs, t)
            got_q, got_qd = joint_targets(evaluator, KIN, t)
            np.testing.assert_allclose(evaluator.evaluate(t)[0], pos.reshape(-1), atol=TOL,
                                       rtol=0)
            np.testing.assert_allclose(got_q, q.reshape(-1), rtol=0, atol=TOL)
            np.testing.assert_allclose(got_qd, qd.reshape(-1), rtol=0, atol=TOL)


def test_continuous_stance_cycles_and_lower_degree_segments():
    g = CFG.gait
    shape = SwingShape(g.lift, g.arc, g.swing_time, g.profiles["smooth"])
    feet = ROBOT.standing_feet()
    legs = tuple(continuous_step_cycle(feet[i], [0.05, 0.01], shape, 0.7).shifted(0.1 * i)
                 for i in range(4))
    line = Segment(np.array([[0.0, 1.0], [2.0, -1.0], [0.5, 0.25]]), 0.4, "linear")
    legs = (*legs[:3], Piecewise([line, line]))  # degree 1, a different span
    evaluator = Track(legs)
    for t in times_of(legs, 0.003):
        pos, vel = evaluator.evaluate(t)
        for i, leg in enumerate(legs):
            p_ref, v_ref, _ = leg.evaluate(t)
            np.testing.assert_allclose(pos[3 * i:3 * i + 3], p_ref[0], rtol=0, atol=TOL)
            np.testing.assert_allclose(vel[3 * i:3 * i + 3], v_ref[0], rtol=0, atol=TOL)


def test_evaluator_refuses_what_it_cannot_evaluate():
    with pytest.raises(TrajectoryError):
        Track([])
    two_d = Piecewise([Segment(np.zeros((2, 7)), 1.0)])
    with pytest.raises(TrajectoryError, match="3-D"):
        Track([two_d])
    octic = Piecewise([Segment(np.zeros((3, 9)), 1.0)])
    with pytest.raises(TrajectoryError, match="degree"):
        Track([octic])


# --- errors: identical to the numpy path ------------------------------------------------------

def numpy_targets(feet: np.ndarray, vel: np.ndarray) -> np.ndarray:
    q = inverse_kinematics(ROBOT, feet)
    return np.concatenate((q.reshape(-1), joint_velocities(ROBOT, q, vel).reshape(-1)))


def fast_targets(feet: np.ndarray, vel: np.ndarray) -> np.ndarray:
    q, qd = KIN.solve(feet.reshape(-1).tolist(), vel.reshape(-1).tolist())
    return np.array(q + qd)


def check_feet(feet: np.ndarray, vel: np.ndarray) -> None:
    flat = feet.reshape(-1).tolist()
    for check in (True, False):
        assert_same(outcome(KIN.inverse, flat, check),
                    outcome(inverse_kinematics, ROBOT, feet, check))
    assert_same(outcome(fast_targets, feet, vel), outcome(numpy_targets, feet, vel))


offsets = st.sampled_from([0.0, 1e-10, -1e-10, 5e-10, -5e-10, 2e-9, -2e-9, 1e-3, -1e-3])


@st.composite
def poses_near_limits(draw):
    """FK of joint angles at, just inside, just outside and beyond the limits."""
    q = np.empty((4, 3))
    for leg in range(4):
        for k in range(3):
            lo, hi = ROBOT.lower[k], ROBOT.upper[k]
            kind = draw(st.sampled_from(["lo", "hi", "in"]))
            if kind == "in":
                q[leg, k] = draw(st.floats(lo, hi))
            else:
                q[leg, k] = (lo if kind == "lo" else hi) + draw(offsets)
    return forward_kinematics(ROBOT, q)


coords = st.floats(-0.35, 0.35, allow_nan=False)
velocities = st.lists(st.floats(-1.0, 1.0), min_size=12, max_size=12).map(
    lambda v: np.array(v).reshape(4, 3))


@settings(max_examples=150, deadline=None)
@given(feet=poses_near_limits(), vel=velocities)
def test_limit_errors_and_snapping_match_numpy(feet, vel):
    check_feet(feet, vel)


@settings(max_examples=150, deadline=None)
@given(feet=st.lists(coords, min_size=12, max_size=12), vel=velocities)
def test_workspace_errors_match_numpy(feet, vel):
    arr = ROBOT.standing_feet() + 0.5 * np.array(feet).reshape(4, 3)
    check_feet(arr, vel)


@pytest.mark.parametrize("where", ["far", "near", "axis", "nan", "inf"])
def test_specific_bad_targets_raise_the_numpy_error(where):
    feet = ROBOT.standing_feet()
    if where == "far":
        feet[2, 0] += 1.0
    elif where == "near":
        feet[1] = ROBOT.hips[1] + np.array([0.0, 0.031, 0.0])
    elif where == "axis":
        feet[3, :2] = ROBOT.hips[3, :2]
    else:
        feet[0, 1] = math.nan if where == "nan" else math.inf
    ref = outcome(inverse_kinematics, ROBOT, feet)
    assert isinstance(ref, tuple) and issubclass(ref[0], (UnreachableError, KinematicsError))
    assert outcome(KIN.inverse, feet.reshape(-1).tolist()) == ref
    assert outcome(fast_targets, feet, np.zeros((4, 3))) == ref


def test_joint_limit_error_message_is_the_numpy_one():
    q = inverse_kinematics(ROBOT, ROBOT.standing_feet())
    q[2, 0] = ROBOT.upper[0] + 0.05
    feet = forward_kinematics(ROBOT, q)
    ref = outcome(inverse_kinematics, ROBOT, feet)
    assert ref[0] is JointLimitError
    assert outcome(KIN.inverse, feet.reshape(-1).tolist()) == ref


@pytest.mark.parametrize("pose", ["knee straight", "foot on root axis"])
def test_singular_jacobian_raises_the_numpy_error(pose):
    q = inverse_kinematics(ROBOT, ROBOT.standing_feet())
    if pose == "knee straight":
        q[1, 2] = 0.0
    else:  # l1 + l2 cos(s) + l3 cos(s - k) = 0 with s = -pi/2: cos(-pi/2 - k) = -l1 / l3
        q[1, 1] = -math.pi / 2
        q[1, 2] = math.acos(-ROBOT.l1 / ROBOT.l3) - math.pi / 2
    vel = np.full((4, 3), 0.01)
    ref = outcome(joint_velocities, ROBOT, q, vel)
    assert isinstance(ref, tuple) and ref[0] is KinematicsError
    assert outcome(KIN.velocities, q.reshape(-1).tolist(), vel.reshape(-1).tolist()) == ref


def test_flat_vectors_of_the_wrong_length_are_refused():
    with pytest.raises(KinematicsError, match="shaped"):
        KIN.inverse([0.0] * 9)
    with pytest.raises(KinematicsError, match="12 values"):
        KIN.velocities([0.0] * 12, [0.0] * 3)
    with pytest.raises(KinematicsError, match="shaped"):
        KIN.solve([0.0] * 9, [0.0] * 9)


@pytest.mark.parametrize("side", ["lower", "upper"])
def test_angles_within_rounding_of_a_limit_are_set_onto_it_as_numpy_does(side):
    q = inverse_kinematics(ROBOT, ROBOT.standing_feet())
    for leg, joint in ((0, 0), (1, 1), (2, 2)):
        limit = (ROBOT.lower if side == "lower" else ROBOT.upper)[joint]
        q[leg, joint] = limit + (-5e-10 if side == "lower" else 5e-10)
    try:
        feet = forward_kinematics(ROBOT, q)
        ref = inverse_kinematics(ROBOT, feet)
    except KinematicsError:
        pytest.skip("this pose is not reachable with the configured geometry")
    fast = np.array(KIN.inverse(feet.reshape(-1).tolist())).reshape(4, 3)
    np.testing.assert_array_equal(fast, ref)
    for leg, joint in ((0, 0), (1, 1), (2, 2)):
        limit = (ROBOT.lower if side == "lower" else ROBOT.upper)[joint]
        assert fast[leg, joint] == limit
    vel = np.full((4, 3), 0.02)
    np.testing.assert_allclose(fast_targets(feet, vel), numpy_targets(feet, vel), rtol=0,
                               atol=TOL)


def test_a_joint_space_track_equals_its_piecewise():
    """The stand / sit move: one 12-D rest sextic, clamped before and after its span."""
    start = inverse_kinematics(ROBOT, ROBOT.standing_feet()).reshape(-1)
    move = Piecewise([rest_segment(start, start + 0.1, 1.3, "stand")])
    track = Track([move], dims=12)
    assert (track.t0, track.t_end, track.duration) == (0.0, 1.3, 1.3)
    for t in (-0.1, 0.0, 0.4, 0.65, 1.3, 1.5):
        pos, vel = track.evaluate(t)
        p_ref, v_ref, _ = move.evaluate(min(max(t, 0.0), 1.3))
        np.testing.assert_allclose(pos, p_ref[0], rtol=0, atol=TOL)
        np.testing.assert_allclose(vel, v_ref[0], rtol=0, atol=TOL)
    with pytest.raises(TrajectoryError, match="3-D"):
        Track([move])
