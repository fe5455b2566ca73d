"""The machine's floor for the end-to-end bench: a bare `Ticker` in a process of its own.

The planner's tick thread is a `runtime.ticker.Ticker`; how punctually it can run depends first
on the machine: how late the kernel wakes a sleeping thread at its deadline, and how often a
virtual machine's CPU is taken away. This measures that floor with nothing of the stack running:
a child process runs a `Ticker` at the bench's rate whose tick only takes the system time
(``time.time``, the clock of the ``joint_commands`` header stamps), for the same window. Its
figures are computed as the pipelines' (`e2e_analysis.period_stats`), so a target below the
floor is one that no code on top of this ticker can meet on this machine at normal priority.

Run alone: ``python -m crawler_motion.tools.wake_floor RATE SECONDS`` prints one JSON object:
``stamps`` [s], ``missed`` (deadlines the ticker skipped), ``cpu`` [% of one core].
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np

from crawler_motion.runtime.ticker import Ticker
from crawler_motion.tools.e2e_analysis import PeriodStats, fmt, period_stats

#: Time the child ticks before its window starts [s] (imports and first wake-ups settle).
SETTLE = 0.5
#: The child may take this much longer than its window before it is given up [s].
CHILD_MARGIN = 30.0


@dataclass(frozen=True)
class Floor:
    """The floor at one rate: the stamps' timing, the ticker's skipped deadlines, its CPU."""

    rate: float  # [Hz]
    timing: PeriodStats
    skipped: int
    cpu: float  # [% of one core]


def tick_stamps(rate: float, seconds: float) -> tuple[list[float], int, float]:
    """Run a bare `Ticker` at ``rate`` [Hz]: the system time of each tick in the ``seconds``
    [s] after `SETTLE`, the deadlines it skipped meanwhile, and its CPU [% of one core]."""
    stamps: list[float] = []
    ticker = Ticker(1.0 / rate, lambda now: stamps.append(time.time()), name="floor")
    ticker.start()
    time.sleep(SETTLE)
    missed0, cpu0, n0, t0 = ticker.missed, time.process_time(), len(stamps), time.monotonic()
    time.sleep(seconds)
    n1, missed1 = len(stamps), ticker.missed
    cpu = 100.0 * (time.process_time() - cpu0) / (time.monotonic() - t0)
    ticker.stop()
    if ticker.error is not None:
        raise RuntimeError(f"the floor's ticker stopped: {ticker.error!r}")
    return stamps[n0:n1], missed1 - missed0, cpu


def measure(rate: float, seconds: float) -> Floor:
    """The floor at ``rate`` [Hz] over ``seconds`` [s], measured in a child process (this
    process's threads cannot delay it); raises RuntimeError if the child fails."""
    cmd = [sys.executable, "-m", __name__, repr(float(rate)), repr(float(seconds))]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, check=False,
                              timeout=seconds + SETTLE + CHILD_MARGIN)
    except subprocess.TimeoutExpired:
        raise RuntimeError(f"the floor's process did not end within "
                           f"{seconds + SETTLE + CHILD_MARGIN:g} s") from None
    if done.returncode != 0:
        raise RuntimeError(f"the floor's process failed ({done.returncode}): "
                           f"{done.stderr.strip()[-300:]}")
    try:
        data = json.loads(done.stdout)
        stamps = np.asarray(data["stamps"], dtype=float)
        missed, cpu = int(data["missed"]), float(data["cpu"])
    except (ValueError, KeyError, TypeError) as exc:
        raise RuntimeError(f"the floor's process printed no figures ({exc!r}): "
                           f"{done.stdout.strip()[:200]!r}") from None
    if stamps.size < 2:
        raise RuntimeError(f"the floor's process ticked {stamps.size} times in {seconds:g} s "
                           f"at {rate:g} Hz: no period to measure")
    return Floor(float(rate), period_stats(stamps, rate), missed, cpu)


def table_row(floor: Floor) -> str:
    """The floor as a row of the bench's timing table (its columns; '-' where none applies)."""
    t = floor.timing
    return (f"| floor (bare ticker) | {floor.rate:g} | {fmt(t.rate, 1)} | {t.missed} (longest "
            f"gap {fmt(t.longest_gap_ms, 1)} ms) | - / {floor.skipped} | {fmt(t.err_p50_ms, 3)} "
            f"/ {fmt(t.err_p99_ms, 3)} / {fmt(t.err_max_ms, 2)} | - | - | {fmt(floor.cpu, 0)} "
            f"(one process) | - | - | - |")


def verdict(floor: Floor, p99_period_error_ms: float) -> str:
    """What the floor at the target rate allows: the line printed under the targets."""
    t = floor.timing
    below = []
    if floor.skipped or t.missed:
        below.append(f"it skipped {floor.skipped} deadlines ({t.missed} gaps > 1.5 T)")
    if not t.err_p99_ms < p99_period_error_ms:
        below.append(f"its p99 period error is {t.err_p99_ms:.3f} ms")
    text = (f"Floor of this machine at {floor.rate:g} Hz (a bare ticker process, nothing of the "
            f"stack running): p99 period error {t.err_p99_ms:.3f} ms, max {t.err_max_ms:.2f} ms, "
            f"{floor.skipped} deadlines skipped")
    if below:
        return (text + f" -> a target of no skipped deadline and a p99 period error < "
                f"{p99_period_error_ms:g} ms is out of this machine's reach at normal priority: "
                + "; ".join(below))
    return text + " -> within the machine's reach"


def main(argv: list[str] | None = None) -> int:
    """``RATE SECONDS`` -> the JSON of `tick_stamps` on stdout."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2:
        print("usage: python -m crawler_motion.tools.wake_floor RATE SECONDS", file=sys.stderr)
        return 2
    try:
        rate, seconds = float(args[0]), float(args[1])
    except ValueError:
        print(f"RATE [Hz] and SECONDS [s] must be numbers, got {args!r}", file=sys.stderr)
        return 2
    if not (1.0 <= rate <= 10_000.0 and 0.0 < seconds <= 3600.0):
        print(f"RATE must be in [1, 10000] Hz and SECONDS in (0, 3600] s, got {args!r}",
              file=sys.stderr)
        return 2
    stamps, missed, cpu = tick_stamps(rate, seconds)
    print(json.dumps({"stamps": stamps, "missed": missed, "cpu": cpu}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
