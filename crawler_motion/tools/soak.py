"""Soak test: the whole stack walking continuously on the cross-process bus for a long time.

Starts the simulated motor manager, the driver (autostart) and the planner (parameter ``rate``)
as separate processes on a fresh python-can ``udp_multicast`` port and a ROS domain of their own
(`e2e_stack.Stack`), stands, walks without a step count (``{"command": "walk"}``: until
stopped) for ``--duration`` seconds, stops and checks that the planner ends STANDING. A one-line
progress report every ``--progress`` seconds; a Markdown report at the end.

What is measured (the observers are this process's subscribers and a passive bus listener in a
child process, `e2e_records.TapProcess`):

- joint_commands received here vs target frame groups on the bus (4 target frames, one counter
  per tick), matched in order by their decoded positions (`e2e_analysis.match_groups`); a command
  stamped before the planner was stopped (minus 0.2 s) without a group is counted;
- the chain's own counters: the driver's (/diagnostics "CAN bus": commands accepted, stale /
  refused / blocked drops, send errors, watchdog trips) and the simulated manager's (printed at
  its exit: target frames applied / rejected), against the frames seen on the bus per family;
- tracking error: the driver's measured joint_states against the commanded trajectory, see
  `tracking_errors` (how the lag is accounted for is printed with the figures);
- the planner's ``late_ticks`` and ``missed_ticks`` (planner_status) and the gaps in the
  header stamps;
- VmRSS (/proc/<pid>/status) of planner, driver, manager, the bus listener and this process
  after the warm-up and at the end, and CPU over the same interval.

A command superseded in the driver's depth-1 queue (the driver was busy when the next one
arrived) is reported, not failed: by design the newest command wins and a late one is never
sent. *Lost* is a command the driver accepted whose frames never reached the bus or the manager.

Exit status 0 when nothing was lost or dropped, no watchdog tripped, the planner walked
without interruption (never left WALKING, never paused) and ended STANDING; 1 otherwise; 2 on
bad options.

Run: crawler-motion soak --rate 200 --duration 600   (``make soak``)
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.testing.stack import STACK_COMMAND_TIMEOUT
from crawler_motion.tools.args import add_gait_option
from crawler_motion.tools.console import describe
from crawler_motion.tools.e2e_analysis import PLANNER_COUNTERS, counters_text, planner_counters
from crawler_motion.tools.e2e_stack import Stack
from crawler_motion.tools.soak_report import (
    ALL_PROCESSES,
    DRIVER_DROPS,
    SoakRun,
    mib,
    report,
)

PROG = "crawler-motion soak"


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """The soak's options, checked (exit 2 on bad ones)."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=200.0, help="planner rate [Hz]")
    parser.add_argument("--duration", type=float, default=600.0,
                        help="walking time [s] (default 600)")
    parser.add_argument("--warmup", type=float, default=10.0,
                        help="walking time before the first memory/CPU sample [s]")
    parser.add_argument("--progress", type=float, default=30.0,
                        help="period of the progress line [s]")
    add_gait_option(parser)
    parser.add_argument("--command-timeout", type=float, default=STACK_COMMAND_TIMEOUT,
                        help="the driver's command watchdog [s] (default: the demo's, "
                             f"{STACK_COMMAND_TIMEOUT:g})")
    parser.add_argument("--max-lag", type=float, default=0.2,
                        help="largest lag tried when fitting the tracking lag [s]")
    parser.add_argument("--save", type=Path, default=None,
                        help="also write the records (commands, joint_states, frame groups, "
                             "times) to this .npz for offline analysis")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.rate) and 1.0 <= args.rate <= 1000.0):
        parser.error(f"--rate must be in [1, 1000] Hz, got {args.rate}")
    for name in ("duration", "warmup", "progress", "max_lag"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            parser.error(f"--{name.replace('_', '-')} must be > 0, got {value}")
    if args.warmup >= args.duration:
        parser.error("--warmup must be shorter than --duration")
    if not 0.02 <= args.command_timeout <= 10.0:
        parser.error("--command-timeout must be in [0.02, 10] s")
    return args


class Watch:
    """Planner status callback: records every episode out of WALKING (or paused) while
    ``walking`` is set."""

    def __init__(self, say: Callable[[str], None], t_start: float) -> None:
        self.say = say
        self.t_start = t_start
        self.walking = False
        self.abnormal = False
        self.anomalies: list[str] = []

    def __call__(self, status: dict[str, Any]) -> None:
        if not self.walking:
            return
        bad = status.get("state") != "WALKING" or bool(status.get("paused"))
        if bad:
            self.say(f"ANOMALY: planner {describe(status)}")
            if not self.abnormal:
                self.anomalies.append(f"{time.monotonic() - self.t_start:.1f} s: "
                                      f"{describe(status)}")
        elif self.abnormal:
            self.say(f"planner back to {describe(status)}")
        self.abnormal = bad


def sample(stack: Stack) -> dict[str, Any]:
    """Memory, CPU, wall time and planner tick counters now."""
    return {"rss": stack.rss(), "cpu": stack.cpu(), "t": time.time(),
            "late": planner_counters(stack.status)}


def walk(args: argparse.Namespace, stack: Stack, say: Callable[[str], None]
         ) -> dict[str, Any]:
    """Spin for ``--duration`` while walking, with the warm-up sample and progress lines;
    returns the warm-up sample (empty if the walk ended before it)."""
    t_walk = time.monotonic()
    warm: dict[str, Any] = {}
    next_progress = t_walk + args.progress
    last = (t_walk, 0)
    while (now := time.monotonic()) < t_walk + args.duration:
        stack.spin(min(0.2, t_walk + args.duration - now))
        now = time.monotonic()
        if not warm and now >= t_walk + args.warmup:
            warm = {**sample(stack), "diag": stack.diag}
            say("warm-up done: VmRSS [MiB] " + ", ".join(
                f"{n} {mib(v)}" for n, v in warm["rss"].items()))
        if now >= next_progress:
            next_progress += args.progress
            last = progress(stack, t_walk, last, say)
    return warm


def run(args: argparse.Namespace, stack: Stack, watch: Watch, say: Callable[[str], None]
        ) -> SoakRun:
    """Start the stack, stand, walk for ``--duration``, stop and collect the records."""
    stack.start()
    say(f"stack up on udp_multicast port {stack.port}, ROS domain {stack.domain}; pids "
        + ", ".join(f"{n} {p}" for n, p in stack.pids().items()))
    say(f"stand: {stack.command({'command': 'stand'})}")
    say(f"walk: {stack.command({'command': 'walk'})}")
    watch.walking = True
    t_walk_wall = time.time()
    warm = walk(args, stack, say)
    watch.walking = False
    state_before_stop = describe(stack.status)
    end = sample(stack)
    say(f"stop (planner {state_before_stop})")
    t_stop_wall = time.time()
    say(f"stop: {stack.command({'command': 'stop'})}")
    stack.spin(0.5)
    final_state = str(stack.status.get("state"))
    return SoakRun(t_walk_wall, t_stop_wall, warm, end, watch.anomalies, final_state,
                   stack.finish())


def save(path: Path, stack: Stack, result: SoakRun) -> None:
    """Write the records to an .npz for offline analysis."""
    np.savez_compressed(path, commands=stack.commands.array(),
                        states=stack.states.array(), groups=result.done.tap.groups,
                        times=np.array([result.t_walk, result.t_stop, result.done.t_cut,
                                        result.warm.get("t", math.nan)]))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the soak test (``--mission``: the mission soak with faults); the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if any(a == "--mission" or a.startswith("--mission=") for a in argv):
        from crawler_motion.tools.mission_soak_cli import main as mission_soak

        return mission_soak(argv)
    args = parse_args(argv)
    t_start = time.monotonic()

    def say(line: str) -> None:
        print(f"[{time.monotonic() - t_start:7.1f} s] {line}", flush=True)

    stack = Stack(args.rate, gait=args.gait, command_timeout=args.command_timeout)
    watch = Watch(say, t_start)
    stack.on_status = watch
    try:
        say(f"soak: {args.duration:g} s walking at {args.rate:g} Hz ({args.gait}); starting "
            f"the stack (logs in {stack.logs})")
        result = run(args, stack, watch, say)
    except (RuntimeError, OSError) as exc:
        print(f"soak: error: {exc}\n{stack.log_tails()}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        stack.close()
    if args.save is not None:
        save(args.save, stack, result)
        say(f"records written to {args.save}")
    failures = report(args, stack, result)
    if failures:
        print("\n**FAILED**: " + "; ".join(failures))
        return 1
    print("\n**PASSED**: nothing lost, no watchdog trip, walked without interruption, ended "
          "STANDING")
    return 0


def progress(stack: Stack, t_walk: float, last: tuple[float, int], say: Any
             ) -> tuple[float, int]:
    """Print one progress line; returns (time, commands) for the next rate figure."""
    now = time.monotonic()
    n = len(stack.commands)
    rate = (n - last[1]) / max(now - last[0], 1e-9)
    assert stack.tap is not None
    counts, groups = stack.tap.counts()
    diag = stack.diag
    drops = sum(diag.n(k) for k in DRIVER_DROPS)
    status = stack.status
    zero = dict.fromkeys(PLANNER_COUNTERS, 0)
    rss = stack.rss()
    say(f"{now - t_walk:6.0f} s walking | {describe(status)} | joint_commands {n} "
        f"({rate:.1f} Hz) | bus groups {groups} ({counts.get('target', 0)} target frames) | "
        f"driver accepted {diag.n('commands')}, drops {drops}, trips "
        f"{diag.n('watchdog_trips')} | late / missed ticks "
        f"{counters_text(zero, planner_counters(status))} | VmRSS MiB "
        + " ".join(f"{k} {mib(rss.get(k))}" for k in ALL_PROCESSES))
    return now, n


if __name__ == "__main__":
    raise SystemExit(main())
