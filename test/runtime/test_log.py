"""Tests of crawler_motion.runtime.log: one severity vocabulary, logging never raises."""

from __future__ import annotations

import logging

import pytest

from crawler_motion.runtime.log import Severity, Throttle, log


class Recorder:
    """A logger recording (method, message, kwargs); ``fail`` makes every call raise."""

    def __init__(self, fail: bool = False) -> None:
        self.calls: list[tuple[str, str, dict]] = []
        self.fail = fail

    def _record(self, method: str):
        def call(message: str, **kwargs) -> None:
            self.calls.append((method, message, kwargs))
            if self.fail:
                raise ValueError("Logger severity cannot be changed between calls.")
        return call

    def __getattr__(self, method: str):
        return self._record(method)


@pytest.mark.parametrize(("severity", "method"), [
    (Severity.DEBUG, "debug"), (Severity.INFO, "info"), (Severity.WARNING, "warning"),
    (Severity.ERROR, "error"),
])
def test_each_severity_calls_its_method(severity, method):
    logger = Recorder()
    log(logger, severity, "hello", throttle_duration_sec=1.0)
    assert logger.calls == [(method, "hello", {"throttle_duration_sec": 1.0})]
    assert severity.value == method  # the value is the logging level name


def test_a_failing_logger_does_not_raise():
    logger = Recorder(fail=True)
    log(logger, Severity.ERROR, "boom")
    assert logger.calls == [("error", "boom", {})]


def test_python_logging(caplog):
    with caplog.at_level(logging.INFO):
        log(logging.getLogger("x"), Severity.WARNING, "careful")
    assert [(r.levelname, r.message) for r in caplog.records] == [("WARNING", "careful")]
    assert Severity("warning") is Severity.WARNING


def test_throttle_lets_one_event_per_key_and_period_through():
    now = [0.0]
    throttle = Throttle(period=1.0, clock=lambda: now[0], max_keys=2)
    assert throttle.allow("a") and not throttle.allow("a") and throttle.allow("b")
    now[0] = 0.999
    assert not throttle.allow("a")
    now[0] = 1.0
    assert throttle.allow("a")  # exactly one period later
    assert throttle.allow("c")  # a third key: the others are forgotten
    assert throttle.allow("a")
