"""A fixed-rate tick loop in its own thread, on the steady clock (no ROS imports).

The planner publishes its joint commands from a `Ticker` rather than from an rclpy timer: an
rclpy timer fires from the executor, which also runs every subscription callback and (in Python)
rebuilds its wait set on every spin, so a busy executor delays or skips ticks. The ticker sleeps
until absolute deadlines ``t0 + k * period`` on ``time.monotonic`` and never drifts:

- a tick that starts late, but less than one period late, runs at once and the next deadline
  stays on the grid (the average rate is kept);
- a tick one or more whole periods late skips the missed deadlines (they are counted in
  ``missed``, never run in a burst: a late joint command is worse than none).

``idle`` (optional) runs right after a tick, in the same thread, so it delays the next tick
by its own duration: keep it short (the planner wakes its planning thread there and, composed
with the driver, takes the measured joint states handed over since the last tick).

The thread's timer slack is `TIMER_SLACK_NS` (Linux): the kernel may otherwise wake a sleeping
thread of normal priority up to 50 µs after its deadline, to batch wake-ups.

``priority`` 1..99 runs the thread under SCHED_FIFO (Linux; needs CAP_SYS_NICE or an rtprio
limit), as real-time controllers do: the thread then preempts ordinary processes when its
deadline comes. If it cannot be set, the ticker runs at normal priority and says why in
``priority_error``.
"""

from __future__ import annotations

import ctypes
import math
import os
import threading
import time
from collections.abc import Callable

#: Largest allowed tick rate [Hz] (a sanity bound, not a performance claim).
MAX_RATE_HZ = 10_000.0
#: Timer slack of the ticker thread [ns] (Linux default 50,000; 0 would mean "the default").
TIMER_SLACK_NS = 1_000
#: ``PR_SET_TIMERSLACK`` of Linux's prctl(2).
PR_SET_TIMERSLACK = 29


def set_timer_slack(nanoseconds: int) -> bool:
    """Set the calling thread's timer slack [ns] (Linux prctl); False where it cannot be."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_TIMERSLACK, ctypes.c_ulong(nanoseconds), 0, 0, 0) == 0
    except (OSError, AttributeError):  # not Linux / no prctl
        return False


def check_priority(priority: int) -> int:
    """A real-time priority: 0 (normal scheduling) or 1..99 (SCHED_FIFO); raises ValueError."""
    if isinstance(priority, bool) or not isinstance(priority, int) or not 0 <= priority <= 99:
        raise ValueError(f"tick priority must be an integer in [0, 99] (0: normal scheduling, "
                         f"1-99: SCHED_FIFO), got {priority!r}")
    return priority


def set_process_priority(priority: int) -> str:
    """Put every thread of this process under SCHED_FIFO at ``priority`` (1..99; Linux).

    Threads created afterwards inherit it from their creator. Returns "" on success, else why
    it could not be set (the process then runs at normal priority). Used so that a thread
    holding the GIL (the executor) is not preempted by ordinary processes while the tick
    thread waits for it.
    """
    check_priority(priority)
    if priority == 0:
        return ""
    try:
        tids = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError as exc:  # not Linux
        return f"SCHED_FIFO priority {priority} not set for the process ({exc})"
    for tid in tids:
        problem = _set_fifo(tid, priority)
        if problem:
            return f"{problem} for the process"
    return ""


def _set_fifo(tid: int, priority: int) -> str:
    """SCHED_FIFO at ``priority`` for thread ``tid`` (0: the calling thread); "" or why not."""
    try:
        os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, OSError) as exc:  # no permission, or not Linux
        return f"SCHED_FIFO priority {priority} not set ({exc})"
    return ""


def catch_up(deadline: float, now: float, period: float) -> tuple[float, int, float]:
    """Where a tick that starts at ``now`` stands on the grid ``deadline + k * period`` [s].

    Returns ``(deadline, skipped, late)``: the deadline this tick serves (the latest one not
    after ``now``, or ``deadline`` itself when ``now`` is early or less than a period late),
    the whole deadlines skipped before it, and how late the tick starts after it [s] (>= 0).
    """
    late = now - deadline
    if late < period:
        return deadline, 0, max(late, 0.0)
    skipped = int(late // period)
    deadline += skipped * period
    return deadline, skipped, now - deadline


class Ticker:
    """Calls ``tick(now)`` every ``period`` seconds of steady time in a daemon thread.

    ``tick`` and ``idle`` must handle their own errors: an exception escaping them stops the
    ticker and is kept in ``error`` (the owner decides what a dead ticker means).
    """

    def __init__(self, period: float, tick: Callable[[float], None],
                 idle: Callable[[float], None] | None = None, name: str = "ticker",
                 priority: int = 0) -> None:
        self._period = self._checked(period)
        self._priority = check_priority(priority)
        self._tick = tick
        self._idle = idle
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        #: Ticks run so far.
        self.ticks = 0
        #: Deadlines skipped because a tick started one or more whole periods late.
        self.missed = 0
        #: Largest start delay of a tick after its deadline [s].
        self.worst_delay = 0.0
        #: The exception that stopped the ticker, if any.
        self.error: BaseException | None = None
        #: Why the real-time priority could not be set ("" if it was, or none was asked).
        self.priority_error = ""
        self._started = threading.Event()

    @staticmethod
    def _checked(period: float) -> float:
        period = float(period)
        if not math.isfinite(period) or period < 1.0 / MAX_RATE_HZ:
            raise ValueError(f"tick period must be a finite number >= {1.0 / MAX_RATE_HZ:g} s, "
                             f"got {period!r}")
        return period

    @property
    def period(self) -> float:
        """Tick period [s]."""
        return self._period

    @period.setter
    def period(self, value: float) -> None:
        """A new period [s] applies after the next tick: the grid restarts at that tick."""
        value = self._checked(value)
        with self._lock:
            self._period = value

    def start(self) -> None:
        """Start ticking; the first tick is one period from now. Returns once the thread
        runs (and has tried its priority: see `priority_error`)."""
        self._thread.start()
        self._started.wait(5.0)

    def stop(self, timeout: float = 1.0) -> bool:
        """Stop and join the thread; True if it ended within ``timeout`` [s]."""
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)
        return not self._thread.is_alive()

    @property
    def running(self) -> bool:
        """True while the thread runs."""
        return self._thread.is_alive()

    def _run(self) -> None:
        set_timer_slack(TIMER_SLACK_NS)
        if self._priority > 0:
            problem = _set_fifo(0, self._priority)
            if problem:
                self.priority_error = f"{problem}; ticking at normal priority"
        self._started.set()
        with self._lock:
            period = self._period
        deadline = time.monotonic() + period
        try:
            while True:
                delay = deadline - time.monotonic()
                if delay > 0.0 and self._stop.wait(delay):
                    return
                if self._stop.is_set():
                    return
                now = time.monotonic()
                deadline, skipped, late = catch_up(deadline, now, period)
                self.missed += skipped
                self.worst_delay = max(self.worst_delay, late)
                self._tick(now)
                self.ticks += 1
                if self._idle is not None:
                    self._idle(time.monotonic())
                with self._lock:
                    if self._period != period:  # restart the grid at the new period
                        period = self._period
                        deadline = now
                deadline += period
        except BaseException as exc:  # kept for the owner; the thread ends
            self.error = exc
