"""End-to-end bench over the cross-process bus: planner -> driver -> CAN, side by side for the
two-node pipeline and the composed ``controller_node``, at 100, 200, 500 and 1000 Hz.

For each command rate and pipeline: starts the simulated motor manager and either the driver
(autostart) and the planner (parameter ``rate``) as separate processes (*two-node*) or both
composed in one ``controller_node`` process (*controller*), on a fresh python-can
``udp_multicast`` port and a ROS domain no other node uses, stands, walks (a walk without
steps) and, after a settling second, measures for ``--seconds``, then ends the commands (the
planner process stopped; the controller e-stopped, its driver reporting the final counters) and
tears the stack down. The two pipelines alternate rate by rate, so both see the same load.

- Planner timing, from a ``joint_commands`` subscriber in this process (reliable, deep queue),
  over the commands whose header stamp lies in the window: achieved rate = (n - 1) / (last
  stamp - first stamp); period error = |stamp difference - 1/rate|, p50 / p99; missed ticks =
  stamp gaps > 1.5 periods. The planner's own counts (``late_ticks`` and, from the ticker
  thread, ``missed_ticks`` in planner_status; differences over the window) are printed next
  to it.
- JointState -> CAN latency, from a passive bus listener in a child process (so that this
  process's rclpy callbacks cannot delay it): the four target frames of one tick (one counter)
  form a group; groups are matched in order to the recorded commands by their decoded positions
  (to the DBC's resolution). Latency = kernel receive time of the group's first frame on the
  listener's socket (SO_TIMESTAMPNS, CLOCK_REALTIME) - the JointState header stamp (the
  planner's ROS clock = the system clock). A command without a group is *lost*; a group without
  a recorded command means this process's subscriber missed a message (observer miss).
- CPU of each process: utime + stime from /proc/<pid>/stat over the window, in % of one core
  (the listener child and this process are shown too: they are load on the same machine);
  planner + driver (two processes, or the one controller) per command in ms of CPU.
- The machine's floor (`wake_floor`), before each rate unless ``--no-floor``: a bare ticker
  process at that rate for the same window, nothing of the stack running; a target below it
  cannot be met on this machine at normal priority.
- Against the floor (`e2e_targets`): each run beside its rate's floor (deadlines skipped,
  p99 period error, their ratio and difference), its latency and CPU per command, and the
  verdict of its target (relative to the floor for the timing).

Run: crawler-motion bench --e2e [--seconds 15] [--rates 100,200,500,1000]
[--pipelines two-node,controller] [--no-floor]
The machine may be shared: the figures depend on its load; rerun before drawing conclusions.
Exit status: 0 when every rate ran (whether the target is met or not), 1 when a run failed.

The stack (`e2e_stack`), the records (`e2e_records`) and the analysis (`e2e_analysis`) are
shared with ``crawler-motion soak``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from crawler_motion.tools import wake_floor
from crawler_motion.tools.args import add_gait_option
from crawler_motion.tools.e2e_analysis import (
    Matching,
    PeriodStats,
    command_flow,
    counters_text,
    fmt,
    listener_delay_ms,
    match_groups,
    percentile,
    period_stats,
    planner_counters,
    tolerance_rad,
)
from crawler_motion.tools.e2e_records import GROUP_T, REC_STAMP
from crawler_motion.tools.e2e_stack import Finish, Stack
from crawler_motion.tools.e2e_targets import Pipeline, chain_cpu, print_against_floor
from crawler_motion.tools.procstat import cpu_percent

#: Command rates of the bench [Hz].
RATES = (100.0, 200.0, 500.0, 1000.0)


@dataclass
class RateResult:
    """One row of the bench table."""

    rate: float
    pipeline: Pipeline = Pipeline.TWO_NODE
    timing: PeriodStats | None = None
    planner_ticks: str = "-"  # `counters_text` over the window
    skipped: int = 0  # deadlines the planner's ticker skipped in the window (missed_ticks)
    lat_p50_ms: float = math.nan
    lat_p99_ms: float = math.nan
    lat_max_ms: float = math.nan
    lost: int = 0  # commands in the window without a frame group
    observer_misses: int = 0  # groups in the window without a recorded command
    cpu: dict[str, float] = field(default_factory=dict)
    error: str = ""
    #: Whole run (stand + walk + stop): where the commands went, see `command_flow`.
    flow: dict[str, int] = field(default_factory=dict)
    listener_delay: tuple[float, float] = (math.nan, math.nan)  # see `listener_delay_ms`


@dataclass
class Window:
    """The measured window of one run: its wall-clock bounds [s], the planner's counters and
    the CPU samples at both ends, the planner state at its end and the final records."""

    t0: float
    t1: float
    ticks0: dict[str, int]
    ticks1: dict[str, int]
    cpu0: dict[str, float | None]
    cpu1: dict[str, float | None]
    state: object
    done: Finish


def run_stack(stack: Stack, seconds: float, settle: float) -> Window:
    """Start ``stack``, stand, walk, settle ``settle`` [s], measure ``seconds`` [s], stop."""
    stack.start()
    stack.command({"command": "stand"})
    stack.command({"command": "walk"})
    stack.spin(settle)
    late0 = planner_counters(stack.status)
    t0, cpu0 = time.time(), stack.cpu()
    stack.spin(seconds)
    t1, cpu1 = time.time(), stack.cpu()
    late1 = planner_counters(stack.status)
    state = stack.status.get("state")
    stack.command({"command": "stop"})
    stack.spin(0.3)
    return Window(t0, t1, late0, late1, cpu0, cpu1, state, stack.finish())


def analyse(result: RateResult, commands: np.ndarray, window: Window) -> None:
    """Fill ``result`` from the recorded ``commands`` and the bus records of ``window``."""
    commands = commands[np.argsort(commands[:, REC_STAMP], kind="stable")]
    done, t0, t1 = window.done, window.t0, window.t1
    groups = done.tap.groups
    in_window = (commands[:, REC_STAMP] >= t0) & (commands[:, REC_STAMP] <= t1)
    result.timing = period_stats(commands[in_window, REC_STAMP], result.rate)
    result.planner_ticks = counters_text(window.ticks0, window.ticks1)
    result.skipped = window.ticks1.get("missed_ticks", 0) - window.ticks0.get("missed_ticks", 0)
    matching: Matching = match_groups(commands, groups, tolerance_rad())
    latency = matching.latency(commands, groups)[in_window] * 1e3
    result.lat_p50_ms = percentile(latency, 50)
    result.lat_p99_ms = percentile(latency, 99)
    result.lat_max_ms = float(np.nanmax(latency)) if np.isfinite(latency).any() else math.nan
    result.lost = int(np.count_nonzero(matching.command_group[in_window] < 0))
    g_window = (groups[:, GROUP_T] >= t0) & (groups[:, GROUP_T] <= t1)
    result.observer_misses = int(np.count_nonzero(matching.group_command[g_window] < 0))
    result.cpu = cpu_percent(window.cpu0, window.cpu1)
    result.flow = command_flow(commands, done, matching)
    result.listener_delay = listener_delay_ms(groups)


def bench_rate(rate: float, seconds: float, *, settle: float = 1.0, gait: str = "diagonal",
               say: Callable[[str], None] = print, tick_priority: int = 0,
               pipeline: Pipeline = Pipeline.TWO_NODE) -> RateResult:
    """Start a stack at ``rate``, stand, walk, measure for ``seconds``, stop, analyse."""
    result = RateResult(rate, pipeline)
    stack = Stack(rate, gait=gait, tick_priority=tick_priority,
                  controller=pipeline is Pipeline.CONTROLLER)
    try:
        say(f"{pipeline.value} {rate:g} Hz: starting the stack (logs in {stack.logs})")
        window = run_stack(stack, seconds, settle)
    except (RuntimeError, OSError) as exc:
        result.error = str(exc)
        say(f"{pipeline.value} {rate:g} Hz: error: {exc}\n{stack.log_tails()}")
        return result
    finally:
        stack.close()
    if window.state != "WALKING":
        result.error = f"not walking at the end of the window ({window.state})"
    analyse(result, stack.commands.array(), window)
    return result


def cpu_text(result: RateResult) -> str:
    """'planner + driver = sum' (two-node) or the controller's CPU, and per command [ms] (at
    the achieved rate)."""
    c, total = result.cpu, chain_cpu(result)
    rate = result.timing.rate if result.timing is not None else result.rate
    per = 10.0 * total / rate  # [ms of CPU per command]
    if result.pipeline is Pipeline.CONTROLLER:
        return f"{fmt(total, 0)} (one process) | {fmt(per, 2)} | -"
    driver = 10.0 * c.get("driver", math.nan) / rate
    return (f"{fmt(c.get('planner'), 0)} + {fmt(c.get('driver'), 0)} = {fmt(total, 0)} | "
            f"{fmt(per, 2)} | {fmt(driver, 2)}")


def print_timing_table(results: Sequence[RateResult], seconds: float,
                       floors: Mapping[float, wake_floor.Floor]) -> None:
    """The table of timing, latency, losses and CPU per pipeline and rate, each rate's rows
    after its floor (`wake_floor`) where it was measured."""
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"\n## End to end: planner -> driver -> CAN ({seconds:g} s walking per rate, "
          f"{os.cpu_count()} CPUs, load average now {load})\n")
    print("| pipeline | rate [Hz] | achieved [Hz] | missed ticks (gaps > 1.5 T) | planner late "
          "/ missed ticks | period error p50 / p99 / max [ms] | JointState->CAN p50 / p99 / "
          "max [ms] | lost | CPU % planner + driver | CPU ms / command | driver CPU ms / "
          "command | CPU % sim / tap / bench |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    shown: set[float] = set()
    for r in results:
        if r.rate in floors and r.rate not in shown:
            shown.add(r.rate)
            print(wake_floor.table_row(floors[r.rate]))
        if r.timing is None:
            print(f"| {r.pipeline.value} | {r.rate:g} | failed: {r.error} | | | | | | | | | |")
            continue
        t, c = r.timing, r.cpu
        lost = f"{r.lost}" + (f" (+{r.observer_misses} observer misses)"
                              if r.observer_misses else "")
        print(f"| {r.pipeline.value} | {r.rate:g} | {fmt(t.rate, 1)} | {t.missed} (longest "
              f"gap {fmt(t.longest_gap_ms, 1)} ms) | {r.planner_ticks} | "
              f"{fmt(t.err_p50_ms, 3)} / {fmt(t.err_p99_ms, 3)} / {fmt(t.err_max_ms, 2)} | "
              f"{fmt(r.lat_p50_ms, 2)} / {fmt(r.lat_p99_ms, 2)} / {fmt(r.lat_max_ms, 2)} | "
              f"{lost} | {cpu_text(r)} | {fmt(c.get('sim'), 0)} / {fmt(c.get('tap'), 0)} / "
              f"{fmt(c.get('self'), 0)} |" + (f" {r.error}" if r.error else ""))


def print_flow_table(results: Sequence[RateResult]) -> None:
    """The table of where the commands of each whole run went."""
    print("\nWhole run (stand, walk, stop; counted after the commands ended): joint_commands "
          "received here -> accepted by the driver (its drops: stale + refused + blocked + "
          "inactive) -> target frame groups on the bus -> target frames applied by the "
          "manager.\n")
    print("| pipeline | rate [Hz] | received here | driver accepted | driver drops | groups on "
          "bus (partial) | commands without group | groups without command | target frames "
          "on bus | manager applied / rejected | listener user-space delay p50 / p99 [ms] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        f = r.flow
        if not f:
            continue
        print(f"| {r.pipeline.value} | {r.rate:g} | {f['published']} | {f['driver_accepted']} | "
              f"{f['driver_dropped']} | {f['groups']} ({f['partial_groups']}) | "
              f"{f['unmatched_commands']} | {f['unmatched_groups']} | {f['target_frames']} | "
              f"{f['sim_applied']} / {f['sim_rejected']} | {fmt(r.listener_delay[0], 3)} / "
              f"{fmt(r.listener_delay[1], 3)} |")


def print_table(results: Sequence[RateResult], seconds: float,
                floors: Mapping[float, wake_floor.Floor] | None = None) -> bool:
    """Print the Markdown tables and the verdict; True when the target is met."""
    floors = {} if floors is None else floors
    print_timing_table(results, seconds, floors)
    print_flow_table(results)
    met = print_against_floor(results, floors, seconds)
    print("\nPeriod error = |difference of consecutive JointState header stamps - 1/rate|. "
          "Latency = kernel receive time of the first target frame of a tick on the listener's "
          "udp_multicast socket - the JointState header stamp (same system clock). "
          "CPU in % of one core over the window; 'tap' is this bench's bus listener, 'bench' "
          "this process (its joint_commands subscriber). The listener's user-space delay "
          "(time.time() when its thread got the frame - the kernel time) is what a "
          "user-space receive time would have added to the latency.")
    return met


def parse_rates(text: str) -> tuple[float, ...]:
    """'100,200,500' -> (100.0, 200.0, 500.0), each in [1, 1000] Hz."""
    try:
        rates = tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of rates: {text!r}") from None
    if not rates or not all(1.0 <= r <= 1000.0 for r in rates):
        raise argparse.ArgumentTypeError(f"rates must be in [1, 1000] Hz, got {text!r}")
    return rates


def parse_pipelines(text: str) -> tuple[Pipeline, ...]:
    """'two-node,controller' -> the `Pipeline` members, in that order."""
    names = [x.strip() for x in text.split(",") if x.strip()]
    known = [p.value for p in Pipeline]
    if not names or any(n not in known for n in names):
        raise argparse.ArgumentTypeError(f"pipelines must be among {known}, got {text!r}")
    return tuple(Pipeline(n) for n in dict.fromkeys(names))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the end-to-end bench; returns the exit status."""
    parser = argparse.ArgumentParser(prog="crawler-motion bench --e2e",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=parse_rates, default=RATES,
                        help="command rates [Hz], comma-separated (default 100,200,500,1000)")
    parser.add_argument("--pipelines", type=parse_pipelines, default=tuple(Pipeline),
                        help="comma-separated: two-node, controller (default both)")
    parser.add_argument("--seconds", type=float, default=15.0,
                        help="measured walking time per rate [s] (default 15)")
    add_gait_option(parser)
    parser.add_argument("--tick-priority", type=int, default=0,
                        help="the planner's tick_priority (1-99: SCHED_FIFO tick thread, "
                             "the planner and driver processes one below; default 0: normal "
                             "scheduling)")
    parser.add_argument("--no-floor", dest="floor", action="store_false",
                        help="skip the machine's floor (a bare ticker process, as long as "
                             "each run, before each rate)")
    args = parser.parse_args(argv)
    if not 0 <= args.tick_priority <= 99:
        parser.error(f"--tick-priority must be in [0, 99], got {args.tick_priority}")
    if not (math.isfinite(args.seconds) and args.seconds > 0):
        parser.error(f"--seconds must be > 0, got {args.seconds}")
    t_start = time.monotonic()

    def say(line: str) -> None:
        print(f"[{time.monotonic() - t_start:6.1f} s] {line}", file=sys.stderr, flush=True)

    results, floors = [], {}
    try:
        for rate in args.rates:
            if args.floor:
                say(f"floor {rate:g} Hz: a bare ticker process for {args.seconds:g} s")
                try:
                    floors[rate] = wake_floor.measure(rate, args.seconds)
                except RuntimeError as exc:
                    say(f"floor {rate:g} Hz: error: {exc}")
            for pipeline in args.pipelines:
                results.append(bench_rate(rate, args.seconds, gait=args.gait, say=say,
                                          tick_priority=args.tick_priority,
                                          pipeline=pipeline))
    except KeyboardInterrupt:
        return 130
    print_table(results, args.seconds, floors)
    return 1 if any(r.timing is None for r in results) else 0


if __name__ == "__main__":
    raise SystemExit(main())
