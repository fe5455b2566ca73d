"""Closed-loop walk over the shipped 1 cm step in the seabed simulator (lock-step: physics, the
planner's contact estimate from the simulated joint angles and torques, planner core, on
simulated time), with the terrain-adaptive touch-down and without it."""

from __future__ import annotations

import math

import pytest

from crawler_motion.model.config import load_config
from crawler_motion.motion.foothold import FootholdSettings
from crawler_motion.motion.gait import WalkParams
from crawler_motion.testing.foothold_loop import FootholdLoop, WalkRecord

STEP_EDGE = 0.25  # world x of the step's face [m] (config/worlds/step.xml)
STEPS = 5
#: The diagonal gait with an all-feet-down transfer between the pairs (0.6 s swing, 1.2 s
#: stance), default stride, lift and arc.
STANCE_TIME = 1.2


def _walk(enabled: bool) -> WalkRecord:
    cfg = load_config()
    params = WalkParams.defaults(cfg.gait, gait="diagonal", stance_time=STANCE_TIME)
    loop = FootholdLoop(cfg, "step", FootholdSettings(enabled=enabled))
    return loop.walk(params, STEPS)


@pytest.mark.slow
def test_the_diagonal_gait_crosses_the_step_landing_each_foot_where_the_ground_is() -> None:
    cfg = load_config()
    rear = float(cfg.robot.standing_feet(None)[:, 0].min())  # rear feet's x in the body
    blind, adaptive = _walk(False), _walk(True)
    for name, rec in (("blind", blind), ("adaptive", adaptive)):
        print(f"\n{name}: {rec.summary()}, max roll {math.degrees(max(map(abs, rec.roll))):.1f}"
              f" deg")
    assert adaptive.state == "STANDING", adaptive.events
    assert adaptive.position[-1][0] + rear > STEP_EDGE + 0.05  # the rear feet are over it
    assert adaptive.advance_ratio >= 0.8
    assert adaptive.max_torque < 0.9  # no joint at its torque limit
    assert adaptive.advance_ratio > blind.advance_ratio + 0.1  # the adaptation is what did it
