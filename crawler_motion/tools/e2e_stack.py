"""The observed stack of the end-to-end bench and soak: processes, bus listener, ROS recorders."""

from __future__ import annotations

import math
import os
import re
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from crawler_motion.testing.bus import BusSpec
from crawler_motion.testing.stack import (
    STACK_COMMAND_TIMEOUT,
    StackProcesses,
    StackSpec,
    isolated_env,
    random_domain,
)
from crawler_motion.tools.e2e_records import (
    REC_Q,
    REC_RECV,
    REC_STAMP,
    Rows,
    TapProcess,
    TapResult,
)
from crawler_motion.tools.procstat import cpu_seconds, rss_mb

#: Process names of the stack (log files ``<name>.log``); the composed controller replaces
#: the planner and the driver by one process.
PROCESSES = ("planner", "driver", "sim")
CONTROLLER_PROCESSES = ("controller", "sim")
#: Period of the driver's /diagnostics in these runs [s] (the driver's default is 1 s): the
#: final counters are read from a report that arrives after the planner stopped and before
#: the driver's command watchdog (`STACK_COMMAND_TIMEOUT`) trips because of it.
DIAGNOSTICS_PERIOD = 0.25
#: Depth of the recording subscriptions: a slow spin must not drop samples (10 s at 1 kHz).
RECORD_DEPTH = 10_000
#: Attempts at finding a ROS domain no other node uses.
DOMAIN_ATTEMPTS = 6


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


class Observer:
    """This process's ROS side: a `Console` on a ROS domain no other node uses, recorders of
    joint_commands / joint_states and the last /diagnostics counters."""

    def __init__(self, names: list[str], on_status: Callable[[dict[str, Any]], None]) -> None:
        import rclpy

        self.names = names
        self.domain = -1
        width = REC_Q + len(names)
        self.commands = Rows(width)
        self.states = Rows(width)
        self.bad_messages = 0
        self.diag = Snapshot()
        self._on_status = on_status
        self._rclpy = rclpy
        self.console = self._open_domain()
        self._subscribe()

    def _open_domain(self) -> Any:
        """rclpy on a random ROS domain in which no other node shows up within a second."""
        from crawler_motion.tools.console import Console

        rclpy = self._rclpy
        for attempt in range(DOMAIN_ATTEMPTS):
            self.domain = random_domain()
            rclpy.init(domain_id=self.domain)
            console = Console(f"e2e_observer_{os.getpid()}")
            console.spin_for(1.0)
            others = [n for n in console.node.get_node_names() if n != console.node.get_name()]
            if not others:
                return console
            console.close()
            rclpy.try_shutdown()
            if attempt == DOMAIN_ATTEMPTS - 1:
                raise RuntimeError(f"no free ROS domain found (last: {self.domain}, nodes "
                                   f"{others})")
        raise AssertionError("unreachable")

    def _subscribe(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        node = self.console.node
        self.console.printer = lambda _line: self._on_status(self.status)
        reliable = QoSProfile(depth=RECORD_DEPTH, reliability=ReliabilityPolicy.RELIABLE)
        self.cmd_sub = node.create_subscription(
            JointState, "joint_commands", lambda m: self._record(self.commands, m), reliable)
        node.create_subscription(
            JointState, "joint_states", lambda m: self._record(self.states, m), reliable)
        node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 50)

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

    @property
    def status(self) -> dict[str, Any]:
        """The planner's latest status."""
        return dict(self.console.status or {})

    def close(self) -> None:
        """Close the console and shut rclpy down (idempotent)."""
        if self.console is not None:
            self.console.close()
            self.console = None
        self._rclpy.try_shutdown()


class Stack:
    """Simulated manager + driver (autostart) + planner on a fresh udp_multicast port and a ROS
    domain of their own, observed by an `Observer` and a `TapProcess` listening on the bus.
    With ``controller`` the planner and the driver run composed (``controller_node``)."""

    def __init__(self, rate: float, *, gait: str = "diagonal",
                 command_timeout: float = STACK_COMMAND_TIMEOUT, logs: Path | None = None,
                 tick_priority: int = 0, controller: bool = False) -> None:
        from crawler_motion.model.config import load_config

        self.rate = float(rate)
        self.controller = bool(controller)
        self.tick_priority = int(tick_priority)
        self.gait = gait
        self.command_timeout = float(command_timeout)
        self.cfg = load_config()
        self.names = list(self.cfg.robot.joint_names)
        self.procs = StackProcesses(logs or Path(tempfile.mkdtemp(prefix="crawler-e2e-")))
        self.bus = BusSpec()
        self.tap: TapProcess | None = None
        self.observer: Observer | None = None
        self.on_status: Callable[[dict[str, Any]], None] | None = None

    @property
    def logs(self) -> Path:
        """Directory of the process logs."""
        return self.procs.logs

    @property
    def port(self) -> int:
        """UDP port of the bus."""
        return self.bus.port

    @property
    def domain(self) -> int:
        """ROS domain of the stack (-1 before `start`)."""
        return self.observer.domain if self.observer is not None else -1

    def spec(self) -> StackSpec:
        """The processes to launch."""
        return StackSpec(
            self.bus, rate=self.rate, command_timeout=self.command_timeout,
            speed_limit=float(self.cfg.robot.velocity.max()),
            driver={"diagnostics_period": DIAGNOSTICS_PERIOD,
                    "priority": max(0, self.tick_priority - 1)},
            planner={"gait": self.gait, "tick_priority": self.tick_priority},
            controller=self.controller)

    @property
    def processes(self) -> tuple[str, ...]:
        """Names of the stack's processes."""
        return CONTROLLER_PROCESSES if self.controller else PROCESSES

    def start(self, timeout: float = 30.0) -> None:
        """Start everything; returns once measured joint_states arrive and the planner is up."""
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        self.bus = BusSpec.fresh()
        self.tap = TapProcess(self.bus.port)
        self.observer = obs = Observer(self.names, self._status)
        self.procs.start(self.spec().commands(), isolated_env(obs.domain))
        if not self.tap.wait_ready(timeout):
            raise RuntimeError("the bus listener did not come up")
        if not obs.console.connect(timeout):
            raise RuntimeError("the planner did not come up within "
                               f"{timeout:g} s{self.procs.died()}")
        if not obs.console.wait_until(lambda: len(obs.states) > 0
                                      and obs.cmd_sub.get_publisher_count() > 0, timeout):
            raise RuntimeError("no measured joint_states from the driver (or joint_commands "
                               f"not matched) within {timeout:g} s{self.procs.died()}")

    def _status(self, status: dict[str, Any]) -> None:
        if self.on_status is not None:
            self.on_status(status)

    # ---- use -----------------------------------------------------------------------------
    @property
    def console(self) -> Any:
        """The observer's `Console`."""
        assert self.observer is not None
        return self.observer.console

    @property
    def commands(self) -> Rows:
        """Recorded joint_commands."""
        assert self.observer is not None
        return self.observer.commands

    @property
    def states(self) -> Rows:
        """Recorded joint_states."""
        assert self.observer is not None
        return self.observer.states

    @property
    def diag(self) -> Snapshot:
        """The latest driver counters."""
        return self.observer.diag if self.observer is not None else Snapshot()

    @property
    def bad_messages(self) -> int:
        """JointState messages ignored (names or lengths not the joints)."""
        return self.observer.bad_messages if self.observer is not None else 0

    @property
    def status(self) -> dict[str, Any]:
        """The planner's latest status."""
        return self.observer.status if self.observer is not None else {}

    def spin(self, seconds: float) -> None:
        """Process callbacks for ``seconds``; raises if a stack process exited."""
        self.console.spin_for(seconds)
        if self.procs.died():
            raise RuntimeError(f"a stack process exited{self.procs.died()}")

    def command(self, command: dict[str, Any], timeout: float = 60.0) -> str:
        """Send a gait command and wait until done (raises when refused or timed out)."""
        ok, message = self.console.run_when_ready(command, timeout)
        if not ok:
            raise RuntimeError(f"{command}: {message}{self.procs.died()}")
        return str(message)

    def pids(self) -> dict[str, int]:
        """Process ids: the three stack processes, the bus listener and this process."""
        pids = self.procs.pids()
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
        self._stop_commands()
        t_exit = time.time()
        self.console.wait_until(lambda: self.diag.t > t_exit + 0.3, 5.0)
        after = self.diag
        assert self.tap is not None
        tap = self.tap.finish()
        self.procs.stop(timeout=10.0)
        sim_log = self.procs.log_path("sim").read_text(errors="replace")
        return Finish(tap, before, after, parse_sim_counters(sim_log), t_cut)

    def _stop_commands(self) -> None:
        """End the joint commands: stop the planner process; in the composed controller, whose
        driver must stay to report its final counters, latch an e-stop (no command after it)."""
        if not self.controller:
            self.procs.stop(["planner"], timeout=10.0)
            return
        self.console.send({"command": "estop"})
        self.console.wait_until(lambda: self.status.get("state") == "ESTOP", 5.0)

    def close(self) -> None:
        """Tear everything down (idempotent; after `finish` or on an error)."""
        if self.tap is not None:
            self.tap.kill()
        self.procs.stop(timeout=10.0)
        if self.observer is not None:
            self.observer.close()

    def log_tails(self, lines: int = 5) -> str:
        """The last lines of each process's log."""
        return self.procs.log_tails(lines, "--- {name} (last lines of {path}) ---")
