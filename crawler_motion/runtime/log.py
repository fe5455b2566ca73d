"""One severity vocabulary and one function logging a message at a severity."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Hashable
from enum import Enum
from typing import Any


class Severity(str, Enum):
    """How bad a logged event is (the value is the python `logging` level name)."""

    DEBUG = "debug"
    INFO = "info"
    WARNING = "warning"
    ERROR = "error"


def log(logger: Any, severity: Severity, message: str, **kwargs: Any) -> None:
    """Log ``message`` at ``severity`` to an rclpy logger or a `logging.Logger`.

    Never raises: logging must not break a safety path (a failure goes to this module's
    debug log). Each severity has its own call line, because rclpy's logger refuses a call
    site whose severity changes between calls. ``kwargs`` go to the logger (e.g. rclpy's
    ``throttle_duration_sec``).
    """
    try:
        if severity is Severity.ERROR:
            logger.error(message, **kwargs)
        elif severity is Severity.WARNING:
            logger.warning(message, **kwargs)
        elif severity is Severity.INFO:
            logger.info(message, **kwargs)
        else:
            logger.debug(message, **kwargs)
    except Exception:
        logging.getLogger(__name__).debug("logging failed", exc_info=True)


class Throttle:
    """Lets one event per key through every ``period`` seconds (steady ``clock`` [s]).

    Remembers at most ``max_keys`` keys (forgets all when more come: a message text may be a
    key).
    """

    def __init__(self, period: float = 1.0, clock: Callable[[], float] = time.monotonic,
                 max_keys: int = 256) -> None:
        self.period = period
        self._clock = clock
        self._max_keys = max_keys
        self._last: dict[Hashable, float] = {}

    def allow(self, key: Hashable) -> bool:
        """True when ``key`` was not let through within the last period (and records it)."""
        now = self._clock()
        if now - self._last.get(key, -math.inf) < self.period:
            return False
        if key not in self._last and len(self._last) >= self._max_keys:
            self._last.clear()
        self._last[key] = now
        return True
