"""Closed-form leg kinematics: workspace and limit boundaries, errors, batches and properties."""

from __future__ import annotations

import copy
import itertools
import math
import re

import numpy as np
import pytest
import yaml
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from crawler_motion.errors import JointLimitError, KinematicsError, UnreachableError
from crawler_motion.model.config import (
    JOINT_KINDS,
    RobotConfig,
    config_path,
    load_config,
    parse_robot,
)
from crawler_motion.model.kinematics import (
    check_limits,
    forward_kinematics,
    inverse_kinematics,
    joint_velocities,
)

ROBOT = load_config().robot
RAW = yaml.safe_load(config_path("robot.yaml").read_text(encoding="utf-8"))["robot"]


def make_robot(**changes: object) -> RobotConfig:
    """The shipped robot section with ``changes`` ('links.l1': 0.1, ...) applied."""
    data = copy.deepcopy(RAW)
    for dotted, value in changes.items():
        *parents, key = dotted.split(".")
        node = data
        for part in parents:
            node = node[part]
        node[key] = value
    return parse_robot(data)


#: Every joint free over (-pi, pi] except the knee, kept off straight/folded; long coxa so that
#: the foot can sit behind and above the shoulder (exercises the shoulder angle's wrap-around).
WIDE = make_robot(**{
    "links.l1": 0.1,
    "limits.root.lower": -math.pi, "limits.root.upper": math.pi,
    "limits.shoulder.lower": -math.pi, "limits.shoulder.upper": math.pi,
    "limits.knee.lower": 0.05, "limits.knee.upper": 3.0,
})
#: Limits that include the straight (0) and fully folded (pi) knee, i.e. the workspace boundary
#: (folded, the femur points away from the foot: the shoulder needs the full circle too).
FULL_KNEE = make_robot(**{"limits.knee.lower": 0.0, "limits.knee.upper": math.pi,
                          "limits.shoulder.lower": -math.pi, "limits.shoulder.upper": math.pi})
#: Two legs knee-down (the knee limits must then allow negative angles, and the femur of a
#: knee-down leg hangs lower).
MIXED = make_robot(**{"knee.lb": "down", "knee.rf": "down",
                      "limits.knee.lower": -2.6, "limits.knee.upper": 2.6,
                      "limits.shoulder.lower": -1.6})


def leg_point(robot: RobotConfig, leg: int, u: float, w: float, root: float = 0.0) -> np.ndarray:
    """Point at (u outwards from the shoulder, w up) in the plane of ``leg`` turned by ``root``."""
    yaw = robot.neutral_yaw[leg] + root
    r = robot.l1 + u
    return robot.hips[leg] + np.array([r * math.cos(yaw), r * math.sin(yaw), w])


def radial(robot: RobotConfig, angles: np.ndarray) -> np.ndarray:
    """Signed horizontal distance of each foot from its root axis, from the angles alone."""
    shoulder, knee = angles[..., 1], angles[..., 2]
    return robot.l1 + robot.l2 * np.cos(shoulder) + robot.l3 * np.cos(shoulder - knee)


def wrapped(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * np.asarray(a)))


# ---------------------------------------------------------------- workspace boundary (table)

D_MAX = ROBOT.l2 + ROBOT.l3
D_MIN = abs(ROBOT.l2 - ROBOT.l3)
REACH_ROWS = [
    # (id, leg, distance from the shoulder, elevation of shoulder->foot [rad], reachable)
    ("max reach, horizontal", 0, D_MAX, 0.0, True),
    ("max reach, 0.5 rad down", 1, D_MAX, -0.5, True),
    ("max reach, 0.3 rad up", 2, D_MAX, 0.3, True),
    ("min reach, horizontal", 3, D_MIN, 0.0, True),
    ("min reach, straight down", 0, D_MIN, -math.pi / 2, True),
    ("just beyond max reach", 1, D_MAX * (1 + 1e-9), 0.0, False),
    ("just beyond max reach, down", 2, D_MAX * (1 + 1e-9), -0.7, False),
    ("just inside min reach", 3, D_MIN * (1 - 1e-9), 0.0, False),
    ("just inside min reach, down", 0, D_MIN * (1 - 1e-9), -math.pi / 2, False),
    ("far away", 1, 1.0, -0.1, False),
]


@pytest.mark.parametrize(("leg", "dist", "elev", "ok"), [r[1:] for r in REACH_ROWS],
                         ids=[r[0] for r in REACH_ROWS])
def test_reach_boundary(leg, dist, elev, ok):
    feet = FULL_KNEE.standing_feet()
    feet[leg] = leg_point(FULL_KNEE, leg, dist * math.cos(elev), dist * math.sin(elev))
    if ok:
        q = inverse_kinematics(FULL_KNEE, feet)
        assert np.all(np.isfinite(q))
        np.testing.assert_allclose(forward_kinematics(FULL_KNEE, q), feet, rtol=0, atol=1e-12)
        expected_knee = 0.0 if dist == D_MAX else math.pi
        assert q[leg, 2] == pytest.approx(expected_knee, abs=1e-6)
    else:
        with pytest.raises(UnreachableError) as err:
            inverse_kinematics(FULL_KNEE, feet)
        message = str(err.value)
        assert f"leg {FULL_KNEE.legs[leg]}:" in message
        assert f"[{D_MIN:.4f}, {D_MAX:.4f}]" in message  # the reachable band
        for other in FULL_KNEE.legs:
            if other != FULL_KNEE.legs[leg]:
                assert f"leg {other}" not in message
        with pytest.raises(UnreachableError):  # also without the limit check
            inverse_kinematics(FULL_KNEE, feet, check=False)


@pytest.mark.parametrize("knee", [0.0, math.pi], ids=["straight", "folded"])
def test_fk_of_boundary_poses_is_reachable_despite_rounding(knee):
    """Feet placed by the FK with the knee straight or folded lie on the workspace boundary;
    rounding may put them a few 1e-17 m outside it, which must not make them unreachable."""
    grid = itertools.product(np.linspace(-0.9, 0.9, 7), np.linspace(-1.0, 1.4, 25))
    q = np.array([[[root, shoulder, knee]] * 4 for root, shoulder in grid])
    if knee:  # folded: the foot must stay off the root axis, on the leg's side
        q = q[radial(FULL_KNEE, q[:, 0]) > 1e-3]
    feet = forward_kinematics(FULL_KNEE, q)
    back = inverse_kinematics(FULL_KNEE, feet)
    np.testing.assert_allclose(forward_kinematics(FULL_KNEE, back), feet, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back[..., 2], knee, atol=1e-6)


@pytest.mark.parametrize("leg", range(4))
def test_target_on_root_axis_is_unreachable(leg):
    feet = ROBOT.standing_feet()
    feet[leg, :2] = ROBOT.hips[leg, :2]
    feet[leg, 2] = -0.05  # 0.0583 m from the shoulder: inside the band, but r = 0
    with pytest.raises(UnreachableError, match=f"leg {ROBOT.legs[leg]}:"):
        inverse_kinematics(ROBOT, feet)


# ---------------------------------------------------------------- joint limits (table)

def _corners() -> list[tuple[float, float, float]]:
    return [tuple(c) for c in itertools.product(*zip(ROBOT.lower, ROBOT.upper, strict=True))]


@pytest.mark.parametrize("corner", _corners(), ids=lambda c: "/".join(f"{v:+.1f}" for v in c))
def test_angles_exactly_at_limits_are_accepted(corner):
    q = np.tile(corner, (4, 1))
    check_limits(ROBOT, q)  # no error
    if np.all(radial(ROBOT, q) > 1e-3):
        # The IK of a pose at its limits is that pose, exactly on the limits (rounding is not a
        # violation). Corners with the foot behind the root axis (r < 0) are not IK solutions.
        back = inverse_kinematics(ROBOT, forward_kinematics(ROBOT, q))
        np.testing.assert_allclose(back, q, rtol=0, atol=1e-9)
        assert np.all(back >= ROBOT.lower) and np.all(back <= ROBOT.upper)


def test_corners_with_foot_behind_root_axis_are_few():
    """Guards the filter above: only the fully folded-back leg (femur down, knee at its upper
    limit) puts the foot behind the root axis, outside the IK's r > 0 branch."""
    behind = [c for c in _corners() if radial(ROBOT, np.array(c)) <= 1e-3]
    assert len(behind) <= 2
    assert all(c[1] == ROBOT.lower[1] and c[2] == ROBOT.upper[2] for c in behind)


LIMIT_ROWS = [(leg, joint, side) for leg in range(4) for joint in range(3)
              for side in ("lower", "upper")]


@pytest.mark.parametrize(("leg", "joint", "side"), LIMIT_ROWS,
                         ids=[f"{ROBOT.legs[lg]}-{JOINT_KINDS[j]}-{s}" for lg, j, s in LIMIT_ROWS])
def test_one_micro_radian_beyond_a_limit_is_an_error(leg, joint, side):
    q = inverse_kinematics(ROBOT, ROBOT.standing_feet())
    limit = (ROBOT.lower if side == "lower" else ROBOT.upper)[joint]
    q[leg, joint] = limit - 1e-6 if side == "lower" else limit + 1e-6
    with pytest.raises(JointLimitError) as err:
        check_limits(ROBOT, q)
    message = str(err.value)
    assert f"leg {ROBOT.legs[leg]} {JOINT_KINDS[joint]} joint" in message
    assert f"[{ROBOT.lower[joint]:.4f}, {ROBOT.upper[joint]:.4f}]" in message
    assert f"{q[leg, joint]:.4f} rad" in message
    assert f"1e-06 rad {'below' if side == 'lower' else 'above'}" in message
    # The same pose as a foot target: the IK refuses it too, naming the same leg and joint.
    if radial(ROBOT, q[leg]) > 1e-3:
        with pytest.raises(JointLimitError, match=f"leg {ROBOT.legs[leg]} {JOINT_KINDS[joint]}"):
            inverse_kinematics(ROBOT, forward_kinematics(ROBOT, q))
        # ...and without the check it returns the pose, unclipped.
        np.testing.assert_allclose(
            inverse_kinematics(ROBOT, forward_kinematics(ROBOT, q), check=False), q, atol=1e-9)


def test_nan_angles_fail_the_limit_check():
    q = np.zeros((4, 3))
    q[2, 1] = np.nan
    with pytest.raises(JointLimitError, match="NaN"):
        check_limits(ROBOT, q)


# ---------------------------------------------------------------- malformed input (table)

@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("func", [inverse_kinematics, forward_kinematics])
def test_non_finite_input_raises(func, bad):
    x = ROBOT.standing_feet() if func is inverse_kinematics else np.full((4, 3), 0.5)
    x[1, 2] = bad
    with pytest.raises(KinematicsError, match="NaN or inf"):
        func(ROBOT, x)


@pytest.mark.parametrize("shape", [(), (3,), (4,), (12,), (3, 3), (4, 2), (5, 3), (4, 3, 1),
                                   (2, 3, 4), (0, 3)])
@pytest.mark.parametrize("func", [inverse_kinematics, forward_kinematics])
def test_wrong_shape_raises(func, shape):
    with pytest.raises(KinematicsError, match=re.escape(f"got {shape}")):
        func(ROBOT, np.full(shape, 0.1))


# ---------------------------------------------------------------- batches

@pytest.mark.parametrize("batch", [(1,), (7,), (2, 5), (3, 1, 2)])
def test_batches_equal_samplewise_results(batch):
    rng = np.random.default_rng(len(batch))
    feet = ROBOT.standing_feet() + rng.uniform(-0.02, 0.02, size=(*batch, 4, 3))
    q = inverse_kinematics(ROBOT, feet)
    assert q.shape == (*batch, 4, 3)
    for idx in np.ndindex(*batch):
        np.testing.assert_array_equal(q[idx], inverse_kinematics(ROBOT, feet[idx]))
    np.testing.assert_allclose(forward_kinematics(ROBOT, q), feet, rtol=0, atol=1e-12)
    rates = joint_velocities(ROBOT, q, np.ones_like(feet))
    assert rates.shape == (*batch, 4, 3)


def test_unreachable_error_names_the_sample():
    feet = np.broadcast_to(ROBOT.standing_feet(), (6, 4, 3)).copy()
    feet[4, 2, 0] += 1.0  # sample 4, leg rb
    with pytest.raises(UnreachableError) as err:
        inverse_kinematics(ROBOT, feet)
    assert "leg rb" in str(err.value) and "at sample (4,)" in str(err.value)
    assert err.value.sample == (4,)


def test_limit_error_names_the_sample_in_a_2d_batch():
    q = np.broadcast_to(inverse_kinematics(ROBOT, ROBOT.standing_feet()), (3, 4, 4, 3)).copy()
    q[1, 2, 3, 0] = 0.95  # sample (1, 2), leg rf, root
    with pytest.raises(JointLimitError) as err:
        check_limits(ROBOT, q)
    assert "leg rf root joint" in str(err.value) and "at sample (1, 2)" in str(err.value)
    assert err.value.sample == (1, 2)
    with pytest.raises(JointLimitError, match=re.escape("leg rf root joint")) as err:
        inverse_kinematics(ROBOT, forward_kinematics(ROBOT, q))
    assert "at sample (1, 2)" in str(err.value)
    assert err.value.sample == (1, 2)


FAR = np.array([1.0, 0.0, 0.0])  # [m] added to every foot: out of reach


@pytest.mark.parametrize("error, make", [
    (UnreachableError, lambda: inverse_kinematics(ROBOT, ROBOT.standing_feet() + FAR)),
    (JointLimitError, lambda: check_limits(ROBOT, np.full((4, 3), 3.0))),
    (JointLimitError, lambda: check_limits(ROBOT, np.full((4, 3), np.nan))),
])
def test_an_unbatched_error_has_no_sample(error, make):
    with pytest.raises(error) as err:
        make()
    assert err.value.sample is None and "at sample" not in str(err.value)


# ---------------------------------------------------------------- known poses

def test_standing_pose():
    q = inverse_kinematics(ROBOT, ROBOT.standing_feet())
    np.testing.assert_allclose(q[:, 0], 0.0, atol=1e-15)  # legs along their neutral yaw
    # knee from the law of cosines, shoulder from the two atan2 terms (spec §2)
    u, w, l2, l3 = ROBOT.reach - ROBOT.l1, -ROBOT.body_height, ROBOT.l2, ROBOT.l3
    knee = math.acos((u**2 + w**2 - l2**2 - l3**2) / (2 * l2 * l3))
    shoulder = math.atan2(w, u) + math.atan2(l3 * math.sin(knee), l2 + l3 * math.cos(knee))
    np.testing.assert_allclose(q[:, 1], shoulder, atol=1e-12)
    np.testing.assert_allclose(q[:, 2], knee, atol=1e-12)


def test_zero_pose_is_leg_stretched_along_neutral_yaw():
    feet = forward_kinematics(ROBOT, np.zeros((4, 3)))
    span = ROBOT.l1 + ROBOT.l2 + ROBOT.l3
    expected = ROBOT.hips + span * np.stack(
        [np.cos(ROBOT.neutral_yaw), np.sin(ROBOT.neutral_yaw), np.zeros(4)], axis=-1)
    np.testing.assert_allclose(feet, expected, atol=1e-15)
    # left legs point +y, right legs -y
    assert feet[0, 1] > ROBOT.hips[0, 1] and feet[2, 1] < ROBOT.hips[2, 1]


@pytest.mark.parametrize(("joint", "check"), [
    (0, lambda d, y: np.cross([math.cos(y), math.sin(y), 0.0], d)[2] > 0),  # CCW from above
    (1, lambda d, y: d[2] > 0),  # shoulder + raises
    (2, lambda d, y: d[2] < 0),  # knee + lowers the foot
])
def test_joint_signs(joint, check):
    q = np.zeros((4, 3))
    q[:, 2] = 0.5
    dq = np.zeros((4, 3))
    dq[:, joint] = 1e-4
    delta = forward_kinematics(ROBOT, q + dq) - forward_kinematics(ROBOT, q)
    for leg in range(4):
        assert check(delta[leg], ROBOT.neutral_yaw[leg]), ROBOT.legs[leg]


def test_shoulder_angle_wraps_into_limits():
    """Foot behind and above the shoulder: the atan2 sum passes -pi; IK must give s, not s+2pi."""
    q = np.tile([0.2, -2.5, 2.0], (4, 1))
    assert np.all(radial(WIDE, q) > 0)
    back = inverse_kinematics(WIDE, forward_kinematics(WIDE, q))
    np.testing.assert_allclose(back, q, atol=1e-12)


def test_jacobian_singularities_raise():
    knee_straight = np.tile([0.0, 0.3, 0.0], (4, 1))
    with pytest.raises(KinematicsError, match="knee straight"):
        joint_velocities(ROBOT, knee_straight, np.ones((4, 3)))
    # foot right under the hip, within the limits: r = 0 (root rate undefined)
    s = -1.0
    k = s + math.acos(-(ROBOT.l1 + ROBOT.l2 * math.cos(s)) / ROBOT.l3)
    under_hip = np.tile([0.0, s, k], (4, 1))
    check_limits(ROBOT, under_hip)
    feet = forward_kinematics(ROBOT, under_hip)
    np.testing.assert_allclose(feet[:, :2], ROBOT.hips[:, :2], atol=1e-15)
    with pytest.raises(KinematicsError, match="root axis"):
        joint_velocities(ROBOT, under_hip, np.ones((4, 3)))


# ---------------------------------------------------------------- knee configuration

def knee_side(robot: RobotConfig, q: np.ndarray, feet: np.ndarray) -> np.ndarray:
    """Per leg: > 0 if the knee lies above the shoulder->foot line in the leg plane, < 0 below.

    The knee point is rebuilt from the root and shoulder angles only and checked to be l2 from
    the shoulder and l3 from the (given) foot, so it is the leg's real knee.
    """
    yaw = robot.neutral_yaw + q[:, 0]
    out = np.stack([np.cos(yaw), np.sin(yaw), np.zeros(4)], axis=-1)
    shoulder = robot.hips + robot.l1 * out
    up = np.array([0.0, 0.0, 1.0])
    knee = shoulder + robot.l2 * (np.cos(q[:, 1])[:, None] * out + np.sin(q[:, 1])[:, None] * up)
    np.testing.assert_allclose(np.linalg.norm(knee - shoulder, axis=-1), robot.l2, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(feet - knee, axis=-1), robot.l3, atol=1e-12)
    to_foot, to_knee = feet - shoulder, knee - shoulder
    # 2-D cross product in the (outwards, up) plane
    return (np.sum(to_foot * out, axis=-1) * to_knee[:, 2]
            - to_foot[:, 2] * np.sum(to_knee * out, axis=-1))


def test_standing_knee_up_is_the_highest_point_of_the_leg():
    feet = ROBOT.standing_feet()
    q = inverse_kinematics(ROBOT, feet)
    assert np.all(q[:, 2] > 0)
    assert np.all(knee_side(ROBOT, q, feet) > 0)
    knee_height = ROBOT.hips[:, 2] + ROBOT.l2 * np.sin(q[:, 1])
    assert np.all(knee_height > ROBOT.hips[:, 2]) and np.all(knee_height > feet[:, 2])


def test_knee_down_legs_mirror_knee_up_legs():
    feet = MIXED.standing_feet()
    q = inverse_kinematics(MIXED, feet)
    np.testing.assert_array_equal(np.sign(q[:, 2]), MIXED.knee_sign)
    np.testing.assert_array_equal(np.sign(knee_side(MIXED, q, feet)), MIXED.knee_sign)
    np.testing.assert_allclose(forward_kinematics(MIXED, q), feet, atol=1e-12)
    # mirror images about the shoulder->foot line: same |knee|, shoulders symmetric about it
    line = math.atan2(-MIXED.body_height, MIXED.reach - MIXED.l1)
    np.testing.assert_allclose(np.abs(q[:, 2]), abs(q[0, 2]), atol=1e-12)
    np.testing.assert_allclose(np.abs(q[:, 1] - line), abs(q[0, 1] - line), atol=1e-12)


# ---------------------------------------------------------------- properties

def in_limit_angles(robot: RobotConfig, min_knee: float = 1e-2, min_r: float = 1e-3):
    """(4, 3) angles inside the limits, knee bent by >= min_knee, foot r >= min_r off the axis."""
    columns = [st.floats(float(lo), float(hi)) for lo, hi in zip(robot.lower, robot.upper,
                                                                  strict=True)]
    legs = st.tuples(*columns).filter(
        lambda a: abs(math.sin(a[2])) >= min_knee
        and robot.l1 + robot.l2 * math.cos(a[1]) + robot.l3 * math.cos(a[1] - a[2]) >= min_r)
    return st.lists(legs, min_size=4, max_size=4).map(np.array)


@pytest.mark.parametrize("robot", [ROBOT, WIDE], ids=["shipped", "wide"])
@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_fk_of_ik_is_identity(robot, data):
    feet = forward_kinematics(robot, data.draw(in_limit_angles(robot)))
    q = inverse_kinematics(robot, feet)
    np.testing.assert_allclose(forward_kinematics(robot, q), feet, rtol=0, atol=1e-9)


@pytest.mark.parametrize("robot", [ROBOT, WIDE], ids=["shipped", "wide"])
@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_ik_of_fk_is_identity(robot, data):
    q = data.draw(in_limit_angles(robot))
    back = inverse_kinematics(robot, forward_kinematics(robot, q))
    # the root may come back as +pi for -pi (same angle); everything else exactly
    np.testing.assert_allclose(wrapped(back - q), 0.0, atol=1e-9)
    assert np.all(back >= robot.lower) and np.all(back <= robot.upper)


def fk_rate(q: np.ndarray, qdot: np.ndarray, h: float) -> np.ndarray:
    """Foot velocity for joint rates ``qdot``: central difference of the FK with step h [s]."""
    ahead = forward_kinematics(ROBOT, q + h * qdot)
    behind = forward_kinematics(ROBOT, q - h * qdot)
    return (ahead - behind) / (2 * h)


@settings(max_examples=150, deadline=None)
@given(q=in_limit_angles(ROBOT, min_knee=0.05, min_r=0.01),
       qdot=hnp.arrays(float, (4, 3), elements=st.floats(-2.0, 2.0)))
def test_joint_velocities_match_finite_differences(q, qdot):
    v = fk_rate(q, qdot, 1e-6)
    np.testing.assert_allclose(joint_velocities(ROBOT, q, v), qdot, rtol=0, atol=1e-5)


@settings(max_examples=100, deadline=None)
@given(q=in_limit_angles(ROBOT, min_knee=0.05, min_r=0.01),
       v=hnp.arrays(float, (4, 3), elements=st.floats(-0.5, 0.5)))
def test_finite_differences_along_joint_velocities_give_the_foot_velocity(q, v):
    qdot = joint_velocities(ROBOT, q, v)
    fd = fk_rate(q, qdot, 1e-7)
    np.testing.assert_allclose(fd, v, rtol=0, atol=1e-6 * (1 + np.abs(qdot).max()))


any_float = st.floats(allow_nan=False, allow_infinity=False)
near_float = st.floats(-0.3, 0.3)


@pytest.mark.parametrize("robot", [ROBOT, MIXED, WIDE], ids=["shipped", "mixed", "wide"])
@settings(max_examples=200, deadline=None)
@given(feet=hnp.arrays(float, (4, 3), elements=st.one_of(near_float, any_float)),
       check=st.booleans())
def test_ik_never_returns_nan(robot, feet, check):
    try:
        # overflow of huge targets is expected (they are unreachable); an invalid operation
        # (the source of a NaN) is a failure
        with np.errstate(over="ignore", invalid="raise"):
            q = inverse_kinematics(robot, feet, check=check)
    except KinematicsError:
        return
    assert np.all(np.isfinite(q))
    assert np.all(np.abs(q) <= math.pi)
    np.testing.assert_allclose(forward_kinematics(robot, q), feet, rtol=0, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(u=st.floats(-0.1, 0.2), w=st.floats(-0.2, 0.2), root=st.floats(-0.8, 0.8))
def test_ik_knee_follows_knee_sign(u, w, root):
    d = math.hypot(u, w)
    assume(D_MIN + 1e-6 < d < D_MAX - 1e-6 and ROBOT.l1 + u > 1e-3)
    feet = np.stack([leg_point(MIXED, leg, u, w, root) for leg in range(4)])
    q = inverse_kinematics(MIXED, feet, check=False)
    np.testing.assert_array_equal(np.sign(q[:, 2]), MIXED.knee_sign)
    np.testing.assert_array_equal(np.sign(knee_side(MIXED, q, feet)), MIXED.knee_sign)
    np.testing.assert_allclose(q[:, 0], root, atol=1e-12)
