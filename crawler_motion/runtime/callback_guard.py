"""The last line of defence of a node's callbacks: an exception is logged, counted, survived."""

from __future__ import annotations

import functools
import traceback
from collections import Counter
from collections.abc import Callable
from typing import Any

from crawler_motion.runtime.log import Severity, Throttle, log


class CallbackGuard:
    """Wraps a node's callbacks so that nothing a message contains can end the process.

    Input is checked where it is read (with the reason in a status); this guard only catches
    what those checks missed: the exception is counted per callback (`errors`, for the node's
    ``/diagnostics``), logged at ERROR with its place once a second per callback and exception
    type, then ``on_error`` (if given: e.g. stop the robot) is called with the message, and the
    callback returns None. ``logger`` is an rclpy or a `logging` logger. While ``alive()`` is
    false (the process is shutting down: rclpy's context is no longer valid) an exception goes
    on to the executor, as rclpy's shutdown pattern expects.
    """

    def __init__(self, logger: Any, period: float = 1.0,
                 alive: Callable[[], bool] = lambda: True) -> None:
        self.logger, self.alive = logger, alive
        self.errors: Counter[str] = Counter()
        self._throttle = Throttle(period)

    @property
    def total(self) -> int:
        """Exceptions caught so far, all callbacks."""
        return sum(self.errors.values())

    def wrap(self, name: str, fn: Callable[..., Any],
             on_error: Callable[[str], None] | None = None) -> Callable[..., Any]:
        """``fn`` guarded under ``name`` (e.g. the topic)."""

        @functools.wraps(fn)
        def guarded(*args: Any) -> Any:
            try:
                return fn(*args)
            except Exception as exc:  # the last line of defence, by design
                if not self.alive():
                    raise
                self.errors[name] += 1
                where = traceback.extract_tb(exc.__traceback__)[-1]
                message = (f"{name}: {type(exc).__name__}: {str(exc)[:200]} (at {where.name}, "
                           f"line {where.lineno})")
                if self._throttle.allow((name, type(exc).__name__)):
                    log(self.logger, Severity.ERROR,
                        f"{message}; survived, {self.errors[name]} so far: this is a defect, "
                        "please report it")
                if on_error is not None:
                    try:
                        on_error(message)
                    except Exception:  # still the last line
                        self.errors[f"{name} (on_error)"] += 1
                return None

        return guarded
