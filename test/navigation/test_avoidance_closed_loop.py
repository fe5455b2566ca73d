"""Closed-loop avoidance in the seabed simulator (lock-step: physics, scanner, mapper, navigator
and planner core on simulated time): the low wall across the path, the goal behind it."""

from __future__ import annotations

import math

import pytest

from crawler_motion.model.config import load_config
from crawler_motion.navigation.navigator import NavigatorSettings
from crawler_motion.navigation.steering import Steering
from crawler_motion.testing.avoidance_loop import AvoidanceLoop

GOAL = (1.6, 0.0)  # the wall's near face is 0.8 m ahead, 0.6 m wide, 0.15 m high


@pytest.mark.parametrize("steering", [Steering.CRAB, Steering.TURN])
def test_the_crawler_walks_around_the_wall_to_the_goal(steering: Steering) -> None:
    loop = AvoidanceLoop(load_config(), "low_wall", NavigatorSettings(steering=steering))
    res = loop.run(GOAL, limit=120.0)
    assert res.state == "ARRIVED", res.reason
    assert res.final_error <= 0.10
    assert min(res.clearance) > 0.0  # the virtual circle never overlaps an obstacle cell
    assert res.contact_samples == 0  # no hull or leg contact with the world
    assert res.walk_time <= 120.0
    assert max(abs(y) for _, y, _ in res.path) > 0.3 + min(res.radius)  # it went around
    rules = set(res.rule)
    assert "tangent" in rules and res.rule[-1] == "goal"
    obstacles = res.mapper.obstacles()
    assert obstacles.any()
    print(f"\n{steering.value}: arrived {res.final_error:.3f} m from the goal after "
          f"{res.walk_time:.1f} s, min clearance {min(res.clearance):.3f} m, "
          f"max heading {math.degrees(max(abs(h) for h in res.heading if h == h)):.1f}°")
