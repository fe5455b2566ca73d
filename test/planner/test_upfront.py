"""The up-front check of a new walk and its cache."""

from __future__ import annotations

import pytest

from crawler_motion.model.config import load_config
from crawler_motion.motion.gait import WalkParams, plan_walk
from crawler_motion.planner import upfront
from crawler_motion.planner.upfront import UPFRONT_CACHE_SIZE, UPFRONT_CHECK_STEPS, UpfrontCheck

CFG = load_config()


@pytest.fixture
def calls(monkeypatch):
    seen = []

    def counting(cfg, params, steps):
        seen.append((params, steps))
        return plan_walk(cfg, params, steps)

    monkeypatch.setattr(upfront, "plan_walk", counting)
    return seen


@pytest.mark.parametrize("steps, checked", [(1, 1), (UPFRONT_CHECK_STEPS, UPFRONT_CHECK_STEPS),
                                            (UPFRONT_CHECK_STEPS + 1, UPFRONT_CHECK_STEPS),
                                            (1000, UPFRONT_CHECK_STEPS)])
def test_at_most_a_few_steps_are_checked_once(calls, steps, checked):
    check = UpfrontCheck(CFG)
    params = WalkParams.defaults(CFG.gait)
    assert check(params, steps) is None and check(params, steps) is None
    assert [s for _, s in calls] == [checked]


def test_a_refusal_is_remembered_and_the_oldest_verdict_dropped(calls):
    check = UpfrontCheck(CFG)
    bad = WalkParams.defaults(CFG.gait, stride=0.0, body_height=0.2)
    assert "body_height" in check(bad, 1)
    assert "body_height" in check(bad, 1) and len(calls) == 1
    for i in range(UPFRONT_CACHE_SIZE):
        check(WalkParams.defaults(CFG.gait, stride=0.001 * (i % 50), turn=0.001 * (i // 50)), 1)
    check(bad, 1)
    assert len(calls) == UPFRONT_CACHE_SIZE + 2  # the first verdict was dropped: checked again


def test_a_prepared_first_slot_is_taken_once_and_only_for_its_parameters():
    check = UpfrontCheck(CFG)
    params = WalkParams.defaults(CFG.gait)
    other = WalkParams.defaults(CFG.gait, stride=0.03)
    check.prepare(params)
    assert check.take_first(other) is None  # another walk: planned at its start
    assert check.take_first(params) is None  # ... and the prepared one is gone
    check.prepare(params)
    first = check.take_first(params)
    assert first is not None and first.params == params
    assert first.facts is not None and first.facts.slot is first.slot
    assert first.track is not None and first.facts.table is not None
    assert check.take_first(params) is None  # once: its sequencer walks on from it


def test_a_first_slot_that_cannot_be_walked_is_left_to_the_start():
    check = UpfrontCheck(CFG)
    check.prepare(WalkParams.defaults(CFG.gait, stride=0.0, body_height=0.2))
    assert check.take_first(WalkParams.defaults(CFG.gait, stride=0.0, body_height=0.2)) is None
