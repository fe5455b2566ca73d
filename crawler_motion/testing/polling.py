"""Waiting for a condition in tests and tools: poll it until true or a timeout."""

from __future__ import annotations

import time
from collections.abc import Callable


def wait_until(predicate: Callable[[], object], timeout: float = 10.0,
               period: float = 0.01) -> bool:
    """Poll ``predicate`` every ``period`` [s] for up to ``timeout`` [s] of real time; True as
    soon as it holds, else its last value."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(period)
    return bool(predicate())
