"""The planning thread of the planner node: each next slot planned ahead of its boundary."""

from __future__ import annotations

import threading
from collections.abc import Callable

from crawler_motion.planner.core import PlannerCore

#: The thread looks for a slot to plan at most this often [s] (steady time of the ticks): the
#: next slot is planned within this long after `next_slot.PLAN_AHEAD_HORIZON` (0.2 s) before its
#: boundary, and a 500 Hz ticker does not wake the thread (and hand it the GIL) at every tick.
AHEAD_POLL_PERIOD = 0.01


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
        self._polled = -float("inf")  # steady time of the last wake-up [s]
        self.wakes = 0  # wake-ups so far
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="planner-ahead", daemon=True)

    def start(self) -> None:
        """Start the thread."""
        self._thread.start()

    def wake(self, now: float) -> None:
        """Ticker thread, right after a tick at steady time ``now`` [s]: plan ahead of it, at
        most every `AHEAD_POLL_PERIOD` (costs nothing)."""
        if now - self._polled < AHEAD_POLL_PERIOD:
            return
        self._polled = now
        self._now = now
        self.wakes += 1
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
