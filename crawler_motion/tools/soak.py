"""Soak test: the whole stack walking continuously on the cross-process bus for a long time.

Starts the simulated motor manager, the driver (autostart) and the planner (parameter ``rate``)
as separate processes on a fresh python-can ``udp_multicast`` port and a ROS domain of their own
(`bench_e2e.Stack`), stands, walks without a step count (``{"command": "walk"}``: until
stopped) for ``--duration`` seconds, stops and checks that the planner ends STANDING. A one-line
progress report every ``--progress`` seconds; a Markdown report at the end.

What is measured (the observers are this process's subscribers and a passive bus listener in a
child process, `bench_e2e.TapProcess`):

- joint_commands received here vs target frame groups on the bus (4 target frames, one counter
  per tick), matched in order by their decoded positions (`bench_e2e.match_groups`); a command
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

Run: python scripts/soak.py --rate 200 --duration 600   (``make soak``)
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.tools.bench_e2e import (
    GROUP_FRAMES,
    GROUP_T,
    PLANNER_COUNTERS,
    PROCESSES,
    REC_Q,
    REC_STAMP,
    Finish,
    Stack,
    counters_text,
    cpu_percent,
    fmt,
    match_groups,
    percentile,
    period_stats,
    planner_counters,
    tolerance_rad,
)
from crawler_motion.tools.console import describe
from crawler_motion.tools.demo import DEMO_COMMAND_TIMEOUT

#: Commands stamped this close to the planner's stop are not checked (they may be in flight).
CUT_MARGIN = 0.2
#: Tracking error: lags tried [s] (the one minimising the RMS error is used).
LAG_STEP = 0.001
#: Measured samples used to fit the lag (evenly spread; all samples are used for the figures).
LAG_FIT_SAMPLES = 5000
#: Driver counters that are drops of joint commands.
DRIVER_DROPS = ("tx_stale", "refused", "blocked", "inactive")
ALL_PROCESSES = (*PROCESSES, "tap", "self")


@dataclass(frozen=True)
class Tracking:
    """Tracking error over the measured samples of a window, without and with the lag."""

    samples: int
    lag: float  # fitted constant lag [s]
    raw_max: float  # max over samples of max over joints |measured - command(t)| [rad]
    raw_p99: float
    lag_max: float  # the same against command(t - lag)
    lag_p99: float
    lag_rms: float  # RMS over samples and joints at the lag [rad]


def tracking_errors(commands: np.ndarray, states: np.ndarray, t0: float, t1: float,
                    max_lag: float) -> Tracking | None:
    """Measured joint_states against the commanded trajectory, stamps in [t0, t1].

    Both stamps are the system clock: the command's is set by the planner when it publishes,
    the measurement's by the driver when a complete position cycle has arrived. The commanded
    trajectory q_c(t) interpolates the commands linearly between their stamps. Per measured
    sample the error is max over the 12 joints of |q_measured(t) - q_c(t - L)|. L = 0 gives
    the raw error, which includes the whole pipeline delay times the joint speed; the lagged
    figures use the one constant L in [0, ``max_lag``] (1 ms grid) that minimises the RMS error
    over the window (not a per-sample best fit, which would hide real deviations).
    """
    cs = commands[:, REC_STAMP]
    cq = commands[:, REC_Q:]
    sel = (states[:, REC_STAMP] >= t0) & (states[:, REC_STAMP] <= t1)
    ts, qs = states[sel, REC_STAMP], states[sel, REC_Q:]
    if ts.size == 0 or cs.size < 2:
        return None

    def residual(lag: float, idx: Any = slice(None)) -> np.ndarray:
        t = ts[idx] - lag
        predicted = np.column_stack([np.interp(t, cs, cq[:, j]) for j in range(cq.shape[1])])
        return np.abs(qs[idx] - predicted)

    sub = np.unique(np.linspace(0, ts.size - 1, min(ts.size, LAG_FIT_SAMPLES)).astype(int))
    lags = np.arange(0.0, max_lag + LAG_STEP / 2, LAG_STEP)
    rms = [float(np.sqrt(np.mean(residual(lag, sub) ** 2))) for lag in lags]
    lag = float(lags[int(np.argmin(rms))])
    raw = residual(0.0).max(axis=1)
    lagged_all = residual(lag)
    lagged = lagged_all.max(axis=1)
    return Tracking(int(ts.size), lag, float(raw.max()), percentile(raw, 99),
                    float(lagged.max()), percentile(lagged, 99),
                    float(np.sqrt(np.mean(lagged_all ** 2))))


def mib(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the soak test; returns the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=200.0, help="planner rate [Hz]")
    parser.add_argument("--duration", type=float, default=600.0,
                        help="walking time [s] (default 600)")
    parser.add_argument("--warmup", type=float, default=10.0,
                        help="walking time before the first memory/CPU sample [s]")
    parser.add_argument("--progress", type=float, default=30.0,
                        help="period of the progress line [s]")
    parser.add_argument("--gait", choices=("diagonal", "wave"), default="diagonal")
    parser.add_argument("--command-timeout", type=float, default=DEMO_COMMAND_TIMEOUT,
                        help="the driver's command watchdog [s] (default: the demo's, "
                             f"{DEMO_COMMAND_TIMEOUT:g})")
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

    t_start = time.monotonic()

    def say(line: str) -> None:
        print(f"[{time.monotonic() - t_start:7.1f} s] {line}", flush=True)

    stack = Stack(args.rate, gait=args.gait, command_timeout=args.command_timeout)
    anomalies: list[str] = []  # episodes: WALKING and not paused -> anything else
    walking = [False]
    abnormal = [False]

    def watch(status: dict[str, Any]) -> None:
        if not walking[0]:
            return
        bad = status.get("state") != "WALKING" or bool(status.get("paused"))
        if bad:
            say(f"ANOMALY: planner {describe(status)}")
            if not abnormal[0]:
                anomalies.append(f"{time.monotonic() - t_start:.1f} s: {describe(status)}")
        elif abnormal[0]:
            say(f"planner back to {describe(status)}")
        abnormal[0] = bad

    stack.on_status = watch
    try:
        say(f"soak: {args.duration:g} s walking at {args.rate:g} Hz ({args.gait}); starting "
            f"the stack (logs in {stack.logs})")
        stack.start()
        say(f"stack up on udp_multicast port {stack.port}, ROS domain {stack.domain}; pids "
            + ", ".join(f"{n} {p}" for n, p in stack.pids().items()))
        say(f"stand: {stack.command({'command': 'stand'})}")
        say(f"walk: {stack.command({'command': 'walk'})}")
        walking[0] = True
        t_walk = time.monotonic()
        t_walk_wall = time.time()
        warm: dict[str, Any] = {}
        next_progress = t_walk + args.progress
        last = (t_walk, 0)
        while (now := time.monotonic()) < t_walk + args.duration:
            stack.spin(min(0.2, t_walk + args.duration - now))
            now = time.monotonic()
            if not warm and now >= t_walk + args.warmup:
                warm = {"rss": stack.rss(), "cpu": stack.cpu(), "t": time.time(),
                        "late": planner_counters(stack.status), "diag": stack.diag}
                say("warm-up done: VmRSS [MiB] " + ", ".join(
                    f"{n} {mib(v)}" for n, v in warm["rss"].items()))
            if now >= next_progress:
                next_progress += args.progress
                last = progress(stack, t_walk, last, say)
        walking[0] = False
        state_before_stop = describe(stack.status)
        end = {"rss": stack.rss(), "cpu": stack.cpu(), "t": time.time(),
               "late": planner_counters(stack.status)}
        say(f"stop (planner {state_before_stop})")
        t_stop_wall = time.time()
        final = stack.command({"command": "stop"})
        say(f"stop: {final}")
        stack.spin(0.5)
        final_state = str(stack.status.get("state"))
        done = stack.finish()
    except (RuntimeError, OSError) as exc:
        print(f"soak: error: {exc}\n{stack.log_tails()}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        stack.close()
    if args.save is not None:
        np.savez_compressed(args.save, commands=stack.commands.array(),
                            states=stack.states.array(), groups=done.tap.groups,
                            times=np.array([t_walk_wall, t_stop_wall, done.t_cut,
                                            warm.get("t", math.nan)]))
        say(f"records written to {args.save}")
    failures = report(args, stack, done, warm, end, t_walk_wall, t_stop_wall, anomalies,
                      final_state)
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


def report(args: argparse.Namespace, stack: Stack, done: Finish, warm: dict[str, Any],
           end: dict[str, Any], t_walk: float, t_stop: float, anomalies: list[str],
           final_state: str) -> list[str]:
    """Print the Markdown report; returns the reasons for failing (empty: passed)."""
    failures: list[str] = []
    commands = stack.commands.array()
    commands = commands[np.argsort(commands[:, REC_STAMP], kind="stable")]
    states = stack.states.array()
    groups = done.tap.groups
    matching = match_groups(commands, groups, tolerance_rad())
    stamps = commands[:, REC_STAMP]
    checked = stamps <= done.t_cut - CUT_MARGIN
    lost = int(np.count_nonzero(matching.command_group[checked] < 0))
    g_checked = groups[:, GROUP_T] <= done.t_cut - CUT_MARGIN
    orphans = int(np.count_nonzero(matching.group_command[g_checked] < 0))
    partial = int(np.count_nonzero(groups[:, GROUP_FRAMES] < 4))
    latency = matching.latency(commands, groups) * 1e3
    walk = (stamps >= t_walk) & (stamps <= t_stop)
    timing = period_stats(stamps[(stamps >= warm.get("t", t_walk)) & (stamps <= t_stop)],
                          args.rate)
    before, after, sim, tap = done.before, done.after, done.sim, done.tap
    drops = {k: after.n(k) for k in DRIVER_DROPS}
    accepted = after.n("commands")
    trips = before.n("watchdog_trips")
    track = tracking_errors(commands, states, t_walk + 1.0, t_stop, args.max_lag)

    print(f"\n## Soak: {t_stop - t_walk:.0f} s walking at {args.rate:g} Hz ({args.gait} gait), "
          f"driver watchdog {args.command_timeout:g} s; {os.cpu_count()} CPUs, load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}\n")
    print("| what | value | note |")
    print("|---|---|---|")
    print(f"| joint_commands received here | {len(commands)} | whole run (stand, walk, stop); "
          f"{int(np.count_nonzero(walk))} while walking |")
    print(f"| target frame groups on the bus | {len(groups)} | {partial} with fewer than 4 "
          f"frames seen by the listener |")
    print(f"| driver: commands accepted | {accepted} | /diagnostics after the planner stopped |")
    never = len(commands) + orphans - accepted - sum(drops.values())
    print(f"| commands without a frame group | {lost} | of "
          f"{int(np.count_nonzero(checked))} stamped before the stop - {CUT_MARGIN:g} s |")
    print(f"| of which superseded before the driver's callback | {never} "
          f"({100.0 * never / max(1, len(commands)):.2f} %) | received here + observer misses "
          f"- accepted - driver drops, whole run: the driver's joint_commands queue is depth-1 "
          f"best effort by design (the newest command wins; a late one is never sent) |")
    print(f"| frame groups without a command here | {orphans} | observer misses of this "
          f"process's subscriber (not product losses) |")
    print(f"| driver drops (stale / refused / blocked / inactive) | "
          f"{' / '.join(str(v) for v in drops.values())} | tx_errors {after.n('tx_errors')}, "
          f"rx_dropped {after.n('rx_dropped')}, bus failures {after.n('bus_failures')} |")
    print(f"| target frames: 4 x accepted / on the bus / applied by the manager / rejected | "
          f"{4 * accepted} / {tap.counts.get('target', 0)} / {sim.get('targets', '-')} / "
          f"{sim.get('rejected', '-')} | manager counters from its exit line |")
    print(f"| JointState -> CAN latency p50 / p99 / max | {fmt(percentile(latency[walk], 50))} "
          f"/ {fmt(percentile(latency[walk], 99))} / "
          f"{fmt(float(np.nanmax(latency[walk])) if np.isfinite(latency[walk]).any() else None)}"
          f" ms | first target frame (kernel receive time) - header stamp, while walking |")
    if track is None:
        print("| tracking error | - | no measured samples while walking |")
    else:
        print(f"| tracking error, same instant: worst / p99 | {track.raw_max:.4f} / "
              f"{track.raw_p99:.4f} rad | includes the pipeline delay x joint speed |")
        print(f"| tracking error, lag {track.lag * 1e3:.0f} ms removed: worst / p99 (RMS) | "
              f"{track.lag_max:.4f} / {track.lag_p99:.4f} ({track.lag_rms:.4f}) rad | "
              f"{track.samples} joint_states samples; see below |")
    print(f"| driver watchdog trips | {trips} | before the planner was stopped |")
    zero = dict.fromkeys(PLANNER_COUNTERS, 0)
    print(f"| planner late / missed ticks after the warm-up (whole run) | "
          f"{counters_text(warm.get('late', {}), end['late'])} "
          f"({counters_text(zero, end['late'])}) | planner_status: gaps > 1.5 periods "
          f"between ticks / deadlines its ticker thread skipped |")
    print(f"| stamp gaps > 1.5 periods after the warm-up | {timing.missed} | longest "
          f"{fmt(timing.longest_gap_ms, 1)} ms; achieved {fmt(timing.rate, 2)} Hz; period "
          f"error p50 / p99 {fmt(timing.err_p50_ms, 3)} / {fmt(timing.err_p99_ms, 3)} ms |")
    print(f"| episodes out of WALKING or paused while walking | {len(anomalies)} | "
          f"{'; '.join(anomalies[:5]) or 'never'} |")
    print(f"| final state | {final_state} | after `stop` |")
    if stack.bad_messages:
        print(f"| JointState messages ignored here | {stack.bad_messages} | names or lengths "
              f"not the 12 joints |")

    print("\n### Frames on the bus per family (passive listener) and the endpoints' counters\n")
    span = max(t_stop - t_walk, 1e-9)
    print("| family | frames on the bus | sender's counter | receiver's counter |")
    print("|---|---|---|---|")
    c = tap.counts
    print(f"| target (driver -> manager) | {c.get('target', 0)} | 4 x {accepted} accepted "
          f"commands | {sim.get('targets', '-')} applied, {sim.get('rejected', '-')} "
          f"rejected |")
    print(f"| control (driver -> manager) | {c.get('control', 0)} | driver tx {after.n('tx')} "
          f"(all frames) | manager received {sim.get('received', '-')} (all frames, "
          f"incl. {sim.get('ignored', '-')} ignored: mostly its own, looped back), "
          f"{sim.get('commands', '-')} control |")
    fb = sum(c.get(k, 0) for k in ("position", "status", "heartbeat"))
    print(f"| position / status / heartbeat (manager -> driver) | {c.get('position', 0)} / "
          f"{c.get('status', 0)} / {c.get('heartbeat', 0)} (sum {fb}, "
          f"{fb / span:.0f}/s over the walk) | manager sent {sim.get('sent', '-')} (all, "
          f"until its exit) | driver rx {after.n('rx')} (incl. {after.n('rx_ignored')} "
          f"ignored: its own frames, which udp_multicast loops back), "
          f"{after.n('feedback')} complete joint states |")
    if c.get("other", 0):
        print(f"| other ids | {c['other']} | | |")
    print("\nThe listener stops after the driver's final /diagnostics; the manager's counters "
          "are printed at its exit, a little later, so its feedback count is larger.")

    print("\n### Memory (VmRSS, MiB) and CPU (% of one core) from the warm-up to the end\n")
    print("| process | after warm-up | end | growth | growth per hour | CPU % |")
    print("|---|---|---|---|---|---|")
    cpu = cpu_percent(warm["cpu"], end["cpu"]) if warm else {}
    hours = max(end["t"] - warm.get("t", end["t"]), 1e-9) / 3600.0
    for name in ALL_PROCESSES:
        r0, r1 = (warm.get("rss") or {}).get(name), end["rss"].get(name)
        growth = r1 - r0 if r0 is not None and r1 is not None else None
        label = {"tap": "bus listener (soak)", "self": "soak process"}.get(name, name)
        print(f"| {label} | {mib(r0)} | {mib(r1)} | {mib(growth)} | "
              f"{mib(growth / hours if growth is not None else None)} | "
              f"{fmt(cpu.get(name), 0)} |")
    kept = (len(commands) + len(states)) * commands.shape[1] * 8 / 2**20
    kept_tap = groups.size * 8 / 2**20
    print(f"\nThe soak process and the bus listener keep every record for the final analysis "
          f"(allocated in chunks of 16384 rows): {kept:.1f} MiB of joint_commands + "
          f"joint_states here and {kept_tap:.1f} MiB of frame groups in the listener by the "
          f"end, so their growth is expected; the stack's processes keep nothing of the kind.")
    if track is not None:
        print(f"\nTracking error: per measured sample (the driver's joint_states, stamped on "
              f"reception of a complete position cycle), max over the 12 joints of |measured - "
              f"commanded(t - L)|; the commanded trajectory interpolates the planner's "
              f"joint_commands linearly between their header stamps (same system clock). L = 0 "
              f"is the raw error; L = {track.lag * 1e3:.0f} ms is the one constant lag in "
              f"[0, {args.max_lag * 1e3:.0f}] ms minimising the RMS error over the walk "
              f"(command -> CAN -> the manager's 10 ms step -> its 100 Hz feedback -> driver); "
              f"window: 1 s after the walk started to the stop.")

    on_bus = tap.counts.get("target", 0)
    if on_bus < 4 * accepted:
        failures.append(f"{4 * accepted - on_bus} target frames accepted by the driver never "
                        f"reached the bus")
    if lost > never:
        failures.append(f"{lost} commands without a frame group, more than the {never} "
                        f"superseded before the driver")
    if any(drops.values()) or after.n("tx_errors"):
        failures.append(f"driver drops {drops}, tx_errors {after.n('tx_errors')}")
    if sim.get("rejected", 0) or sim.get("send_errors", 0):
        failures.append(f"manager rejected {sim.get('rejected')}, send errors "
                        f"{sim.get('send_errors')}")
    if sim.get("targets", -1) != 4 * accepted:
        failures.append(f"manager applied {sim.get('targets')} target frames, driver accepted "
                        f"{accepted} commands (x 4 = {4 * accepted}; "
                        f"{tap.counts.get('target', 0)} on the bus)")
    if trips:
        failures.append(f"{trips} driver watchdog trips")
    if anomalies:
        failures.append(f"planner left WALKING or paused {len(anomalies)} times")
    if final_state != "STANDING":
        failures.append(f"final state {final_state}, not STANDING")
    if not before.bus:
        failures.append("no /diagnostics from the driver")
    return failures


if __name__ == "__main__":
    raise SystemExit(main())
