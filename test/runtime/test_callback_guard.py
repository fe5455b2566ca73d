"""The callbacks' last line of defence: an exception is counted, logged once a second per
callback and type, handed to ``on_error``, and survived; a normal call is untouched."""

from __future__ import annotations

import logging

import pytest

from crawler_motion.runtime.callback_guard import CallbackGuard


class Logger:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def error(self, message: str) -> None:
        self.lines.append(message)


def boom(kind: type[Exception]) -> None:
    raise kind("bad input")


def test_a_normal_call_returns_its_value_and_counts_nothing() -> None:
    guard = CallbackGuard(Logger())
    assert guard.wrap("topic", lambda a, b: a + b)(2, 3) == 5
    assert guard.total == 0


@pytest.mark.parametrize("calls, kinds, logged", [
    (1, (ValueError,), 1),
    (50, (ValueError,), 1),  # a flood: one line a second
    (50, (ValueError, OverflowError), 2),  # a second kind has its own line
])
def test_exceptions_are_counted_and_logged_once_a_second_per_kind(calls, kinds, logged) -> None:
    logger, stops = Logger(), []
    guard = CallbackGuard(logger)
    for k in range(calls):
        kind = kinds[k % len(kinds)]
        assert guard.wrap("odom", lambda kind=kind: boom(kind), stops.append)() is None
    assert guard.errors["odom"] == calls == guard.total == len(stops)
    assert len(logger.lines) == logged
    assert "odom: ValueError: bad input (at boom" in logger.lines[0]
    assert "survived, 1 so far" in logger.lines[0]


def test_an_on_error_that_raises_is_counted_too() -> None:
    guard = CallbackGuard(logging.getLogger("test"))

    def bad_stop(_why: str) -> None:
        raise RuntimeError("cannot stop")

    guard.wrap("terrain_map", lambda: boom(KeyError), bad_stop)()
    assert guard.errors == {"terrain_map": 1, "terrain_map (on_error)": 1}


def test_while_shutting_down_an_exception_goes_on_to_the_executor() -> None:
    guard = CallbackGuard(Logger(), alive=lambda: False)
    with pytest.raises(ValueError):
        guard.wrap("terrain_map", lambda: boom(ValueError))()
    assert guard.total == 0
