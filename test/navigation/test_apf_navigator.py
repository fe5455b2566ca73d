"""The navigator's ``apf`` method (pure): planning grid, look-ahead point, follow commands,
goto past the U trap, follow mode on a synthetic wall, and the registry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.navigation.apf.maps import U_TRAP, box_grid
from crawler_motion.navigation.apf_navigator import (
    PLAN_CELLS,
    TRAP_PATIENCE,
    ApfNavigator,
    FollowCommand,
    Side,
    carrot,
    planning_grid,
)
from crawler_motion.navigation.methods import METHODS
from crawler_motion.navigation.navigator import (
    Method,
    NavigatorSettings,
    NavState,
    TerrainView,
    VirtualBodyNavigator,
)
from crawler_motion.navigation.parameters import NAVIGATOR_PARAMETERS

RADIUS = 0.2  # virtual radius given to the navigator [m]; the disc is RADIUS + margin
MARGIN = NavigatorSettings().margin  # added to the virtual radius [m]


def view_of(boxes, origin=(-2.0, -2.0), size=(4.0, 4.0), res=0.05) -> TerrainView:
    g = box_grid(boxes, origin, size, res)
    shape = g.obstacle.shape
    return TerrainView(g.origin, res, np.ones(shape, bool), g.obstacle, np.zeros(shape))


WALL = ((0.0, -0.05, 2.0, 0.05),)  # a straight wall along x, its face at y = 0


@pytest.mark.parametrize("points, expect_extent", [
    ([[0.0, 0.0]], (-1.0, 1.0, -1.0, 1.0)),  # inside: the map as it is
    ([[0.0, 0.0], [1.3, 0.0]], (-1.0, 1.8, -1.0, 1.0)),  # goal beyond +x: padded
    ([[-1.2, -0.9]], (-1.7, 1.0, -1.4, 1.0)),  # beyond two edges
])
def test_the_planning_grid_holds_the_points_and_keeps_obstacles_in_place(
        points, expect_extent) -> None:
    view = view_of(((0.5, 0.5, 0.1, 0.1),), origin=(-1.0, -1.0), size=(2.0, 2.0))
    grid = planning_grid(view, np.array(points), 0.5)
    assert grid.extent == pytest.approx(expect_extent)
    assert grid.obstacle.sum() == view.obstacle.sum()
    assert grid.occupied(np.array([0.5, 0.5])) and not grid.occupied(np.array([0.7, 0.7]))


# the 2 m map at 0.05 m from (-1, -1), the body on the x axis and 0.5 m of margin: the grid
# holds (x + 1.5 m) x 2 m / 0.05² cells, PLAN_CELLS at x = 1248.5 m
@pytest.mark.parametrize("x, refused", [(10.0, False), (1248.0, False), (1249.0, True),
                                        (1e5, True)])
def test_a_body_far_from_its_map_is_refused_within_the_cell_budget(x, refused) -> None:
    view = view_of(((0.5, 0.5, 0.1, 0.1),), origin=(-1.0, -1.0), size=(2.0, 2.0))
    if not refused:
        assert planning_grid(view, np.array([[x, 0.0]]), 0.5).obstacle.size <= PLAN_CELLS
        return
    with pytest.raises(CommandError, match="beyond the budget of 1e\\+06: the body is far"):
        planning_grid(view, np.array([[x, 0.0]]), 0.5)
    nav = ApfNavigator()
    nav.set_goal(x + 1.0, 0.0, 0.0)
    out = nav.step((x, 0.0, 0.0), RADIUS, view, 0.0)  # a cycle fails the goal, no exception
    assert nav.state is NavState.FAILED and "far from its map" in nav.reason
    assert out.twist == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("distance, expect", [(0.0, [0, 0]), (0.5, [0.5, 0]), (1.0, [1, 0]),
                                              (1.5, [1, 0.5]), (9.0, [1, 1])])
def test_the_look_ahead_point_lies_that_far_along_the_path(distance, expect) -> None:
    path = np.array([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0], [1.0, 0.5], [1.0, 1.0]])
    assert carrot(path, distance) == pytest.approx(expect)


@pytest.mark.parametrize("text, length, side", [
    ('{"length": 2}', 2.0, Side.RIGHT), ('{"length": 0.5, "side": "left"}', 0.5, Side.LEFT)])
def test_a_follow_command_parses(text, length, side) -> None:
    assert FollowCommand.from_json(text) == FollowCommand(length, side)


@pytest.mark.parametrize("text, says", [
    ("follow 2", "not JSON"), ('{"side": "left"}', "needs"),
    ('{"length": 2, "speed": 1}', "needs"),
    ('{"length": 0}', "> 0"), ('{"length": -1}', "> 0"), ('{"length": NaN}', "finite"),
    ('{"length": true}', "finite"), ('{"length": "2"}', "finite"), ("[2]", "needs"),
    ('{"length": 2, "side": "up"}', "right or left"),
    # hostile input that used to crash the navigator (RecursionError, OverflowError, ...)
    ("[" * 100_000, "at most 1000 characters"), ("[" * 999, "not JSON"),
    ('{"length": ' + "9" * 400 + "}", "finite"), ('{"length": ' + "9" * 980 + "}", "finite"),
    ('{"length": 1e999}', "finite"), ("x" * 1001, "at most 1000 characters")])
def test_a_bad_follow_command_is_refused_with_the_reason(text, says) -> None:
    with pytest.raises(CommandError, match=says):
        FollowCommand.from_json(text)


def test_goto_in_front_of_the_u_trap_heads_around_it_with_virtual_goals() -> None:
    nav = ApfNavigator()
    nav.set_goal(1.3, 0.0, 0.0)
    out = nav.step((-1.2, 0.0, 0.0), RADIUS, view_of(U_TRAP), 0.0)
    status = nav.status()
    assert nav.state is NavState.ACTIVE and status["virtual_goals"]
    assert status["virtual_goals_used"] == len(status["virtual_goals"]) >= 1
    assert math.hypot(out.twist[0], out.twist[1]) == pytest.approx(nav.settings.speed)
    # the plan first descends towards the mouth of the U (straight ahead), then goes round
    assert out.heading == pytest.approx(0.0, abs=0.05)
    assert status["path_length"] > 2.5 + 0.5


@pytest.mark.parametrize("goal, says", [((0.3, 0.0), "inside an obstacle"),
                                        ((0.55, 0.0), "inside an obstacle")])
def test_a_goal_in_an_obstacle_fails_and_the_robot_stands(goal, says) -> None:
    nav = ApfNavigator()
    nav.set_goal(*goal, 0.0)
    out = nav.step((-1.2, 0.0, 0.0), RADIUS, view_of(U_TRAP), 0.0)
    assert nav.state is NavState.FAILED and says in nav.reason
    assert out.twist == (0.0, 0.0, 0.0)


BOX = ((0.0, 1.0, 1.0, 0.05), (0.0, -1.0, 1.0, 0.05), (1.0, 0.0, 0.05, 1.05),
       (-1.0, 0.0, 0.05, 1.05))  # walls round the origin


@pytest.mark.parametrize("waited, state", [(0.0, NavState.ACTIVE),
                                           (TRAP_PATIENCE - 0.01, NavState.ACTIVE),
                                           (TRAP_PATIENCE, NavState.FAILED)])
def test_a_trapped_plan_stands_and_plans_again_then_fails_with_the_reason(
        waited, state) -> None:
    nav = ApfNavigator()
    nav.set_goal(0.0, 0.0, 10.0)  # walled in
    nav.step((-1.6, 0.0, 0.0), RADIUS, view_of(BOX), 10.0)
    out = nav.step((-1.6, 0.0, 0.0), RADIUS, view_of(BOX), 10.0 + waited)
    assert nav.state is state and "trapped" in nav.reason
    assert out.twist == (0.0, 0.0, 0.0)


def test_a_trap_the_fuller_map_opens_is_walked_after_all() -> None:
    nav = ApfNavigator()
    nav.set_goal(0.0, 0.0, 0.0)
    nav.step((-1.6, 0.0, 0.0), RADIUS, view_of(BOX), 0.0)
    opened = BOX[:3]  # the next map: no wall on the robot's side
    out = nav.step((-1.6, 0.0, 0.0), RADIUS, view_of(opened), 1.0)
    assert nav.state is NavState.ACTIVE and nav.reason == "" and any(out.twist)
    nav.step((-1.6, 0.0, 0.0), RADIUS, view_of(BOX), 1.5)  # trapped again: patience anew
    nav.step((-1.6, 0.0, 0.0), RADIUS, view_of(BOX), 1.5 + TRAP_PATIENCE - 0.01)
    assert nav.state is NavState.ACTIVE


def test_goto_arrives_within_the_tolerance_and_stops() -> None:
    nav = ApfNavigator()
    nav.set_goal(1.0, 0.0, 0.0)
    out = nav.step((0.97, 0.0, 0.0), RADIUS, view_of(()), 0.0)
    assert nav.state is NavState.ARRIVED and out.twist == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("tolerance, x, arrived", [
    (None, 0.951, True),  # the settings' 0.05 m
    (None, 0.949, False),
    (0.02, 0.981, True),  # a goal's own, tighter tolerance
    (0.02, 0.979, False),
])
def test_a_goal_arrives_within_its_own_tolerance(tolerance, x, arrived) -> None:
    nav = ApfNavigator()
    nav.set_goal(1.0, 0.0, 0.0, tolerance)
    nav.step((x, 0.0, 0.0), RADIUS, view_of(()), 0.0)
    assert (nav.state is NavState.ARRIVED) is arrived, nav.reason
    assert nav.status()["tolerance"] == (tolerance or NavigatorSettings().goal_tolerance)


@pytest.mark.parametrize("tolerance", [0.0, -0.01, math.nan, math.inf])
def test_a_bad_goal_tolerance_is_refused_and_the_goal_kept(tolerance) -> None:
    nav = ApfNavigator()
    nav.set_goal(1.0, 0.0, 0.0)
    with pytest.raises(CommandError, match="tolerance"):
        nav.set_goal(2.0, 0.0, 0.0, tolerance)
    assert nav.goal is not None and nav.goal.tolist() == [1.0, 0.0]


@pytest.mark.parametrize("y, side, heading, sign", [
    (RADIUS + MARGIN + 0.10, Side.RIGHT, 0.0, 0),  # at ρ_o: along the wall
    (RADIUS + MARGIN + 0.05, Side.RIGHT, 0.0, +1),  # too close: away from the wall
    (RADIUS + MARGIN + 0.17, Side.RIGHT, 0.0, -1),  # in the band, too far: towards it
    (RADIUS + MARGIN + 0.10, Side.LEFT, math.pi, 0),  # the wall on the left: the other way
])
def test_follow_walks_along_a_wall_at_the_standoff(y, side, heading, sign) -> None:
    nav = ApfNavigator()
    nav.set_follow(FollowCommand(2.0, side), 0.0)
    out = nav.step((0.0, y, 0.0), RADIUS, view_of(WALL), 0.0)
    assert nav.state is NavState.ACTIVE, nav.reason
    off = math.atan2(math.sin(out.heading - heading), math.cos(out.heading - heading))
    vy = out.twist[1]
    if sign == 0:
        assert abs(off) < math.radians(3)
    else:
        assert abs(off) > math.radians(3) and np.sign(vy) == sign
    nav.step((2.0 if side is Side.RIGHT else -2.0, y, 0.0), RADIUS, view_of(WALL), 1.0)
    assert nav.state is NavState.ARRIVED and nav.status()["follow"]["walked"] == 2.0


@pytest.mark.parametrize("y, active", [
    (RADIUS + 0.01, True),  # inside the margin: the margin gives way
    (RADIUS - 0.05, True),  # the map grew 0.05 m into the bare disc: led out
    (0.5 * RADIUS + 0.01, True),  # the disc shrinks down to half the virtual radius
    (0.5 * RADIUS - 0.01, False),  # closer still: FAILED, the robot stands
])
def test_a_body_the_map_grew_into_is_led_out_away_from_the_wall(y, active) -> None:
    nav = ApfNavigator()
    nav.set_goal(1.5, y + 0.3, 0.0)  # off the wall (its face at y = 0): up and along
    out = nav.step((0.5, y, 0.0), RADIUS, view_of(WALL), 0.0)
    assert (nav.state is NavState.ACTIVE) is active, nav.reason
    if active:
        assert out.twist is not None and out.heading is not None
        assert math.sin(out.heading) > 0  # away from the wall (it lies at y < 0)
    else:
        assert "inside an obstacle" in nav.reason and out.twist == (0.0, 0.0, 0.0)


def test_follow_without_a_structure_fails() -> None:
    nav = ApfNavigator()
    nav.set_follow(FollowCommand(1.0), 0.0)
    nav.step((0.0, 0.0, 0.0), RADIUS, view_of(()), 0.0)
    assert nav.state is NavState.FAILED and "no structure" in nav.reason


def test_the_registry_holds_both_methods_and_the_parameter_offers_them() -> None:
    assert METHODS == {Method.VIRTUAL_BODY: VirtualBodyNavigator, Method.APF: ApfNavigator}
    spec = next(p for p in NAVIGATOR_PARAMETERS if p.name == "method")
    assert set(spec.choices) == {m.value for m in METHODS}
    for method, cls in METHODS.items():
        nav = cls(NavigatorSettings())
        assert nav.status()["method"] == method.value and nav.cancel() is False
