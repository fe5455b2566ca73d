"""Tests of crawler_motion.motion.contact: the foot's roll and the centre targets."""

import math
import re

import numpy as np
import pytest

from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import inverse_kinematics
from crawler_motion.model.urdf import foot_sphere_radius, generate_urdf
from crawler_motion.motion.contact import rolled_centres
from crawler_motion.motion.gait import WalkParams, plan_walk

CFG = load_config()
ROBOT = CFG.robot
RADIUS = foot_sphere_radius(ROBOT)


def elevation(centres: np.ndarray) -> np.ndarray:
    q = inverse_kinematics(ROBOT, centres)
    return q[:, 1] - q[:, 2]


def test_foot_radius_is_the_urdf_sphere():
    urdf = generate_urdf(ROBOT)
    radii = {float(r) for r in re.findall(r'<sphere radius="([0-9.e-]+)"', urdf)}
    assert len(radii) == 1 and radii.pop() == pytest.approx(RADIUS, rel=1e-5)
    assert RADIUS == pytest.approx(1.2 * 0.04 * 0.18)


@pytest.mark.parametrize("shift", [(0.0, 0.0), (0.03, 0.0), (0.0, 0.03), (0.0, -0.03),
                                   (-0.02, 0.025)])
def test_rolled_centre_satisfies_the_rolling_equation(shift):
    touch = ROBOT.standing_feet()
    contacts = touch.copy()
    contacts[:, :2] += shift
    centres = rolled_centres(ROBOT, contacts, touch)
    q = inverse_kinematics(ROBOT, centres)
    yaw = ROBOT.neutral_yaw + q[:, 0]
    u = np.stack((np.cos(yaw), np.sin(yaw)), axis=-1)
    expected = contacts[:, :2] - RADIUS * (
        elevation(centres) - elevation(touch))[:, None] * u
    np.testing.assert_allclose(centres[:, :2], expected, rtol=0, atol=1e-7)
    np.testing.assert_array_equal(centres[:, 2], contacts[:, 2])
    if shift == (0.0, 0.0):
        np.testing.assert_array_equal(centres, touch)  # no roll at touch-down


def test_sideways_stance_is_shortened_by_the_roll():
    # A left leg's stance of a sideways walk to the left: contact from +30 mm to -30 mm.
    touch = ROBOT.standing_feet()
    touch[:, 1] += 0.03
    contacts = touch.copy()
    contacts[:, 1] -= 0.06
    roll = rolled_centres(ROBOT, contacts, touch)[0, :2] - contacts[0, :2]
    # The tibia's elevation changes by ~40 deg: the centre lags its contact point by ~6 mm
    # (the roll the body would otherwise gain: 10 % of the stride).
    assert roll[0] == pytest.approx(0.0, abs=1e-12)
    assert 0.005 < roll[1] < 0.007


def test_walk_plans_centres_that_touch_down_on_their_contact_points():
    plan = plan_walk(CFG, WalkParams.defaults(CFG.gait, heading=math.pi / 2), 2)
    t = np.concatenate([s0 + np.array([0.0, s.swing_time]) for s0, s in
                        zip(plan.starts, plan.slots, strict=True)])
    centres, contacts = plan.evaluate(t)[0], plan.contact_points(t)
    differs = np.linalg.norm(centres - contacts, axis=-1)
    for k, slot in enumerate(plan.slots):  # touch-down of the swinging group: no roll yet
        assert differs[2 * k + 1, list(slot.group)].max() <= 1e-12
    assert 0.003 < differs.max() < 0.01  # elsewhere the roll, a few mm
