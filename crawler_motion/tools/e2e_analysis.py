"""Analysis of end-to-end records: commands matched to frame groups, period and tick figures."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from crawler_motion.tools.e2e_records import (
    GROUP_FRAMES,
    GROUP_Q,
    GROUP_T,
    GROUP_T_USER,
    REC_Q,
    REC_STAMP,
)

if TYPE_CHECKING:
    from crawler_motion.tools.e2e_stack import Finish

#: A stamp gap longer than this many periods is a missed tick.
MISSED_GAP_PERIODS = 1.5
#: Tick counters of planner_status: gaps between ticks > 1.5 periods (PlannerCore) and
#: deadlines the ticker thread skipped (absent from planners without one).
PLANNER_COUNTERS = ("late_ticks", "missed_ticks")


def planner_counters(status: dict[str, Any]) -> dict[str, int]:
    """The `PLANNER_COUNTERS` a planner status carries."""
    return {k: int(status[k]) for k in PLANNER_COUNTERS if isinstance(status.get(k), int)}


def counters_text(before: dict[str, int], after: dict[str, int]) -> str:
    """'late / missed' differences ('-' where a counter is absent)."""
    return " / ".join(str(after[k] - before[k]) if k in after and k in before else "-"
                      for k in PLANNER_COUNTERS)


@dataclass
class Matching:
    """Commands matched to target frame groups (indices into the sorted commands / groups)."""

    command_group: np.ndarray  # per command: index of its group, -1 if none
    group_command: np.ndarray  # per group: index of its command, -1 if none

    def latency(self, commands: np.ndarray, groups: np.ndarray) -> np.ndarray:
        """Per command: first-frame kernel time - header stamp [s] (NaN when unmatched)."""
        out = np.full(len(commands), math.nan)
        ok = self.command_group >= 0
        out[ok] = groups[self.command_group[ok], GROUP_T] - commands[ok, REC_STAMP]
        return out


def match_groups(commands: np.ndarray, groups: np.ndarray, tolerance: float,
                 max_age: float = 1.0, slack: float = 0.002) -> Matching:
    """Match the target frame groups, in bus order, to the commands (sorted by stamp).

    A group is given the earliest not yet matched command after the previous match whose
    positions equal the group's decoded ones within ``tolerance`` [rad] (joints of frames the
    listener missed are skipped) and whose stamp lies in [group time - ``max_age``, group time
    + ``slack``] (the driver never sends a command later than one target period; the stamp
    precedes the frame on the same clock). In-order matching keeps identical consecutive
    commands (standing) apart.
    """
    stamps = commands[:, REC_STAMP]
    q = commands[:, REC_Q:]
    n = len(commands)
    command_group = np.full(n, -1, dtype=np.int64)
    group_command = np.full(len(groups), -1, dtype=np.int64)
    p = 0
    for j in range(len(groups)):
        t = groups[j, GROUP_T]
        g = groups[j, GROUP_Q:]
        seen = ~np.isnan(g)
        i = max(p, int(np.searchsorted(stamps, t - max_age)))
        while i < n and stamps[i] <= t + slack:
            if np.all(np.abs(q[i, seen] - g[seen]) <= tolerance):
                command_group[i] = j
                group_command[j] = i
                p = i + 1
                break
            i += 1
    return Matching(command_group, group_command)


def tolerance_rad() -> float:
    """Largest difference between a command and its decoded frame: half the resolution."""
    from crawler_motion.canbus.protocol import MotorProtocol
    from crawler_motion.model.config import load_config

    res = MotorProtocol.from_config(load_config().robot).resolution_rad
    return 0.5 * res * (1.0 + 1e-6) + 1e-9


def percentile(values: np.ndarray, q: float) -> float:
    """``q``-th percentile (NaN for no values)."""
    values = values[np.isfinite(values)]
    return float(np.percentile(values, q)) if values.size else math.nan


@dataclass(frozen=True)
class PeriodStats:
    """Timing of consecutive joint_commands header stamps."""

    n: int
    span: float  # last - first stamp [s]
    rate: float  # achieved [Hz]
    err_p50_ms: float  # |period - 1/rate| [ms]
    err_p99_ms: float
    err_max_ms: float
    missed: int  # gaps > MISSED_GAP_PERIODS periods
    longest_gap_ms: float


def period_stats(stamps: np.ndarray, rate: float) -> PeriodStats:
    """`PeriodStats` of sorted header ``stamps`` [s] against the set ``rate`` [Hz]."""
    if stamps.size < 2:
        return PeriodStats(int(stamps.size), 0.0, math.nan, math.nan, math.nan, math.nan, 0,
                           math.nan)
    period = 1.0 / rate
    dt = np.diff(stamps)
    err = np.abs(dt - period) * 1e3
    span = float(stamps[-1] - stamps[0])
    return PeriodStats(int(stamps.size), span, (stamps.size - 1) / span,
                       percentile(err, 50), percentile(err, 99), float(err.max()),
                       int(np.count_nonzero(dt > MISSED_GAP_PERIODS * period)),
                       float(dt.max() * 1e3))


def fmt(value: float | None, digits: int = 2) -> str:
    """A number for a table ('-' for None / NaN)."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}f}"




def command_flow(commands: np.ndarray, done: Finish, matching: Matching) -> dict[str, int]:
    """Counts along the chain over the whole run (the planner stopped before they were read):
    commands received here, accepted by the driver, its drops, target frame groups and frames
    on the bus, target frames the manager applied / rejected."""
    after, groups = done.after, done.tap.groups
    return {
        "published": len(commands),
        "driver_accepted": after.n("commands"),
        "driver_dropped": sum(after.n(k) for k in ("tx_stale", "refused", "blocked",
                                                    "inactive")),
        "tx_errors": after.n("tx_errors"),
        "groups": len(groups),
        "partial_groups": int(np.count_nonzero(groups[:, GROUP_FRAMES] < 4)),
        "unmatched_commands": int(np.count_nonzero(matching.command_group < 0)),
        "unmatched_groups": int(np.count_nonzero(matching.group_command < 0)),
        "target_frames": done.tap.counts.get("target", 0),
        "sim_applied": done.sim.get("targets", -1),
        "sim_rejected": done.sim.get("rejected", -1),
    }


def listener_delay_ms(groups: np.ndarray) -> tuple[float, float]:
    """p50 / p99 of (time.time() when the listener thread got a group's first frame - its
    kernel receive time) [ms]: what a user-space timestamp would have added to the latency."""
    delay = (groups[:, GROUP_T_USER] - groups[:, GROUP_T]) * 1e3
    return percentile(delay, 50), percentile(delay, 99)

