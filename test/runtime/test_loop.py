"""Tests of crawler_motion.runtime.loop: the background step loop."""

from __future__ import annotations

import threading
import time

from crawler_motion.runtime.loop import BackgroundLoop


def _wait(predicate, timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.001)
    return predicate()


def test_steps_until_stopped_and_restarts() -> None:
    count = []
    loop = BackgroundLoop("t", lambda: (count.append(1), time.sleep(0.001)), print, 0.01)
    loop.start()
    loop.start()  # no-op while running: still one thread
    assert _wait(lambda: len(count) > 5)
    assert sum(t.name == "t" for t in threading.enumerate()) == 1
    assert loop.stop(2.0) is True
    assert not loop.running
    n = len(count)
    time.sleep(0.02)
    assert len(count) == n
    loop.start()
    assert _wait(lambda: len(count) > n)
    assert loop.stop(2.0)


def test_a_failing_step_is_reported_and_the_loop_goes_on() -> None:
    errors: list[Exception] = []
    calls = []

    def step() -> None:
        calls.append(1)
        if len(calls) == 1:
            raise ValueError("boom")

    loop = BackgroundLoop("t2", step, errors.append, 0.001)
    loop.start()
    assert _wait(lambda: len(calls) > 3)
    assert loop.stop(2.0)
    assert [str(e) for e in errors] == ["boom"]


def test_stop_reports_a_thread_that_does_not_end_in_time() -> None:
    release = threading.Event()
    loop = BackgroundLoop("t3", lambda: release.wait(5.0), print, 0.0)
    loop.start()
    time.sleep(0.01)
    assert loop.stop(0.05) is False
    release.set()
    assert loop.stop(1.0) is True  # already stopped: nothing to wait for
