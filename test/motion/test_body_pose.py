"""The standing body pose: limits, feet fixed in the world, the smooth move and its checks."""

from __future__ import annotations

import math
from dataclasses import fields, replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crawler_motion.errors import ConfigError, PoseError
from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.model.rotations import rpy_matrix
from crawler_motion.motion import body_pose
from crawler_motion.motion.body_pose import (
    MIN_POSE_TIME,
    NEUTRAL,
    POSE_FIELDS,
    POSE_SPEED_FRACTION,
    BodyPose,
    check_pose,
    foot_state_at,
    plan_pose_move,
    pose_move_duration,
    posed_feet,
    posed_foot_motion,
)
from crawler_motion.motion.gait import standing_pose
from crawler_motion.motion.trajectory import REST_PEAK_SPEED

CFG = load_config()
ROBOT = CFG.robot
HEIGHT = ROBOT.body_height  # 0.07 m
LIMITS = CFG.body_pose
#: Where the feet stand (base_link of the neutral pose) [m].
STANDING = ROBOT.standing_feet(HEIGHT)


def world_feet(q: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """The feet of joint angles ``q`` ``(k, n_legs, 3)`` in the neutral frame, the body at
    ``poses`` ``(k, 6)``: ``R p' + t`` of the forward kinematics."""
    feet = forward_kinematics(ROBOT, q)
    return np.einsum("kij,knj->kni", rpy_matrix(poses[:, 3:]), feet) + poses[:, None, :3]


def test_the_pose_fields_are_the_option_table_keys():
    assert tuple(f.name for f in fields(BodyPose)) == POSE_FIELDS == (
        "x", "y", "z", "roll", "pitch", "yaw")
    pose = BodyPose(0.01, -0.02, 0.005, 0.1, -0.05, 0.2)
    assert BodyPose.from_vector(pose.vector()) == pose
    assert pose.as_dict()["pitch"] == -0.05 and not pose.is_neutral and NEUTRAL.is_neutral
    assert pose.described() == ("x 0.01 m, y -0.02 m, z 0.005 m, roll 0.1 rad, "
                                "pitch -0.05 rad, yaw 0.2 rad")
    assert BodyPose(roll=0.1).described() == "roll 0.1 rad" and NEUTRAL.described() == "neutral"
    assert pose.rebased(0.07, 0.08).z == pytest.approx(0.005 - 0.01)


def test_the_neutral_pose_is_the_standing_pose():
    np.testing.assert_array_equal(posed_feet(STANDING, NEUTRAL.vector()), STANDING)
    np.testing.assert_allclose(check_pose(CFG, HEIGHT, NEUTRAL), standing_pose(CFG), atol=1e-15)


@pytest.mark.parametrize(("pose", "feet"), [
    (BodyPose(x=0.01), STANDING - [0.01, 0.0, 0.0]),  # body forward: feet back
    (BodyPose(z=0.01), STANDING - [0.0, 0.0, 0.01]),  # body up: feet lower
    (BodyPose(yaw=math.pi / 2), np.stack((STANDING[:, 1], -STANDING[:, 0], STANDING[:, 2]), 1)),
])
def test_feet_are_the_fixed_points_seen_from_the_moved_body(pose, feet):
    np.testing.assert_allclose(posed_feet(STANDING, pose.vector()), feet, atol=1e-15)


# ---------------------------------------------------------------- limits

EDGES = [("x", LIMITS.max_shift), ("y", LIMITS.max_shift), ("z", 0.02), ("roll", LIMITS.max_tilt),
         ("pitch", LIMITS.max_tilt), ("yaw", LIMITS.max_yaw)]


@pytest.mark.parametrize(("name", "edge"), EDGES)
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_every_field_is_accepted_at_its_edge_and_refused_just_beyond(name, edge, sign):
    """z: the standing height 0.07 m +- 0.02 m is the edge of body_height_range [0.05, 0.09]."""
    at_edge = BodyPose(**{name: sign * edge})
    path = plan_pose_move(CFG, HEIGHT, NEUTRAL, at_edge)
    q, _ = path.joints(path.duration)
    np.testing.assert_allclose(world_feet(q, path.pose(path.duration)[0]), [STANDING],
                               atol=1e-12)
    beyond = BodyPose(**{name: sign * (edge + 1e-4)})
    with pytest.raises(PoseError, match=f"^{name} = ") as err:
        plan_pose_move(CFG, HEIGHT, NEUTRAL, beyond)
    assert err.value.field == name


@pytest.mark.parametrize(("height", "z", "field"), [
    (0.09, 0.0, None),
    (0.09, 0.001, "z"),  # above body_height_range
    (0.05, -0.001, "z"),
    (0.05, 0.09 - 0.05, None),  # the whole range up
    (0.06, -0.01, None),
])
def test_the_posed_height_stays_within_the_body_height_range(height, z, field):
    if field is None:
        check_pose(CFG, height, BodyPose(z=z))
        return
    with pytest.raises(PoseError, match="outside body_height_range") as err:
        check_pose(CFG, height, BodyPose(z=z))
    assert err.value.field == field


@pytest.mark.parametrize(("pose", "match"), [
    (BodyPose(z=0.02, roll=-0.2, pitch=-0.2, yaw=-0.2), r"workspace: leg lf: foot target"),
    (BodyPose(y=0.03, z=0.02), r"workspace: leg rb: .* 0\.1581 m from the shoulder"),
    (BodyPose(x=-0.03, y=-0.03, roll=-0.2, pitch=0.1, yaw=-0.1),
     r"its limits: leg lf knee joint: 0\.0500 rad is outside"),
    (BodyPose(z=-0.02, roll=-0.2, pitch=-0.2, yaw=-0.2), r"its limits: leg lb shoulder joint"),
])
def test_a_pose_taking_a_foot_out_of_its_workspace_is_refused_with_the_leg(pose, match):
    with pytest.raises(PoseError, match=match) as err:
        plan_pose_move(CFG, HEIGHT, NEUTRAL, pose)
    assert err.value.field is None


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_a_pose_that_is_not_finite_is_refused(value):
    with pytest.raises(PoseError, match=r"^pitch = ") as err:
        check_pose(CFG, HEIGHT, BodyPose(pitch=value))
    assert err.value.field == "pitch"


def test_a_standing_height_outside_the_range_is_a_config_error():
    with pytest.raises(ConfigError, match=r"body height 0\.1 m"):
        check_pose(CFG, 0.1, NEUTRAL)


# ---------------------------------------------------------------- the move

#: Poses anywhere in the option ranges (many are refused: the corners leave the workspace).
POSES = st.builds(BodyPose, *(st.floats(-edge, edge) for _, edge in EDGES))
#: Smaller poses, mostly within reach.
SMALL = st.builds(BodyPose, *(st.floats(-edge / 2, edge / 2) for _, edge in EDGES))
PROPERTY = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


@PROPERTY
@given(POSES | SMALL, POSES | SMALL)
def test_every_sample_of_a_move_keeps_every_foot_fixed_in_the_world(start, end):
    """Accepted: FK of the joint targets moved by the body pose is the standing feet within
    1e-9 m at every sample. Refused: an end is out of reach, or a sample on the way is (the
    message says where: the pose-space path between two poses within reach may leave it)."""
    try:
        path = plan_pose_move(CFG, HEIGHT, start, end)
    except PoseError as exc:
        try:
            check_pose(CFG, HEIGHT, start)
            check_pose(CFG, HEIGHT, end)
        except PoseError:
            return  # an end is out of reach
        assert " of the way " in str(exc) or " at t = " in str(exc), exc
        return
    t = np.linspace(0.0, path.duration, 301)
    q, rates = path.joints(t)
    np.testing.assert_allclose(world_feet(q, path.pose(t)[0]),
                               np.broadcast_to(STANDING, q.shape), atol=1e-9)
    assert np.all(np.abs(rates) <= POSE_SPEED_FRACTION * ROBOT.velocity * (1 + 1e-6))
    np.testing.assert_allclose(path.pose(0.0)[0][0], start.vector(), atol=1e-15)
    np.testing.assert_allclose(path.pose(path.duration)[0][0], end.vector(), atol=1e-12)


@PROPERTY
@given(SMALL, st.lists(st.floats(-0.3, 0.3), min_size=6, max_size=6))
def test_the_one_instant_float_form_equals_the_numpy_form(pose, rate):
    feet, vel, _ = posed_foot_motion(STANDING, pose.vector(), np.array(rate), np.zeros(6))
    fast_feet, fast_vel = foot_state_at(STANDING.reshape(-1).tolist(), pose.vector().tolist(),
                                        rate)
    np.testing.assert_allclose(fast_feet, feet.reshape(-1), atol=1e-15)
    np.testing.assert_allclose(fast_vel, vel.reshape(-1), atol=1e-15)


def test_foot_velocity_and_acceleration_are_the_derivatives_of_the_position():
    path = plan_pose_move(CFG, HEIGHT, BodyPose(x=-0.01, pitch=0.1),
                          BodyPose(y=0.01, z=0.01, roll=0.1, yaw=-0.15))
    h = 1e-5
    t = np.linspace(h, path.duration - h, 50)
    _, vel, acc = path.feet(t)
    np.testing.assert_allclose((path.feet(t + h)[0] - path.feet(t - h)[0]) / (2 * h), vel,
                               atol=1e-8)
    np.testing.assert_allclose((path.feet(t + h)[1] - path.feet(t - h)[1]) / (2 * h), acc,
                               atol=1e-7)


def test_the_move_is_c2_and_at_rest_at_both_ends():
    """Joint angles: velocity and acceleration 0 at the ends (the standing body does not
    move before or after); the acceleration changes by at most O(dt) per sample (no jump)."""
    path = plan_pose_move(CFG, HEIGHT, NEUTRAL, BodyPose(x=0.02, roll=0.1, yaw=0.15))
    dt = 1e-3
    t = np.arange(-0.05, path.duration + 0.05, dt)
    q, _ = path.joints(t)
    _, vel, acc = path.feet(np.array([0.0, path.duration]))
    assert np.abs(vel).max() < 1e-12 and np.abs(acc).max() < 1e-12
    q_acc = np.diff(q, 2, axis=0) / dt**2  # [rad/s^2]
    jump = np.abs(np.diff(q_acc, axis=0)).max()
    assert jump < 50.0 * dt, jump  # a jerk below 50 rad/s^3: continuous acceleration
    assert np.abs(q_acc).max() > 0.1  # (the move does accelerate)


@pytest.mark.parametrize(("end", "expected"), [
    (BodyPose(x=0.001), MIN_POSE_TIME),  # tiny: the shortest move
    (BodyPose(x=0.03), REST_PEAK_SPEED * 0.03 / LIMITS.speed),  # the body's speed limit
    (BodyPose(y=-0.02, z=0.01), REST_PEAK_SPEED * math.hypot(0.02, 0.01) / LIMITS.speed),
    (BodyPose(yaw=0.2), REST_PEAK_SPEED * 0.2 / LIMITS.turn_rate),  # the turn rate limit
])
def test_the_duration_keeps_the_body_speed_and_turn_rate(end, expected):
    assert pose_move_duration(CFG, HEIGHT, NEUTRAL, end) == pytest.approx(expected)


def test_the_duration_keeps_every_joint_at_half_its_velocity_limit():
    slow = replace(CFG, robot=replace(ROBOT, velocity=np.full(3, 0.2)))
    end = BodyPose(x=0.02, roll=0.1)
    path = plan_pose_move(slow, HEIGHT, NEUTRAL, end)
    assert path.duration > pose_move_duration(CFG, HEIGHT, NEUTRAL, end)
    _, rates = path.joints(np.linspace(0.0, path.duration, 2001))
    peak = np.abs(rates).max()  # the duration samples 201 points: the peak within 0.1 %
    assert POSE_SPEED_FRACTION * 0.2 * 0.999 <= peak <= POSE_SPEED_FRACTION * 0.2 * 1.001


def test_the_duration_rule_samples_the_whole_way_and_says_where_it_fails():
    """(`plan_pose_move` checks the end first: there this pose is refused by `check_pose`.)"""
    with pytest.raises(PoseError, match=r"cannot keep every foot on the ground: leg lf: .* "
                                        r"66% of the way is 0\.1502 m from the shoulder"):
        pose_move_duration(CFG, HEIGHT, NEUTRAL, BodyPose(y=-0.03, z=0.02))


def test_every_sample_is_checked_with_the_walks_check(monkeypatch):
    """`gait.check_trajectories` samples the move: a move made too short for the joints'
    velocity limits is refused with its reason, naming the joint and the time."""
    monkeypatch.setattr(body_pose, "pose_move_duration", lambda *args: 0.01)
    with pytest.raises(PoseError, match=r"the pose move cannot be executed: \w+_joint would "
                                        r"turn at .* rad/s at t = .* above its velocity limit"):
        plan_pose_move(CFG, HEIGHT, NEUTRAL, BodyPose(x=0.02, roll=0.1))
    leg = plan_pose_move(CFG, HEIGHT, NEUTRAL, NEUTRAL).foot_paths()[2]
    pos, vel, acc = leg.evaluate(np.array([0.0, leg.t_end]))
    assert pos.shape == vel.shape == acc.shape == (2, 3) and leg.breaks[-1] == leg.t_end
    np.testing.assert_array_equal(pos, STANDING[[2, 2]])
