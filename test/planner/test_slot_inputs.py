"""`SlotInputs`: which slot a twist or a command is for (table with the horizon's boundary)."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from crawler_motion.model.config import load_config
from crawler_motion.motion.gait import WalkParams
from crawler_motion.planner.next_slot import PLAN_AHEAD_HORIZON
from crawler_motion.planner.slot_inputs import SlotInputs

CURRENT = WalkParams.defaults(load_config().gait)
A = replace(CURRENT, stride=CURRENT.stride / 2)
B = replace(CURRENT, stride=CURRENT.stride / 3)


@pytest.mark.parametrize(("to_boundary", "pending", "later"), [
    (math.inf, A, None),  # no slot planned ahead (a frozen walk)
    (PLAN_AHEAD_HORIZON + 1e-6, A, None),
    (PLAN_AHEAD_HORIZON, None, A),  # the boundary row
    (0.0, None, A),
])
def test_a_twist_is_for_the_next_slot_unless_it_is_being_planned(to_boundary, pending, later):
    inputs = SlotInputs()
    inputs.take_twist(A, CURRENT, to_boundary)
    assert (inputs.pending, inputs.later) == (pending, later)
    assert inputs.newest(CURRENT) == A


def test_a_twist_equal_to_the_newest_changes_nothing_and_a_command_replaces_a_later_twist():
    inputs = SlotInputs()
    inputs.take_twist(CURRENT, CURRENT, 0.0)
    assert (inputs.pending, inputs.later) == (None, None)
    inputs.take_twist(A, CURRENT, 1.0)
    inputs.take_twist(B, CURRENT, 0.1)
    assert (inputs.pending, inputs.later) == (A, B)
    inputs.advance(stopping=False)  # the next slot took A: B is the one after's
    assert (inputs.pending, inputs.later) == (B, None)
    inputs.take_twist(A, CURRENT, 0.1)
    inputs.take_command(CURRENT, 3)
    assert (inputs.pending, inputs.later, inputs.steps) == (CURRENT, None, (3,))
    inputs.take_twist(A, CURRENT, 0.1)
    inputs.advance(stopping=True)  # a stop drops what was asked for
    assert (inputs.pending, inputs.later) == (None, None)
