"""The planner's shared context: journal (revision, refusals, events) and pause flag."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.planner.context import MAX_EVENTS, Journal, PlannerContext
from crawler_motion.planner.state import IDLE, WALKING


@pytest.mark.parametrize("n, kept", [(0, 0), (1, 1), (MAX_EVENTS, MAX_EVENTS),
                                     (MAX_EVENTS + 1, MAX_EVENTS)])
def test_the_event_queue_keeps_the_newest(n, kept):
    journal = Journal()
    for i in range(n):
        journal.event("info", str(i))
    events = journal.pop_events()
    assert len(events) == kept
    if n:
        assert events[-1] == ("info", str(n - 1)) and journal.last_event == str(n - 1)
    assert journal.pop_events() == []


def test_a_refusal_is_counted_reported_and_raised():
    journal = Journal()
    with pytest.raises(CommandError, match=r"^no$"):
        journal.refuse("no", 2.5)
    assert (journal.refusals, journal.last_refusal, journal.revision, journal.stamp) == (
        1, "no", 1, 2.5)
    assert journal.pop_events() == [("warn", "refused: no")]


@pytest.mark.parametrize("calls, revision, events", [
    ([(True, "x")], 1, [("warn", "paused: motor manager fault (x); no new gait slot starts "
                                 "until it clears")]),
    ([(True, "x"), (True, "x")], 1, 1),  # unchanged: nothing
    ([(True, "x"), (True, "y")], 2, 1),  # a new reason: a status change, no new event
    ([(True, "")], 1, [("warn", "paused: motor manager fault (no reason given); no new gait "
                                "slot starts until it clears")]),
    ([(False, "")], 0, 0),  # not paused: nothing to clear
    ([(True, "x"), (False, "")], 2, 2),
])
def test_pause_changes(calls, revision, events):
    ctx = PlannerContext(12)
    for paused, reason in calls:
        ctx.set_paused(paused, 1.0, reason)
    got = ctx.journal.pop_events()
    assert ctx.journal.revision == revision
    assert got == events if isinstance(events, list) else len(got) == events
    assert ctx.paused == calls[-1][0]


def test_held_poses_are_read_only_and_enter_touches():
    ctx = PlannerContext(3)
    held = ctx.hold_pose(np.array([1.0, 2.0, 3.0]))
    assert not held.positions.flags.writeable and not held.velocities.flags.writeable
    assert ctx.state == IDLE
    ctx.enter(WALKING, 4.0)
    assert (ctx.state, ctx.journal.revision, ctx.journal.stamp) == (WALKING, 1, 4.0)
