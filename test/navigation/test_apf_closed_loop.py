"""The U trap in the seabed simulator with the navigator's ``apf`` method (lock-step: physics,
scanner, mapper, navigator and planner core on simulated time, deterministic)."""

from __future__ import annotations

from crawler_motion.model.config import load_config
from crawler_motion.navigation.navigator import Method, NavigatorSettings
from crawler_motion.testing.avoidance_loop import AvoidanceLoop

START = (-1.2, 0.0, 0.0)  # in front of the opening of config/worlds/u_trap.xml [m, rad]
GOAL = (1.3, 0.0)  # behind its back wall [m]


def test_the_crawler_walks_around_the_u_trap_to_the_goal_behind_it() -> None:
    loop = AvoidanceLoop(load_config(), "u_trap", NavigatorSettings(), method=Method.APF,
                         start=START)
    res = loop.run(GOAL, limit=90.0)
    assert res.state == "ARRIVED", res.reason
    assert res.final_error <= 0.10
    assert min(res.clearance) > 0.0  # the virtual circle never overlaps an obstacle cell
    assert res.contact_samples == 0  # no hull or leg contact with the walls
    assert res.virtual_goals >= 1  # the field alone is trapped in the U
    assert max(abs(y) for _, y, _ in res.path) > 0.4 + min(res.radius)  # it went around
    print(f"\napf U trap: arrived {res.final_error:.3f} m from the goal after "
          f"{res.walk_time:.1f} s, min clearance {min(res.clearance):.3f} m, "
          f"{res.virtual_goals} virtual goals, navigator cycle max {max(res.nav_ms):.0f} ms")
