"""The soak test's figures and Markdown report: losses, counters, tracking error, memory."""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from crawler_motion.tools.e2e_analysis import (
    PLANNER_COUNTERS,
    PeriodStats,
    counters_text,
    fmt,
    match_groups,
    percentile,
    period_stats,
    tolerance_rad,
)
from crawler_motion.tools.e2e_records import GROUP_FRAMES, GROUP_T, REC_Q, REC_STAMP
from crawler_motion.tools.e2e_stack import PROCESSES, Finish, Stack
from crawler_motion.tools.procstat import cpu_percent

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
    """A size [MiB] for a table ('-' for None)."""
    return "-" if value is None else f"{value:.1f}"


@dataclass
class SoakRun:
    """What a soak run hands to the report: the wall-clock times [s] of the walk's start and of
    the stop command, the samples after the warm-up and at the end (``rss``, ``cpu``, ``t``,
    ``late``), the planner episodes out of WALKING, its final state and the final records."""

    t_walk: float
    t_stop: float
    warm: dict[str, Any]
    end: dict[str, Any]
    anomalies: list[str]
    final_state: str
    done: Finish


@dataclass
class Figures:
    """The soak's figures computed from the records."""

    commands: np.ndarray
    states: np.ndarray
    groups: np.ndarray
    checked: np.ndarray  # commands stamped before the stop - CUT_MARGIN
    walk: np.ndarray  # commands stamped while walking
    lost: int  # checked commands without a frame group
    orphans: int  # checked groups without a command here
    partial: int  # groups with fewer than 4 frames
    latency: np.ndarray  # per command [ms]
    timing: PeriodStats
    track: Tracking | None
    drops: dict[str, int] = field(default_factory=dict)
    accepted: int = 0
    trips: int = 0

    @property
    def never(self) -> int:
        """Commands superseded before the driver's callback (received here + observer misses -
        accepted - driver drops)."""
        return len(self.commands) + self.orphans - self.accepted - sum(self.drops.values())


def figures(args: argparse.Namespace, stack: Stack, run: SoakRun) -> Figures:
    """The figures of ``run`` (``args``: the soak's options)."""
    done = run.done
    commands = stack.commands.array()
    commands = commands[np.argsort(commands[:, REC_STAMP], kind="stable")]
    states = stack.states.array()
    groups = done.tap.groups
    matching = match_groups(commands, groups, tolerance_rad())
    stamps = commands[:, REC_STAMP]
    checked = stamps <= done.t_cut - CUT_MARGIN
    g_checked = groups[:, GROUP_T] <= done.t_cut - CUT_MARGIN
    after = done.after
    window = (stamps >= run.warm.get("t", run.t_walk)) & (stamps <= run.t_stop)
    return Figures(
        commands, states, groups, checked,
        (stamps >= run.t_walk) & (stamps <= run.t_stop),
        int(np.count_nonzero(matching.command_group[checked] < 0)),
        int(np.count_nonzero(matching.group_command[g_checked] < 0)),
        int(np.count_nonzero(groups[:, GROUP_FRAMES] < 4)),
        matching.latency(commands, groups) * 1e3,
        period_stats(stamps[window], args.rate),
        tracking_errors(commands, states, run.t_walk + 1.0, run.t_stop,
                        args.max_lag),
        {k: after.n(k) for k in DRIVER_DROPS}, after.n("commands"),
        done.before.n("watchdog_trips"))


def print_chain(args: argparse.Namespace, run: SoakRun, fig: Figures) -> None:
    """The head of the summary table: where the commands went, latency."""
    t_walk, t_stop, done = run.t_walk, run.t_stop, run.done
    commands, groups, walk, checked = fig.commands, fig.groups, fig.walk, fig.checked
    lost, orphans, partial, latency = fig.lost, fig.orphans, fig.partial, fig.latency
    drops, accepted, never = fig.drops, fig.accepted, fig.never
    after, sim, tap = done.after, done.sim, done.tap
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


def print_state(args: argparse.Namespace, stack: Stack, run: SoakRun, fig: Figures) -> None:
    """The tail of the summary table: tracking, watchdog, ticks, planner state."""
    track, trips, timing, warm, end = fig.track, fig.trips, fig.timing, run.warm, run.end
    anomalies, final_state = run.anomalies, run.final_state
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



def print_frames(run: SoakRun, fig: Figures) -> None:
    """Frames on the bus per family against the endpoints' counters."""
    t_walk, t_stop, accepted = run.t_walk, run.t_stop, fig.accepted
    after, sim, tap = run.done.after, run.done.sim, run.done.tap
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
    fb = sum(c.get(k, 0) for k in ("effort", "position", "status", "heartbeat"))
    print(f"| effort / position / status / heartbeat (manager -> driver) | "
          f"{c.get('effort', 0)} / {c.get('position', 0)} / "
          f"{c.get('status', 0)} / {c.get('heartbeat', 0)} (sum {fb}, "
          f"{fb / span:.0f}/s over the walk) | manager sent {sim.get('sent', '-')} (all, "
          f"until its exit) | driver rx {after.n('rx')} (incl. {after.n('rx_ignored')} "
          f"ignored: its own frames, which udp_multicast loops back), "
          f"{after.n('feedback')} complete joint states |")
    if c.get("other", 0):
        print(f"| other ids | {c['other']} | | |")
    print("\nThe listener stops after the driver's final /diagnostics; the manager's counters "
          "are printed at its exit, a little later, so its feedback count is larger.")



def print_memory(args: argparse.Namespace, run: SoakRun, fig: Figures) -> None:
    """Memory and CPU per process, and how the tracking error is measured."""
    warm, end, track = run.warm, run.end, fig.track
    commands, states, groups = fig.commands, fig.states, fig.groups
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



def failures(run: SoakRun, fig: Figures) -> list[str]:
    """The reasons for failing (empty: passed)."""
    failures: list[str] = []
    before, after, sim, tap = run.done.before, run.done.after, run.done.sim, run.done.tap
    accepted, lost, never, drops, trips = fig.accepted, fig.lost, fig.never, fig.drops, fig.trips
    anomalies, final_state = run.anomalies, run.final_state
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


def report(args: argparse.Namespace, stack: Stack, run: SoakRun) -> list[str]:
    """Print the Markdown report; returns the reasons for failing (empty: passed)."""
    fig = figures(args, stack, run)
    print_chain(args, run, fig)
    print_state(args, stack, run, fig)
    print_frames(run, fig)
    print_memory(args, run, fig)
    return failures(run, fig)
