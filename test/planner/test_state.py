"""The planner states: a closed set whose values are the status JSON strings."""

from __future__ import annotations

import json

import pytest

from crawler_motion.planner import state
from crawler_motion.planner.state import HOLDING_STATES, WALK_STATES, PlannerState

NAMES = ["IDLE", "MOVING", "STANDING", "WALKING", "STOPPING", "SITTING", "HOLDING", "ESTOP"]


def test_the_states_are_exactly_the_documented_ones():
    assert [s.value for s in PlannerState] == NAMES


@pytest.mark.parametrize("name", NAMES)
def test_a_state_reads_and_serialises_as_its_bare_name(name):
    member = PlannerState(name)
    assert member == name and getattr(state, name) is member
    assert str(member) == name and f"{member}" == name and f"{member:>9}" == f"{name:>9}"
    assert json.dumps({"state": member}) == json.dumps({"state": name})


@pytest.mark.parametrize("member, holds, walks", [
    (PlannerState.IDLE, False, False),
    (PlannerState.MOVING, False, False),
    (PlannerState.STANDING, True, False),
    (PlannerState.SITTING, True, False),
    (PlannerState.HOLDING, True, False),
    (PlannerState.WALKING, False, True),
    (PlannerState.STOPPING, False, True),
    (PlannerState.ESTOP, False, False),
])
def test_state_groups(member, holds, walks):
    assert (member in HOLDING_STATES, member in WALK_STATES) == (holds, walks)
