"""The planning thread of the planner node: each next slot planned ahead of its boundary."""

from __future__ import annotations

import threading
from collections.abc import Callable

from crawler_motion.planner.core import PlannerCore


class AheadPlanner:
    """The planning thread: plans the next slot before its boundary without holding the
    core's lock while it computes, so the ticks go on meanwhile.

    ``report`` receives the failures (the boundary tick then plans the slot itself).
    """

    def __init__(self, core: PlannerCore, lock: threading.Lock,
                 report: Callable[[str], None]) -> None:
        self._core = core
        self._lock = lock
        self._report = report
        self._now = 0.0
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="planner-ahead", daemon=True)

    def start(self) -> None:
        """Start the thread."""
        self._thread.start()

    def wake(self, now: float) -> None:
        """Ticker thread, right after a tick: plan ahead of ``now`` (costs nothing)."""
        self._now = now
        self._wake.set()

    def stop(self, timeout: float) -> None:
        """Stop the thread and wait up to ``timeout`` [s] for it."""
        self._stop.set()
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(timeout=timeout)

    def _loop(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()
            if self._stop.is_set():
                return
            try:
                with self._lock:
                    job = self._core.ahead_job(self._now)
                if job is None:
                    continue
                ahead = job.run()
                with self._lock:
                    self._core.store_ahead(ahead)
            except Exception as exc:  # the boundary tick plans it itself if needed
                self._report(f"planning ahead failed: {type(exc).__name__}: {exc}")
