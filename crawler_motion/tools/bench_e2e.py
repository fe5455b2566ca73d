"""End-to-end bench over the cross-process bus: planner -> driver -> CAN at 100, 200, 500 Hz.

For each command rate: starts the simulated motor manager, the driver (autostart) and the
planner (parameter ``rate``) as separate processes on a fresh python-can ``udp_multicast`` port
and a ROS domain no other node uses, stands, walks (a walk without steps) and, after a settling
second, measures for ``--seconds``, then stops (back to STANDING) and tears the stack down.

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
  (the listener child and this process are shown too: they are load on the same machine).

Run: python scripts/bench_e2e.py [--seconds 15] [--rates 100,200,500]  (or bench.py --e2e).
The machine may be shared: the figures depend on its load; rerun before drawing conclusions.
Exit status: 0 when every rate ran (whether the target is met or not), 1 when a run failed.

`Stack`, `TapProcess` and the analysis functions are reused by ``scripts/soak.py``.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import random
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.tools.demo import DEMO_COMMAND_TIMEOUT, BusTap, free_udp_port

#: Command rates of the bench [Hz].
RATES = (100.0, 200.0, 500.0)
#: The issue's target: at this rate no missed tick and p99 period error below this [ms].
TARGET_RATE = 500.0
TARGET_P99_PERIOD_ERROR_MS = 1.0
#: A stamp gap longer than this many periods is a missed tick.
MISSED_GAP_PERIODS = 1.5
#: Period of the driver's /diagnostics in these runs [s] (the driver's default is 1 s): the
#: final counters are read from a report that arrives after the planner stopped and before
#: the driver's command watchdog (`DEMO_COMMAND_TIMEOUT`) trips because of it.
DIAGNOSTICS_PERIOD = 0.25
#: Depth of the recording subscriptions: a slow spin must not drop samples (10 s at 1 kHz).
RECORD_DEPTH = 10_000
#: Columns of a target frame group (see `GroupTap`): kernel time, user time, counter, frames.
GROUP_T, GROUP_T_USER, GROUP_COUNTER, GROUP_FRAMES, GROUP_Q = 0, 1, 2, 3, 4
#: Columns of a recorded JointState: header stamp, receive time (time.time()), positions.
REC_STAMP, REC_RECV, REC_Q = 0, 1, 2
FAMILIES = ("target", "control", "position", "status", "heartbeat", "other")
PROCESSES = ("planner", "driver", "sim")
CLK_TCK = os.sysconf("SC_CLK_TCK")
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


# ------------------------------------------------------------------------------- /proc
def cpu_seconds(pid: int) -> float | None:
    """User + system CPU time of a process (all its threads) [s]; None if it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2:].split()  # fields[0] is field 3 (state)
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # fields 14 utime, 15 stime


def rss_mb(pid: int) -> float | None:
    """Resident set size (VmRSS) of a process [MiB]; None if it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        return None
    return None


# ------------------------------------------------------------------------------- records
class Rows:
    """A growable float table filled row by row (chunked: appending never copies)."""

    def __init__(self, width: int, chunk: int = 16_384) -> None:
        self.width = width
        self._chunk = chunk
        self._chunks: list[np.ndarray] = []
        self._n = 0

    def __len__(self) -> int:
        return self._n

    def append(self) -> np.ndarray:
        """A fresh row (a view, NaN-filled) to fill in place."""
        i = self._n % self._chunk
        if i == 0:
            self._chunks.append(np.empty((self._chunk, self.width)))
        self._n += 1
        row = self._chunks[-1][i]
        row.fill(math.nan)
        return row

    def array(self) -> np.ndarray:
        """A copy of the rows filled so far, shape ``(n, width)``."""
        if not self._chunks:
            return np.empty((0, self.width))
        return np.concatenate(self._chunks)[: self._n].copy()


# ------------------------------------------------------------------------------- bus tap
class GroupTap(BusTap):
    """`BusTap` that also decodes the target frames into one row per tick (`Rows`).

    Row: kernel receive time of the first frame (SO_TIMESTAMPNS on the listener's socket,
    CLOCK_REALTIME), ``time.time()`` when this thread got it, counter, number of frames seen,
    12 joint positions in joint order (NaN where a frame was not seen). A frame starts a new
    group when its counter differs from the current group's or its id is already in it.
    """

    def __init__(self, bus: Any, protocol: Any, joint_names: Sequence[str]) -> None:
        super().__init__(bus, protocol)
        self.protocol = protocol
        self.index = {name: i for i, name in enumerate(joint_names)}
        self.groups = Rows(GROUP_Q + len(joint_names))
        self.undecodable = 0
        self._row: np.ndarray | None = None
        self._ids: set[int] = set()

    def on_frame(self, msg: Any, kind: str) -> None:
        if kind == "target":
            self._target(msg)

    def _target(self, msg: Any) -> None:
        from crawler_motion.canbus.protocol import TargetFrame

        try:
            frame = self.protocol.decode(msg)
        except Exception:
            self.undecodable += 1
            return
        if not isinstance(frame, TargetFrame):
            return
        row = self._row
        if row is None or frame.counter != row[GROUP_COUNTER] or msg.arbitration_id in self._ids:
            row = self._row = self.groups.append()
            row[GROUP_T] = msg.timestamp
            row[GROUP_T_USER] = time.time()
            row[GROUP_COUNTER] = frame.counter
            row[GROUP_FRAMES] = 0
            self._ids = set()
        self._ids.add(msg.arbitration_id)
        row[GROUP_FRAMES] += 1
        for joint, value in frame.positions.items():
            row[GROUP_Q + self.index[joint]] = value


def _tap_main(port: int, shared: Any, ready: Any, stop: Any, conn: Any) -> None:
    """Child process: run a `GroupTap` until ``stop``, then send its records on ``conn``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops us (Ctrl-C goes to all)
    import can
    from can.interfaces.udp_multicast import UdpMulticastBus

    from crawler_motion.canbus.protocol import MotorProtocol
    from crawler_motion.model.config import load_config

    cfg = load_config()
    protocol = MotorProtocol.from_config(cfg.robot)
    bus = can.Bus(interface="udp_multicast", channel=UdpMulticastBus.DEFAULT_GROUP_IPv4,
                  port=port, receive_own_messages=False)
    tap = GroupTap(bus, protocol, cfg.robot.joint_names)
    tap.start()
    ready.set()

    def publish() -> None:
        for i, kind in enumerate(FAMILIES):
            shared[i] = tap.counts.get(kind, 0)
        shared[len(FAMILIES)] = len(tap.groups)

    while not stop.wait(0.25):
        publish()
    tap.stop()
    publish()
    conn.send({"counts": dict(tap.counts), "groups": tap.groups.array(),
               "undecodable": tap.undecodable})
    conn.close()


@dataclass
class TapResult:
    """What the bus listener saw: frames per family and the target frame groups."""

    counts: dict[str, int]
    groups: np.ndarray
    undecodable: int


class TapProcess:
    """A `GroupTap` in a child process (spawned: no fork of an rclpy process)."""

    def __init__(self, port: int) -> None:
        ctx = mp.get_context("spawn")
        self._shared = ctx.Array("q", len(FAMILIES) + 1, lock=False)
        self._ready = ctx.Event()
        self._stop = ctx.Event()
        self._recv, send = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_tap_main, name="bus-tap", daemon=True,
                                 args=(port, self._shared, self._ready, self._stop, send))
        self._proc.start()
        send.close()

    @property
    def pid(self) -> int:
        """Process id of the listener."""
        return int(self._proc.pid or 0)

    def wait_ready(self, timeout: float) -> bool:
        """True once the listener's bus is open."""
        return bool(self._ready.wait(timeout))

    def counts(self) -> tuple[dict[str, int], int]:
        """Live frames per family and target groups (updated every 0.25 s)."""
        values = list(self._shared)
        return dict(zip(FAMILIES, values, strict=False)), int(values[len(FAMILIES)])

    def finish(self, timeout: float = 30.0) -> TapResult:
        """Stop listening and collect the records."""
        self._stop.set()
        if not self._recv.poll(timeout):
            self.kill()
            raise RuntimeError("the bus listener did not report back")
        data = self._recv.recv()
        self._proc.join(5.0)
        return TapResult(data["counts"], data["groups"], data["undecodable"])

    def kill(self) -> None:
        """End the listener if it is still running."""
        self._stop.set()
        self._proc.join(2.0)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join(2.0)


# ------------------------------------------------------------------------------- the stack
def parse_sim_counters(text: str) -> dict[str, int]:
    """The counters the simulated manager prints when it stops (empty if absent)."""
    match = re.search(r"SimCounters\(([^)]*)\)", text)
    if match is None:
        return {}
    return {k.strip(): int(v) for k, v in (p.split("=") for p in match.group(1).split(","))}


@dataclass
class Snapshot:
    """Counters of the driver from one /diagnostics report (receive time ``t``)."""

    t: float = math.nan
    bus: dict[str, str] = field(default_factory=dict)  # "driver: CAN bus" values
    manager: dict[str, str] = field(default_factory=dict)  # "driver: motor manager" values

    def n(self, key: str) -> int:
        """Integer counter ``key`` of the bus entry (0 when absent)."""
        try:
            return int(self.bus.get(key, 0))
        except ValueError:
            return 0


@dataclass
class Finish:
    """What `Stack.finish` collects once the planner has stopped."""

    tap: TapResult
    before: Snapshot  # last /diagnostics before the planner was stopped
    after: Snapshot  # first /diagnostics well after it stopped (final command counters)
    sim: dict[str, int]  # the simulated manager's counters at its exit
    t_cut: float  # time.time() when the planner was told to stop


class Stack:
    """Simulated manager + driver (autostart) + planner on a fresh udp_multicast port and a ROS
    domain of its own, with a `Console`, recorders of joint_commands / joint_states, the last
    /diagnostics counters and a `TapProcess` listening on the bus."""

    def __init__(self, rate: float, *, gait: str = "diagonal",
                 command_timeout: float = DEMO_COMMAND_TIMEOUT, logs: Path | None = None,
                 tick_priority: int = 0) -> None:
        from crawler_motion.model.config import load_config

        self.rate = float(rate)
        self.tick_priority = int(tick_priority)
        self.gait = gait
        self.command_timeout = float(command_timeout)
        self.cfg = load_config()
        self.names = list(self.cfg.robot.joint_names)
        self.logs = logs or Path(tempfile.mkdtemp(prefix="crawler-e2e-"))
        self.port = 0
        self.domain = -1
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.tap: TapProcess | None = None
        self.console: Any = None
        width = REC_Q + len(self.names)
        self.commands = Rows(width)
        self.states = Rows(width)
        self.bad_messages = 0
        self.diag = Snapshot()
        self.on_status: Callable[[dict[str, Any]], None] | None = None
        self._rclpy: Any = None
        self._cmd_sub: Any = None

    # ---- start ---------------------------------------------------------------------------
    def start(self, timeout: float = 30.0) -> None:
        """Start everything; returns once measured joint_states arrive and the planner is up."""
        import rclpy

        self._rclpy = rclpy
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        self.port = free_udp_port()
        self.tap = TapProcess(self.port)
        self._open_domain()
        self._launch()
        if not self.tap.wait_ready(timeout):
            raise RuntimeError("the bus listener did not come up")
        console = self.console
        if not console.connect(timeout):
            raise RuntimeError("the planner did not come up within "
                               f"{timeout:g} s{self._died()}")
        if not console.wait_until(lambda: len(self.states) > 0
                                  and self._cmd_sub.get_publisher_count() > 0, timeout):
            raise RuntimeError("no measured joint_states from the driver (or joint_commands "
                               f"not matched) within {timeout:g} s{self._died()}")

    def _open_domain(self) -> None:
        """rclpy on a random ROS domain in which no other node shows up within a second."""
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        from crawler_motion.tools.console import Console

        rclpy = self._rclpy
        for attempt in range(6):
            self.domain = random.randint(1, 101)
            rclpy.init(domain_id=self.domain)
            console = Console(f"e2e_observer_{os.getpid()}")
            console.spin_for(1.0)
            others = [n for n in console.node.get_node_names() if n != console.node.get_name()]
            if not others:
                break
            console.close()
            rclpy.try_shutdown()
            if attempt == 5:
                raise RuntimeError(f"no free ROS domain found (last: {self.domain}, nodes "
                                   f"{others})")
        self.console = console
        console.printer = self._status_line
        reliable = QoSProfile(depth=RECORD_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
        self._cmd_sub = console.node.create_subscription(
            JointState, "joint_commands", lambda m: self._record(self.commands, m), reliable)
        console.node.create_subscription(
            JointState, "joint_states", lambda m: self._record(self.states, m), reliable)
        console.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 50)

    def _launch(self) -> None:
        from can.interfaces.udp_multicast import UdpMulticastBus

        group = UdpMulticastBus.DEFAULT_GROUP_IPv4
        py = sys.executable
        env = dict(os.environ, ROS_DOMAIN_ID=str(self.domain),
                   ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        commands = {
            "sim": [py, "-m", "crawler_motion.sim.motor_manager", "--interface",
                    "udp_multicast", "--channel", group, "--port", str(self.port),
                    "--speed-limit", str(float(self.cfg.robot.velocity.max()))],
            "driver": [py, "-m", "crawler_motion.driver.node", "--ros-args",
                       "-p", "autostart:=true", "-p", f"command_timeout:={self.command_timeout}",
                       "-p", f"diagnostics_period:={DIAGNOSTICS_PERIOD}",
                       "-p", "can_interface:=udp_multicast", "-p", f"can_channel:={group}",
                       "-p", f"can_port:={self.port}",
                       "-p", f"priority:={max(0, self.tick_priority - 1)}"],
            "planner": [py, "-m", "crawler_motion.planner.node", "--ros-args",
                        "-p", f"rate:={self.rate}", "-p", f"gait:={self.gait}",
                        "-p", f"tick_priority:={self.tick_priority}"],
        }
        for name, cmd in commands.items():
            with open(self.logs / f"{name}.log", "wb") as log:
                self.procs[name] = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                                                    env=env)

    def _died(self) -> str:
        dead = [f"{n} exited {p.returncode}" for n, p in self.procs.items()
                if p.poll() is not None]
        return f" ({', '.join(dead)}; logs in {self.logs})" if dead else ""

    # ---- callbacks -----------------------------------------------------------------------
    def _record(self, rows: Rows, msg: Any) -> None:
        if len(msg.position) != len(self.names) or list(msg.name) != self.names:
            self.bad_messages += 1
            return
        row = rows.append()
        row[REC_STAMP] = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        row[REC_RECV] = time.time()
        row[REC_Q:] = msg.position

    def _on_diag(self, msg: Any) -> None:
        snap = Snapshot(t=time.time(), bus=dict(self.diag.bus),
                        manager=dict(self.diag.manager))
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if status.name.endswith(": CAN bus"):
                snap.bus = values
            elif status.name.endswith(": motor manager"):
                snap.manager = values
        self.diag = snap

    def _status_line(self, line: str) -> None:
        if self.on_status is not None:
            self.on_status(dict(self.console.status or {}))

    # ---- use -----------------------------------------------------------------------------
    @property
    def status(self) -> dict[str, Any]:
        """The planner's latest status."""
        return dict(self.console.status or {})

    def spin(self, seconds: float) -> None:
        """Process callbacks for ``seconds``; raises if a stack process exited."""
        self.console.spin_for(seconds)
        if self._died():
            raise RuntimeError(f"a stack process exited{self._died()}")

    def command(self, command: dict[str, Any], timeout: float = 60.0) -> str:
        """Send a gait command and wait until done (raises when refused or timed out)."""
        ok, message = self.console.run_when_ready(command, timeout)
        if not ok:
            raise RuntimeError(f"{command}: {message}{self._died()}")
        return str(message)

    def pids(self) -> dict[str, int]:
        """Process ids: the three stack processes, the bus listener and this process."""
        pids = {name: p.pid for name, p in self.procs.items()}
        if self.tap is not None:
            pids["tap"] = self.tap.pid
        pids["self"] = os.getpid()
        return pids

    def cpu(self) -> dict[str, float | None]:
        """CPU seconds of every process of `pids`, with the time [s] under key ``"wall"``."""
        out: dict[str, float | None] = {n: cpu_seconds(p) for n, p in self.pids().items()}
        out["wall"] = time.monotonic()
        return out

    def rss(self) -> dict[str, float | None]:
        """VmRSS [MiB] of every process of `pids`."""
        return {name: rss_mb(pid) for name, pid in self.pids().items()}

    # ---- end -----------------------------------------------------------------------------
    def finish(self) -> Finish:
        """Stop the planner, read the final driver counters, collect the bus records, stop the
        driver and the manager (in that order: no target frame after the planner stops)."""
        before = self.diag
        t_cut = time.time()
        planner = self.procs["planner"]
        planner.send_signal(signal.SIGINT)
        try:
            planner.wait(10.0)
        except subprocess.TimeoutExpired:
            planner.kill()
        t_exit = time.time()
        self.console.wait_until(lambda: self.diag.t > t_exit + 0.3, 5.0)
        after = self.diag
        assert self.tap is not None
        tap = self.tap.finish()
        self._stop_processes()
        sim_log = (self.logs / "sim.log").read_text(errors="replace")
        return Finish(tap, before, after, parse_sim_counters(sim_log), t_cut)

    def _stop_processes(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in self.procs.values():
            try:
                proc.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()

    def close(self) -> None:
        """Tear everything down (idempotent; after `finish` or on an error)."""
        if self.tap is not None:
            self.tap.kill()
        self._stop_processes()
        if self.console is not None:
            self.console.close()
            self.console = None
        if self._rclpy is not None:
            self._rclpy.try_shutdown()

    def log_tails(self, lines: int = 5) -> str:
        """The last lines of each process's log."""
        out = []
        for name in self.procs:
            path = self.logs / f"{name}.log"
            tail = path.read_text(errors="replace").splitlines()[-lines:] if path.exists() else []
            out.append(f"--- {name} (last lines of {path}) ---\n" + "\n".join(tail))
        return "\n".join(out)


# ------------------------------------------------------------------------------- analysis
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


def cpu_percent(before: dict[str, float | None], after: dict[str, float | None]
                ) -> dict[str, float]:
    """CPU % of one core per process between two `Stack.cpu` samples."""
    wall = float(after["wall"] or 0.0) - float(before["wall"] or 0.0)
    out = {}
    for name, value in after.items():
        start = before.get(name)
        if name == "wall" or value is None or start is None or wall <= 0:
            continue
        out[name] = 100.0 * (value - start) / wall
    return out


def fmt(value: float | None, digits: int = 2) -> str:
    """A number for a table ('-' for None / NaN)."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    return f"{value:.{digits}f}"


# ------------------------------------------------------------------------------- the bench
@dataclass
class RateResult:
    """One row of the bench table."""

    rate: float
    timing: PeriodStats | None = None
    planner_ticks: str = "-"  # `counters_text` over the window
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


def bench_rate(rate: float, seconds: float, *, settle: float = 1.0, gait: str = "diagonal",
               say: Callable[[str], None] = print, tick_priority: int = 0) -> RateResult:
    """Start a stack at ``rate``, stand, walk, measure for ``seconds``, stop, analyse."""
    result = RateResult(rate)
    stack = Stack(rate, gait=gait, tick_priority=tick_priority)
    try:
        say(f"{rate:g} Hz: starting the stack (logs in {stack.logs})")
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
        done = stack.finish()
    except (RuntimeError, OSError) as exc:
        result.error = str(exc)
        say(f"{rate:g} Hz: error: {exc}\n{stack.log_tails()}")
        return result
    finally:
        stack.close()
    if state != "WALKING":
        result.error = f"not walking at the end of the window ({state})"
    commands = stack.commands.array()
    commands = commands[np.argsort(commands[:, REC_STAMP], kind="stable")]
    groups = done.tap.groups
    in_window = (commands[:, REC_STAMP] >= t0) & (commands[:, REC_STAMP] <= t1)
    result.timing = period_stats(commands[in_window, REC_STAMP], rate)
    result.planner_ticks = counters_text(late0, late1)
    matching = match_groups(commands, groups, tolerance_rad())
    latency = matching.latency(commands, groups)[in_window] * 1e3
    result.lat_p50_ms = percentile(latency, 50)
    result.lat_p99_ms = percentile(latency, 99)
    result.lat_max_ms = float(np.nanmax(latency)) if np.isfinite(latency).any() else math.nan
    result.lost = int(np.count_nonzero(matching.command_group[in_window] < 0))
    g_window = (groups[:, GROUP_T] >= t0) & (groups[:, GROUP_T] <= t1)
    result.observer_misses = int(np.count_nonzero(matching.group_command[g_window] < 0))
    result.cpu = cpu_percent(cpu0, cpu1)
    result.flow = command_flow(commands, done, matching)
    result.listener_delay = listener_delay_ms(groups)
    return result


def print_table(results: Sequence[RateResult], seconds: float) -> bool:
    """Print the Markdown table and the verdict; True when the target is met."""
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"\n## End to end: planner -> driver -> CAN ({seconds:g} s walking per rate, "
          f"{os.cpu_count()} CPUs, load average now {load})\n")
    print("| rate [Hz] | achieved [Hz] | missed ticks (gaps > 1.5 T) | planner late / missed "
          "ticks | period error p50 / p99 / max [ms] | JointState->CAN p50 / p99 / max [ms] | "
          "lost | CPU % planner / driver / sim | CPU % tap / bench |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in results:
        if r.timing is None:
            print(f"| {r.rate:g} | failed: {r.error} | | | | | | | |")
            continue
        t, c = r.timing, r.cpu
        lost = f"{r.lost}" + (f" (+{r.observer_misses} observer misses)"
                              if r.observer_misses else "")
        late = r.planner_ticks
        print(f"| {r.rate:g} | {fmt(t.rate, 1)} | {t.missed} (longest gap "
              f"{fmt(t.longest_gap_ms, 1)} ms) | {late} | {fmt(t.err_p50_ms, 3)} / "
              f"{fmt(t.err_p99_ms, 3)} / {fmt(t.err_max_ms, 2)} | "
              f"{fmt(r.lat_p50_ms)} / {fmt(r.lat_p99_ms)} / {fmt(r.lat_max_ms)} | {lost} | "
              f"{fmt(c.get('planner'), 0)} / {fmt(c.get('driver'), 0)} / {fmt(c.get('sim'), 0)}"
              f" | {fmt(c.get('tap'), 0)} / {fmt(c.get('self'), 0)} |"
              + (f" {r.error}" if r.error else ""))
    print("\nWhole run (stand, walk, stop; counted after the planner stopped): joint_commands "
          "received here -> accepted by the driver (its drops: stale + refused + blocked + "
          "inactive) -> target frame groups on the bus -> target frames applied by the "
          "manager.\n")
    print("| rate [Hz] | received here | driver accepted | driver drops | groups on bus "
          "(partial) | commands without group | groups without command | target frames on "
          "bus | manager applied / rejected | listener user-space delay p50 / p99 [ms] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        f = r.flow
        if not f:
            continue
        print(f"| {r.rate:g} | {f['published']} | {f['driver_accepted']} | "
              f"{f['driver_dropped']} | {f['groups']} ({f['partial_groups']}) | "
              f"{f['unmatched_commands']} | {f['unmatched_groups']} | {f['target_frames']} | "
              f"{f['sim_applied']} / {f['sim_rejected']} | {fmt(r.listener_delay[0], 3)} / "
              f"{fmt(r.listener_delay[1], 3)} |")
    target = next((r for r in results if r.rate == TARGET_RATE and r.timing is not None), None)
    print(f"\nTarget: {TARGET_RATE:g} Hz with no missed ticks and p99 period error < "
          f"{TARGET_P99_PERIOD_ERROR_MS:g} ms -> ", end="")
    if target is None or target.timing is None:
        print("not measured")
        return False
    t = target.timing
    met = (t.missed == 0 and t.err_p99_ms < TARGET_P99_PERIOD_ERROR_MS
           and abs(t.rate - TARGET_RATE) < 0.01 * TARGET_RATE and not target.error)
    why = [] if met else [f"{t.missed} missed", f"p99 {t.err_p99_ms:.3f} ms",
                          f"achieved {t.rate:.1f} Hz"]
    lost = (f"; besides, {target.lost} of its commands in the window never reached the bus"
            if target.lost else "")
    print(("**met**" if met else f"**NOT met** ({', '.join(why)})") + lost)
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


def main(argv: Sequence[str] | None = None) -> int:
    """Run the end-to-end bench; returns the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", type=parse_rates, default=RATES,
                        help="command rates [Hz], comma-separated (default 100,200,500)")
    parser.add_argument("--seconds", type=float, default=15.0,
                        help="measured walking time per rate [s] (default 15)")
    parser.add_argument("--gait", choices=("diagonal", "wave"), default="diagonal")
    parser.add_argument("--tick-priority", type=int, default=0,
                        help="the planner's tick_priority (1-99: SCHED_FIFO tick thread, "
                             "the planner and driver processes one below; default 0: normal "
                             "scheduling)")
    args = parser.parse_args(argv)
    if not 0 <= args.tick_priority <= 99:
        parser.error(f"--tick-priority must be in [0, 99], got {args.tick_priority}")
    if not (math.isfinite(args.seconds) and args.seconds > 0):
        parser.error(f"--seconds must be > 0, got {args.seconds}")
    t_start = time.monotonic()

    def say(line: str) -> None:
        print(f"[{time.monotonic() - t_start:6.1f} s] {line}", file=sys.stderr, flush=True)

    results = []
    try:
        for rate in args.rates:
            results.append(bench_rate(rate, args.seconds, gait=args.gait, say=say,
                                      tick_priority=args.tick_priority))
    except KeyboardInterrupt:
        return 130
    print_table(results, args.seconds)
    return 1 if any(r.timing is None for r in results) else 0


if __name__ == "__main__":
    raise SystemExit(main())
