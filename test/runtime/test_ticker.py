"""The fixed-rate tick thread: the grid arithmetic as a table, the thread's contract."""

from __future__ import annotations

import ctypes
import os
import threading
import time

import pytest

from crawler_motion.runtime.ticker import (
    MAX_RATE_HZ,
    TIMER_SLACK_NS,
    Ticker,
    catch_up,
    check_priority,
)

P = 0.01


@pytest.mark.parametrize(("now", "expected"), [
    # (start of the tick [s] for the deadline 1.0), (served deadline, skipped, late)
    (0.99, (1.0, 0, 0.0)),        # early wake-up: no negative delay
    (1.0, (1.0, 0, 0.0)),         # on time
    (1.005, (1.0, 0, 0.005)),     # late but within a period: runs now, keeps the grid
    (1.0099, (1.0, 0, 0.0099)),   # just under a period late
    (1.01, (1.01, 1, 0.0)),       # exactly a period late: one deadline skipped
    (1.035, (1.03, 3, 0.005)),    # three and a half periods late: no burst of three ticks
])
def test_catch_up_table(now, expected):
    deadline, skipped, late = catch_up(1.0, now, P)
    assert deadline == pytest.approx(expected[0], abs=1e-12)
    assert skipped == expected[1]
    assert late == pytest.approx(expected[2], abs=1e-12)
    assert 0.0 <= late < P


@pytest.mark.parametrize("period", [0.0, -1.0, float("nan"), float("inf"),
                                    0.99 / MAX_RATE_HZ, "fast"])
def test_period_is_validated(period):
    with pytest.raises((ValueError, TypeError)):
        Ticker(period, lambda now: None)
    ticker = Ticker(1.0 / MAX_RATE_HZ, lambda now: None)  # the boundary itself is accepted
    with pytest.raises((ValueError, TypeError)):
        ticker.period = period
    assert ticker.period == 1.0 / MAX_RATE_HZ


def test_ticks_then_idle_in_order_and_stop_joins():
    calls: list[tuple[str, float]] = []
    done = threading.Event()

    def tick(now: float) -> None:
        calls.append(("tick", now))

    def idle(now: float) -> None:
        calls.append(("idle", now))
        if len(calls) >= 20:
            done.set()

    ticker = Ticker(0.005, tick, idle)
    ticker.start()
    assert done.wait(10.0)
    assert ticker.stop(2.0) and not ticker.running
    kinds = [k for k, _ in calls]
    assert kinds[:20] == ["tick", "idle"] * 10
    times = [t for _, t in calls]
    assert times == sorted(times)  # steady clock
    assert ticker.ticks >= 10 and ticker.error is None
    count = len(calls)
    time.sleep(0.05)
    assert len(calls) == count  # nothing after stop


def test_an_exception_stops_the_ticker_and_is_kept():
    def tick(now: float) -> None:
        raise RuntimeError("boom")

    ticker = Ticker(0.001, tick)
    ticker.start()
    deadline = time.monotonic() + 10.0
    while ticker.running and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not ticker.running
    assert isinstance(ticker.error, RuntimeError) and ticker.ticks == 0


def test_a_blocked_tick_is_counted_as_missed_not_replayed():
    """A tick that blocks for ~6 periods: the deadlines it covered are skipped and counted."""
    stamps: list[float] = []
    blocked = threading.Event()

    def tick(now: float) -> None:
        stamps.append(now)
        if len(stamps) == 3:
            time.sleep(6 * P)
            blocked.set()

    ticker = Ticker(P, tick)
    ticker.start()
    assert blocked.wait(10.0)
    time.sleep(3 * P)
    ticker.stop()
    assert ticker.missed >= 4  # >= 5 on an idle machine; more if the machine is loaded
    assert ticker.worst_delay < P
    # at most one tick per deadline: ticks = deadlines served, never more
    span = stamps[-1] - stamps[0]
    assert len(stamps) - 1 <= round(span / P) - ticker.missed + 1


def test_a_new_period_applies_to_the_running_ticker():
    stamps: list[float] = []
    ticker = Ticker(0.002, stamps.append)
    ticker.start()
    time.sleep(0.05)
    ticker.period = 0.02
    time.sleep(0.01)
    mark = len(stamps)
    time.sleep(0.2)
    ticker.stop()
    assert ticker.period == 0.02
    assert len(stamps) - mark <= 12  # ~10 at 50 Hz; ~100 if the old period had stayed


@pytest.mark.parametrize(("priority", "ok"), [
    (0, True), (1, True), (99, True), (-1, False), (100, False), (True, False), (1.0, False),
    ("50", False)])
def test_check_priority_table(priority, ok):
    if ok:
        assert check_priority(priority) == priority
    else:
        with pytest.raises(ValueError, match=r"integer in \[0, 99\]"):
            check_priority(priority)


@pytest.mark.skipif(not hasattr(os, "SCHED_FIFO"), reason="no SCHED_FIFO on this platform")
def test_a_priority_is_set_in_the_thread_or_the_reason_is_given():
    policies: list[int] = []
    ticker = Ticker(0.002, lambda now: policies.append(os.sched_getscheduler(0)), priority=10)
    ticker.start()
    time.sleep(0.05)
    ticker.stop()
    assert policies
    if ticker.priority_error:  # no permission here: normal scheduling, and why
        assert "SCHED_FIFO priority 10 not set" in ticker.priority_error
        assert set(policies) == {os.SCHED_OTHER}
    else:
        assert set(policies) == {os.SCHED_FIFO}
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # only the tick thread


def _timer_slack() -> int:
    """The calling thread's timer slack [ns] (prctl PR_GET_TIMERSLACK); -1 where unknown."""
    try:
        return int(ctypes.CDLL(None).prctl(30, 0, 0, 0, 0))
    except (OSError, AttributeError):
        return -1


def test_the_ticker_thread_sleeps_with_a_short_timer_slack():
    """Linux: the ticker's thread has TIMER_SLACK_NS, the caller's thread keeps its own."""
    before = _timer_slack()
    if before < 0:
        pytest.skip("no prctl(PR_GET_TIMERSLACK) here (not Linux)")
    seen: list[int] = []

    def tick(_now: float) -> None:
        if not seen:
            seen.append(_timer_slack())

    ticker = Ticker(0.001, tick)
    ticker.start()
    deadline = time.monotonic() + 5.0
    while not seen and time.monotonic() < deadline:
        time.sleep(0.01)
    ticker.stop()
    assert seen == [TIMER_SLACK_NS]
    assert _timer_slack() == before != TIMER_SLACK_NS
