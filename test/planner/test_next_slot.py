"""Planning the next slot: a walk never enters a slot it cannot stop from, and a cmd_vel
walk's slot that the limits refuse is slowed, stated, rather than stopped (pure core)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.motion.gait import standing_pose
from crawler_motion.planner import next_slot
from crawler_motion.planner.core import PlannerCore
from crawler_motion.planner.driver_view import DriverReport
from crawler_motion.planner.state import HOLDING, STANDING

CFG = load_config()
DT = 0.01
#: A navigator's twists (t [s] from standing, (vx, vy, wz)) from a harbour mission's clean-up
#: goals on the real-time stack, simplified: backwards and left, slower, then right. With the
#: default gait the last change found a stance foot at its reach with its velocity out, and
#: neither the next slot nor a stop could follow (HOLDING until an operator sent stand).
TRACE = [(0.0, (0.01, 0.02, 0.0)), (0.6, (-0.047, 0.038, 0.0)), (1.5, (-0.03, 0.025, 0.0)),
         (2.5, (-0.016, 0.013, 0.0)), (3.2, (-0.042, -0.068, 0.0))]


def walk_trace(trace: list[tuple[float, tuple[float, float, float]]], seconds: float,
               levels: tuple[str, ...] = ("error",), status: dict | None = None
               ) -> tuple[list[str], list[str]]:
    """Stand, then send the trace's twist every 0.1 s (as the navigator) for ``seconds``,
    the joints following the targets; the states seen and the events of ``levels`` (and the
    final planner status into ``status``)."""
    core = PlannerCore(CFG, 1 / DT)
    core.on_driver(DriverReport("enabled", 1), 0.0)
    q, t = standing_pose(CFG).reshape(-1), 0.0
    core.set_measured(q, t)
    core.tick(t)
    core.submit('{"command": "stand"}', t)
    while core.state != STANDING:
        t = round(t + DT, 9)
        core.set_measured(q, t)
        q = np.array(core.tick(t).positions)
    states, errors, start = [], [], t
    for k in range(round(seconds / DT)):
        now = start + k * DT
        twist = [v for at, v in trace if at <= k * DT][-1]
        if k % 10 == 0:
            try:
                core.on_twist(*twist, now)
            except CommandError:
                pass  # a twist while the walk stops: the next one is taken
        core.set_measured(q, now)
        target = core.tick(now)
        if target is not None:
            q = np.array(target.positions)
        states.append(str(core.state))
        errors += [m for level, m in core.ctx.journal.pop_events() if level in levels]
    if status is not None:
        status.update(core.status())
    return states, errors


def test_a_walk_never_enters_a_slot_it_cannot_stop_from(monkeypatch) -> None:
    monkeypatch.setattr(next_slot, "SLOWED_SHARES", ())  # the rule below, left out
    states, errors = walk_trace(TRACE, 6.0)
    assert str(HOLDING) not in states, errors
    assert not any("cannot stop either" in e for e in errors), errors
    # the slot it could not stop from was refused: the walk stopped, then walked on
    assert any("could not be stopped from" in e for e in errors), errors
    assert "STOPPING" in states
    assert states[-1] == "WALKING", states[-1]


def test_a_cmd_vel_slot_it_cannot_stop_from_is_slowed_not_stopped() -> None:
    """The same trace with the rule: the slot is walked slower, with a warning, and the walk
    never stops (a navigator would have restarted it, in a loop, at every such slot)."""
    states, events = walk_trace(TRACE, 6.0, ("error", "warn"))
    assert set(states) == {"WALKING"}, events
    slowed = [e for e in events if e.startswith("slot slowed to 60%")]
    assert slowed and "could not be stopped from" in slowed[0], events
    assert not any("slot check failed" in e for e in events), events


#: A crab walk whose heading swings between slots (deg, every 0.5 s) at 0.08 m/s, as a
#: navigator along a wall: each swing to sideways carries a stance foot past its reach.
SWINGS = [(0.5 * k, (0.08 * np.cos(h), 0.08 * np.sin(h), 0.0))
          for k, h in enumerate([1.57, 0.0] * 8)]


@pytest.mark.parametrize(("shares", "walking"), [((0.6, 0.3), True), ((), False)])
def test_a_swinging_crab_walks_on_slowed(monkeypatch, shares, walking) -> None:
    monkeypatch.setattr(next_slot, "SLOWED_SHARES", shares)
    status: dict = {}
    states, events = walk_trace(SWINGS, 8.0, ("error", "warn"), status)
    stops = sum(1 for a, b in itertools.pairwise(states)
                if (a, b) == ("WALKING", "STOPPING"))
    if walking:
        assert stops == 0, events
        assert status["slowed_slots"] >= 3, status
        # the first one is logged, the others counted (a navigator along a wall: every
        # other slot)
        assert sum(e.startswith("slot slowed to") for e in events) == 1, events
    else:  # without the rule: a stop into standing at each of them
        assert stops >= 3, events
