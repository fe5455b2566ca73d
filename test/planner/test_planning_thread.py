"""Tests of crawler_motion.planner.planning_thread: the planning thread plans the next slot
outside the lock and is woken at most every AHEAD_POLL_PERIOD of tick time."""

from __future__ import annotations

import threading
import time

import pytest

from crawler_motion.planner.planning_thread import AHEAD_POLL_PERIOD, AheadPlanner


class Job:
    def __init__(self, plan: str) -> None:
        self.plan = plan

    def run(self) -> str:
        return self.plan


class Core:
    """`PlannerCore`'s ahead_job / store_ahead: one job at ``due``, recorded calls."""

    def __init__(self, due: float) -> None:
        self.due = due
        self.asked: list[float] = []
        self.stored: list[str] = []
        self.done = threading.Event()

    def ahead_job(self, now: float) -> Job | None:
        self.asked.append(now)
        return Job(f"plan at {now:g}") if now >= self.due and not self.stored else None

    def store_ahead(self, plan: str) -> None:
        self.stored.append(plan)
        self.done.set()


def _run(core: Core, ticks: list[float]) -> AheadPlanner:
    failures: list[str] = []
    planner = AheadPlanner(core, threading.Lock(), failures.append)  # type: ignore[arg-type]
    planner.start()
    try:
        for now in ticks:
            planner.wake(now)
            time.sleep(0.002)  # the thread takes each wake-up before the next tick
        core.done.wait(2.0 if core.due < float("inf") else 0.05)
    finally:
        planner.stop(2.0)
    assert not failures
    return planner


@pytest.mark.parametrize(("period", "wakes"), [
    (0.003, 5), (0.004, 7), (AHEAD_POLL_PERIOD * 0.99, 10), (AHEAD_POLL_PERIOD * 1.2, 20)])
def test_ticks_wake_the_thread_at_most_every_poll_period(period: float, wakes: int) -> None:
    """20 ticks ``period`` apart: the first tick wakes the thread, then the first tick at
    least a poll period (10 ms) after the last wake-up (3 ms: ticks 0, 4, 8, 12, 16)."""
    core = Core(due=float("inf"))
    planner = _run(core, [100.0 + i * period for i in range(20)])
    assert planner.wakes == wakes
    assert 1 <= len(core.asked) <= wakes


def test_the_due_slot_is_planned_within_one_poll_period_and_stored() -> None:
    core = Core(due=100.05)
    ticks = [100.0 + i * 0.002 for i in range(40)]  # 500 Hz for 80 ms
    _run(core, ticks)
    assert len(core.stored) == 1
    planned_at = float(core.stored[0].split()[-1])
    assert core.due <= planned_at < core.due + AHEAD_POLL_PERIOD + 1e-9
