"""The benchmarks' timing primitives: a row of the timing table and how one is measured."""

from __future__ import annotations

import gc
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Row:
    """One line of the timing table (``median``/``p99`` in us; None when skipped)."""

    name: str
    calls: int
    median: float | None
    p99: float | None
    note: str = ""


def measure(name: str, func: Callable[[], object], calls: int, warmup: int = 200,
            note: str = "", between: Callable[[], object] | None = None) -> Row:
    """Time ``func`` ``calls`` times (after ``warmup`` calls) with the GC disabled;
    ``between`` (untimed) runs after every call."""
    for _ in range(warmup):
        func()
        if between is not None:
            between()
    samples = [0] * calls
    clock = time.perf_counter_ns
    was_enabled = gc.isenabled()
    gc.collect()
    gc.disable()
    try:
        for i in range(calls):
            start = clock()
            func()
            samples[i] = clock() - start
            if between is not None:
                between()
    finally:
        if was_enabled:
            gc.enable()
    samples.sort()
    p99 = samples[min(calls - 1, math.ceil(0.99 * calls) - 1)]
    return Row(name, calls, statistics.median(samples) / 1e3, p99 / 1e3, note)


def timer_overhead() -> float:
    """Median cost of an empty timed call [us]."""
    return measure("", lambda: None, 20_000).median or 0.0


def calls_scaled(calls: int, scale: float) -> int:
    """``calls`` scaled by ``scale`` (at least 20)."""
    return max(20, int(calls * scale))
