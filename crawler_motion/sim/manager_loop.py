"""Timing of the simulated manager: periodic frames on its clock and its background thread."""

from __future__ import annotations

import logging
from collections.abc import Callable

import can

from crawler_motion.runtime.loop import BackgroundLoop

log = logging.getLogger(__name__)

#: Slack on "is a periodic frame due" against float rounding of the simulated time [s].
DUE_SLACK = 1e-9


class PeriodicSchedule:
    """When a periodic frame is due on the simulated clock; never bursts after a stall."""

    def __init__(self, period: float) -> None:
        self.period = period  # [s]
        self._next = 0.0  # [s]

    def due(self, now: float) -> bool:
        """True (and the next time scheduled) when the frame is due at ``now`` [s]."""
        if now < self._next - DUE_SLACK:
            return False
        self._next += self.period
        if self._next <= now:  # fell behind: do not burst
            self._next = now + self.period
        return True


class StepLoop:
    """A background thread handling received frames as they come and advancing the simulation
    by the elapsed time every ``tick`` [s] of ``clock`` (monotonic, [s]).

    ``receive(timeout)`` returns a frame or None, ``handle(frame)`` processes one,
    ``advance(dt)`` moves the simulation on by ``dt`` [s]; ``on_error(text)`` is told when a
    step raised (the loop goes on).
    """

    def __init__(self, name: str, tick: float, clock: Callable[[], float],
                 receive: Callable[[float], can.Message | None],
                 handle: Callable[[can.Message], None], advance: Callable[[float], None],
                 on_error: Callable[[str], None]) -> None:
        self._tick = tick
        self._clock = clock
        self._receive = receive
        self._handle = handle
        self._advance = advance
        self._on_error = on_error
        self._last = self._next_tick = 0.0  # [s] on ``clock``
        self._loop = BackgroundLoop(name, self._step, self._step_failed, pause=tick)

    @property
    def running(self) -> bool:
        """True while the thread runs."""
        return self._loop.running

    def start(self) -> None:
        """Start the thread; RuntimeError when it already runs."""
        if self.running:
            raise RuntimeError("the simulated manager is already running")
        self._last = self._next_tick = self._clock()
        self._loop.start()

    def stop(self, timeout: float) -> None:
        """Stop the thread within ``timeout`` [s] (no-op when not running)."""
        if not self._loop.stop(timeout):
            raise RuntimeError(f"the simulated manager thread did not stop within {timeout} s")

    def _step(self) -> None:
        wait = self._next_tick - self._clock()
        if wait > 0:
            msg = self._receive(wait)
            if msg is not None:
                self._handle(msg)
                return
        now = self._clock()
        try:
            self._advance(max(now - self._last, 0.0))
        finally:
            self._last = now
            self._next_tick = now + self._tick

    def _step_failed(self, exc: Exception) -> None:
        """Keep the manager alive after a failed step; the counters tell."""
        log.error("simulation step failed", exc_info=exc)
        self._on_error(f"step failed: {exc}")
