"""Virtual radius, steering laws and the navigator's states."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.motion.gait import standing_pose
from crawler_motion.navigation.body import envelope_radius, virtual_radius
from crawler_motion.navigation.heading import Rule
from crawler_motion.navigation.methods import METHODS
from crawler_motion.navigation.navigator import (
    Method,
    NavigatorSettings,
    NavState,
    TerrainView,
    VirtualBodyNavigator,
)
from crawler_motion.navigation.steering import Steering, turn_radius, twist

CFG = load_config()


def test_the_virtual_radius_of_the_standing_pose_is_hip_plus_reach() -> None:
    q = standing_pose(CFG)
    assert virtual_radius(CFG.robot, q) == pytest.approx(math.hypot(0.10, 0.06 + 0.13))
    stretched = np.zeros((4, 3))
    assert virtual_radius(CFG.robot, stretched) == pytest.approx(math.hypot(0.10, 0.24))
    yawed = stretched.copy()
    yawed[:, 0] = np.radians([-31.0, 31.0, -31.0, 31.0])  # legs along the hip directions
    assert virtual_radius(CFG.robot, yawed) <= envelope_radius(CFG.robot) + 1e-12
    assert envelope_radius(CFG.robot) == pytest.approx(math.hypot(0.10, 0.06) + 0.18)


@pytest.mark.parametrize("r_w, expected", [(0.0, math.inf), (1.0, 0.12 / math.sqrt(2)),
                                           (2.0, 0.06), (-1.0, -0.12 / math.sqrt(2))])
def test_the_radius_law(r_w: float, expected: float) -> None:
    assert turn_radius(r_w, 0.12) == pytest.approx(expected)


@pytest.mark.parametrize("heading, expected", [
    (0.0, (0.08, 0.0, 0.0)), (math.pi / 2, (0.0, 0.08, 0.0)),
    (-math.pi / 4, (0.08 / math.sqrt(2), -0.08 / math.sqrt(2), 0.0))])
def test_crabbing_walks_along_the_heading_without_turning(heading: float, expected: tuple
                                                         ) -> None:
    assert twist(Steering.CRAB, heading, 0.08, 0.12, 0.2) == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("heading", [0.0, 0.05, -0.1, 0.3, 1.0, 3.0])
def test_turning_uses_omega_v_over_r_and_never_exceeds_the_yaw_rate(heading: float) -> None:
    vx, vy, wz = twist(Steering.TURN, heading, 0.08, 0.12, 0.2)
    assert vy == 0.0 and abs(wz) <= 0.2 + 1e-12 and math.copysign(1, wz) == math.copysign(
        1, heading)
    r_w = max(-2.0, min(2.0, 4 * heading / math.pi))
    radius = turn_radius(r_w, 0.12)
    assert (wz == 0.0 if heading == 0.0 else vx / wz == pytest.approx(radius))


def flat_view(obstacles: list[tuple[int, int]] = ()) -> TerrainView:
    known = np.ones((80, 80), dtype=bool)
    obstacle = np.zeros_like(known)
    for r, c in obstacles:
        obstacle[r, c] = True
    return TerrainView(np.array([-2.0, -2.0]), 0.05, known, obstacle,
                       np.where(obstacle, 0.15, 0.0))


def test_a_goal_is_reached_then_the_walk_stops() -> None:
    nav = METHODS[Method.VIRTUAL_BODY]()
    assert nav.step((0, 0, 0), 0.2, flat_view(), 0.0).twist is None  # IDLE: nothing
    nav.set_goal(1.0, 0.0, 0.0)
    out = nav.step((0.0, 0.0, 0.0), 0.2, flat_view(), 0.1)
    assert out.twist == pytest.approx((0.08, 0.0, 0.0)) and nav.rule is Rule.GOAL
    out = nav.step((0.96, 0.0, 0.0), 0.2, flat_view(), 5.0)
    assert out.twist == (0.0, 0.0, 0.0) and nav.state is NavState.ARRIVED


def test_a_goal_inside_an_obstacle_fails_and_stops() -> None:
    nav = VirtualBodyNavigator()
    nav.set_goal(1.0, 0.0, 0.0)
    out = nav.step((0.0, 0.0, 0.0), 0.2, flat_view([(40, 62)]), 0.1)  # cell at (1.125, 0.025)
    assert out.twist == (0.0, 0.0, 0.0) and nav.state is NavState.FAILED
    assert "inside an obstacle" in nav.reason


def test_time_out_fails_and_a_cancel_stops_only_an_active_goal() -> None:
    nav = VirtualBodyNavigator(NavigatorSettings(timeout=10.0))
    nav.set_goal(1.0, 0.0, 0.0)
    assert nav.step((0.0, 0.0, 0.0), 0.2, flat_view(), 10.5).twist == (0.0, 0.0, 0.0)
    assert nav.state is NavState.FAILED and "10 s" in nav.reason
    nav.set_goal(1.0, 0.0, 20.0)
    assert nav.cancel() is True and nav.state is NavState.IDLE
    assert nav.cancel() is False


@pytest.mark.parametrize("x, y", [(math.nan, 0.0), (0.0, math.inf)])
def test_a_non_finite_goal_is_refused_and_changes_nothing(x: float, y: float) -> None:
    nav = VirtualBodyNavigator()
    with pytest.raises(CommandError, match="not finite"):
        nav.set_goal(x, y, 0.0)
    assert nav.state is NavState.IDLE and nav.goal is None
@pytest.mark.parametrize(("x", "y", "body", "says"), [
    (1e9, 0.0, None, "beyond max_goal_distance 10 m"),
    (1.7e308, 1.7e308, (0.0, 0.0), "beyond max_goal_distance"),  # no Infinity anywhere
    (50.0, 0.0, (0.0, 0.0), "50 m from the body"),
    (10.0 + 1e-9, 0.0, None, "beyond"),
    (float("nan"), 0.0, None, "not finite"),
    (float("inf"), 0.0, None, "not finite"),
])
def test_a_goal_beyond_reach_is_refused_with_the_reason(x, y, body, says):
    from crawler_motion.navigation.navigator import goal_error

    why = goal_error(x, y, body, 10.0)
    assert why is not None and says in why
    assert "inf" not in why.lower() or "not finite" in why


@pytest.mark.parametrize(("x", "y", "body"), [(10.0, 0.0, None), (12.0, 3.0, (2.0, 3.0))])
def test_a_goal_within_reach_is_accepted(x, y, body):
    from crawler_motion.navigation.navigator import goal_error

    assert goal_error(x, y, body, 10.0) is None
