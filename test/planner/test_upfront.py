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
