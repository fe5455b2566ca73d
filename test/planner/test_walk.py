"""The walk controller's slot inputs: when a twist or a command takes effect, and that the node's
planning ahead is never made stale by a steering navigator (its twists at 10 Hz)."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.model.config import load_config
from crawler_motion.motion.gait import WalkParams, standing_pose
from crawler_motion.planner.core import PlannerCore
from crawler_motion.planner.next_slot import PLAN_AHEAD_HORIZON
from crawler_motion.planner.state import STANDING, WALKING
from crawler_motion.planner.walk import WalkController

CFG = load_config()
DT = 0.01
DIAGONAL = WalkParams.defaults(CFG.gait, gait="diagonal")
SLOT = 0.6  # the diagonal's slot [s]


def walking(**kwargs) -> tuple[PlannerCore, float]:
    """A core walking a cmd_vel walk (0.06 m/s forward) that started at the time returned."""
    core = PlannerCore(CFG, 100.0, **{"defaults": DIAGONAL, "cmd_vel_timeout": 30.0, **kwargs})
    core.set_measured(standing_pose(CFG), 0.0)
    core.submit('{"command": "stand"}', 0.0)
    t = 0.0
    while core.state != STANDING:
        t = round(t + DT, 9)
        core.tick(t)
        assert t < 10.0
    t0 = round(t + DT, 9)
    core.on_twist(0.06, 0.0, 0.0, t0)
    core.tick(t0)
    assert core.state == WALKING
    return core, t0


# (time before the first slot's boundary the twist arrives [s], the slot that takes it: 1 is
# the slot after the boundary, 2 the one after that)
LATCH = [
    (0.5, 1),
    (PLAN_AHEAD_HORIZON + DT, 1),
    (PLAN_AHEAD_HORIZON, 2),  # the boundary row: the next slot is being planned ahead
    (PLAN_AHEAD_HORIZON - DT, 2),
    (DT, 2),
]


@pytest.mark.parametrize(("before", "slot"), LATCH)
def test_a_twist_takes_effect_at_the_boundary_it_arrived_in_time_for(before, slot):
    core, t0 = walking()
    start_stride = core.walk_params.stride
    t = t0
    boundary = t0 + SLOT
    while t < boundary - before - 1e-9:
        t = round(t + DT, 9)
        core.tick(t)
    core.on_twist(0.03, 0.0, 0.0, round(boundary - before, 9))
    strides = []
    while t < t0 + 3.5 * SLOT:
        t = round(t + DT, 9)
        core.tick(t)
        strides.append((t, core.walk_params.stride))
    first = min(tt for tt, s in strides if s != start_stride)
    assert first == pytest.approx(boundary + (slot - 1) * SLOT, abs=DT + 1e-9)
    assert strides[-1][1] == pytest.approx(start_stride / 2)


def test_a_walk_command_replaces_a_twist_not_yet_taken():
    core, t0 = walking()
    t = t0
    while t < t0 + SLOT - 0.1:
        t = round(t + DT, 9)
        core.tick(t)
    core.on_twist(0.03, 0.0, 0.0, t)  # kept for the slot after the next one
    assert core.walk.inputs.later is not None
    core.submit('{"command": "walk", "steps": 1, "stride": 0.02}', t)  # for the next slot
    assert core.walk.inputs.later is None and core.walk.inputs.pending.stride == 0.02
    strides = set()
    while core.state != STANDING:
        t = round(t + DT, 9)
        core.tick(t)
        if core.walk_params is not None:
            strides.add(round(core.walk_params.stride, 6))
        assert t < t0 + 10 * SLOT
    assert 0.03 not in strides and 0.02 in strides  # the twist's stride never walked


def test_a_steering_navigator_never_makes_a_tick_plan_a_slot(monkeypatch):
    """Twists at 10 Hz, each a little different (as the navigator steers), with the slot
    planned ahead after every tick as the node does: no tick plans a slot itself (before,
    every twist within the horizon made the plan made ahead stale and the boundary tick
    planned the slot: 10-150 ms of a tick on the real-time stack)."""
    in_tick: list[float] = []
    real = WalkController._try_slot
    ahead = [False]

    def counting(self, params, stopping):
        if not ahead[0]:
            in_tick.append(self.slot_t0)
        return real(self, params, stopping)

    monkeypatch.setattr(WalkController, "_try_slot", counting)
    core, t0 = walking()
    rng = np.random.default_rng(3)
    t = t0
    while t < t0 + 6 * SLOT:
        t = round(t + DT, 9)
        if round((t - t0) / DT) % 10 == 0:
            core.on_twist(0.06 + rng.uniform(-0.02, 0.0), rng.uniform(-0.01, 0.01), 0.0, t)
        core.tick(t)
        ahead[0] = True
        try:
            core.plan_ahead(t)
        finally:
            ahead[0] = False
    assert core.state == WALKING
    assert in_tick == []
