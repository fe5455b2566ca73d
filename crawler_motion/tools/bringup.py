"""``crawler-motion sim`` and ``crawler-motion up``: the whole robot brought up by one command.

``sim`` starts the seabed simulator, the controller (``controller_node``; ``--split``: the
driver and the planner as two processes), ``terrain_mapper`` and ``navigator`` (and the
recorder with ``--record``, the Foxglove view with ``--view``), each once the one before it is
ready, all from one parameter file and in one namespace, and prints one line per process when
it is ready. ``up`` does the same for the real robot: no simulator, the driver on the CAN bus of
the parameter file (or ``--interface/--channel``). A second terminal drives the robot
(``crawler-motion console stand | goto X Y | cancel | status``, Foxglove).

Ctrl-C or SIGTERM stops every process it started (the navigator first, the motors' side
last), exit 0. A process that dies is reported with its last log lines; the robot is brought to
a standing hold by the planner (if it still runs), the rest are stopped, exit 1. Bad options
(an unknown world or parameter file, a namespace that is not a ROS name, a bus that cannot be
opened, a port in use): one line, exit 1, nothing started.
"""

from __future__ import annotations

import argparse
import signal
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from crawler_motion.bringup.checks import check_bus, check_output, check_port_free, check_world
from crawler_motion.bringup.lineup import (
    MEDIA,
    VIEW_PORT,
    BringUpOptions,
    Member,
    check_namespace,
    check_params_file,
    lineup,
)
from crawler_motion.bringup.supervisor import BringUpError, Supervisor, interrupts_held
from crawler_motion.errors import CrawlerMotionError
from crawler_motion.runtime.cli_args import OneLineParser, finite_number
from crawler_motion.runtime.dds import dds_defaults
from crawler_motion.testing.bus import BusSpec
from crawler_motion.tools.procstat import cpu_seconds

#: Time a process gets to show its nodes on the graph [s].
READY_TIMEOUT = 30.0
#: Planner states in which the robot moves and a ``stop`` brings it to a standing hold.
MOVING_STATES = ("WALKING", "STOPPING", "MOVING")
#: Time the planner gets to bring a walk to a standing hold after a process died [s].
HOLD_TIMEOUT = 8.0


def build_parser(simulate: bool) -> argparse.ArgumentParser:
    """The options of ``sim`` (``simulate``) or ``up``."""
    prog = f"crawler-motion {'sim' if simulate else 'up'}"
    parser = OneLineParser(prog=prog, description=__doc__.splitlines()[0])
    if simulate:
        parser.add_argument("--world", default="flat", help="seabed world: a shipped name or "
                            "an MJCF path (default flat)")
        parser.add_argument("--medium", choices=MEDIA, default="water")
    else:
        parser.add_argument("--interface", default=None, help="CAN interface (default: the "
                            "parameter file's can_interface, else udp_multicast)")
        parser.add_argument("--channel", default=None, help="CAN channel, e.g. can0")
        parser.add_argument("--port", type=int, default=0, help="udp_multicast port")
    parser.add_argument("--params", type=Path, default=None, help="ROS parameter file of "
                        "every node (default: the shipped defaults; see config/params.yaml)")
    parser.add_argument("--namespace", default="", help="ROS namespace of every node")
    parser.add_argument("--split", action="store_true", help="the planner and the driver as "
                        "two processes instead of controller_node")
    parser.add_argument("--record", type=Path, default=None, metavar="RUN.mcap",
                        help="record every topic to this MCAP file")
    parser.add_argument("--view", action="store_true", help="serve the stack to Foxglove")
    parser.add_argument("--view-port", type=int, default=VIEW_PORT,
                        help=f"Foxglove WebSocket port (default {VIEW_PORT})")
    parser.add_argument("--logs", type=Path, default=None, help="directory of the processes' "
                        "logs (default: a new temporary directory)")
    parser.add_argument("--ready-timeout", type=finite_number("ready-timeout", positive=True),
                        default=READY_TIMEOUT, help="time a process gets to come up [s]")
    return parser


def options_from(args: argparse.Namespace, simulate: bool) -> BringUpOptions:
    """Checked options; `CrawlerMotionError` (one line) for anything that cannot run."""
    namespace = check_namespace(args.namespace)
    tree: dict[str, Any] = {}
    if args.params is not None:
        tree = check_params_file(args.params)
    if args.record is not None:
        check_output(args.record, "recording")
    if args.view:
        check_port_free("127.0.0.1", args.view_port, "Foxglove view")
    if simulate:
        check_world(args.world)
        bus = BusSpec.fresh()
    else:
        bus = _robot_bus(args, tree)
        check_bus(bus)
    extra = {} if simulate else {"driver": bus.ros_params()}
    return BringUpOptions(simulate=simulate, world=getattr(args, "world", "flat"),
                          medium=getattr(args, "medium", "water"), params=args.params,
                          namespace=namespace, split=args.split, record=args.record,
                          view=args.view, view_port=args.view_port, bus=bus, extra=extra)


def _robot_bus(args: argparse.Namespace, tree: dict[str, Any]) -> BusSpec:
    """The real robot's bus: the options, else the driver section of the file, else defaults."""
    section: dict[str, Any] = {}
    for key, value in tree.items():
        if key.rsplit("/", 1)[-1] == "driver":
            section = value.get("ros__parameters", {}) or {}
    interface = args.interface or section.get("can_interface") or BusSpec().interface
    channel = args.channel or section.get("can_channel")
    port = args.port or int(section.get("can_port") or 0)
    if channel is None:
        return BusSpec.fresh(interface) if interface != BusSpec().interface else BusSpec(
            interface, BusSpec().channel, port)
    return BusSpec(interface, str(channel), port)


class BringUp:
    """One run: start, watch, stop; prints what happens on stdout/stderr."""

    def __init__(self, prog: str, options: BringUpOptions, logs: Path) -> None:
        import rclpy

        self.prog, self.options = prog, options
        self.node = rclpy.create_node("crawler_bringup", namespace=options.namespace or None)
        self.sup = Supervisor(logs, _env(), self._ready)
        self.members: list[Member] = lineup(options)
        self.cpu_start: dict[str, float] = {}
        self.started = time.monotonic()

    def _ready(self, nodes: Sequence[str]) -> bool:
        ns = self.options.namespace or "/"
        seen = set(self.node.get_node_names_and_namespaces())
        return all((name, ns) in seen for name in nodes)

    def _on_ready(self, name: str, pid: int, seconds: float) -> None:
        print(f"{self.prog}: ready: {name} (pid {pid}) in {seconds:.1f} s", flush=True)
        self.cpu_start[name] = cpu_seconds(pid) or 0.0

    def run(self) -> int:
        """Bring up, watch until Ctrl-C/SIGTERM or a death; the exit status."""
        try:
            self.sup.start(self.members, self.options_timeout, self._on_ready)
            print(f"{self.prog}: up: {len(self.members)} processes in "
                  f"{time.monotonic() - self.started:.1f} s (logs in {self.sup.logs}); drive "
                  f"it with: crawler-motion console stand | goto X Y | cancel | status"
                  f"{self._ns_hint()}; Ctrl-C stops everything", flush=True)
            self.started = time.monotonic()
            while (ended := self.sup.exited()) is None:
                time.sleep(0.1)
        except BringUpError as exc:
            self._report(exc.member, exc.reason, exc.tail)
            return self._stop(hold=False, status=1)
        except KeyboardInterrupt:
            return self._stop(hold=False, status=0)
        self._report(ended.name, f"(pid {ended.pid}) exited with status {ended.status}",
                     self.sup.tail(ended.name))
        return self._stop(hold=True, status=1)

    options_timeout = READY_TIMEOUT

    def _ns_hint(self) -> str:
        ns = self.options.namespace
        return f" --ros-args -r __ns:={ns}" if ns else ""

    def _report(self, name: str, reason: str, tail: Sequence[str]) -> None:
        lines = "".join(f"\n    {line}" for line in tail)
        print(f"{self.prog}: error: {name} {reason}; its last log lines:{lines}",
              file=sys.stderr, flush=True)

    def _stop(self, hold: bool, status: int) -> int:
        """Hold the robot (if asked and the planner runs), print the CPU table, stop all."""
        with interrupts_held():
            if hold:
                print(f"{self.prog}: {self._hold()}", file=sys.stderr, flush=True)
            print(self._cpu_table(), flush=True)
            killed = self.sup.stop()
        tail = f" ({', '.join(killed)} killed after the timeout)" if killed else ""
        print(f"{self.prog}: stopped: every process ended{tail}", flush=True)
        return status

    def _hold(self) -> str:
        """Stop the navigator's walk with the planner's ``stop``: standing hold."""
        running = self.sup.running()
        planner = "planner_node" if self.options.split else "controller_node"
        if planner not in running:
            return ("the planner is gone: the driver's watchdog holds the motors "
                    "(no new targets)")
        from crawler_motion.tools.console import Console

        if "navigator" in running:
            self.sup.stop_one("navigator")
        console = Console("crawler_bringup_hold", namespace=self.options.namespace or None)
        console.printer = lambda _line: None
        try:
            if not console.connect(3.0):
                return "the planner did not answer; its cmd_vel timeout stops any walk"
            state = (console.status or {}).get("state")
            if state not in MOVING_STATES:
                return f"robot held: {state} (the planner had already stopped the walk)"
            ok, message = console.run({"command": "stop"}, HOLD_TIMEOUT)
            state = (console.status or {}).get("state")
            return f"robot held: {state}" if ok else f"hold: {message}"
        finally:
            console.close()

    def _cpu_table(self) -> str:
        """CPU per process since it was ready, in % of one core."""
        wall = max(1e-9, time.monotonic() - self.started)
        rows, total = [], 0.0
        for name, proc in self.sup.procs.items():
            now = cpu_seconds(proc.pid)
            if now is None or name not in self.cpu_start:
                continue
            share = 100.0 * (now - self.cpu_start[name]) / wall
            total += share
            rows.append(f"{name} {share:.0f} %")
        return (f"{self.prog}: CPU over the last {wall:.0f} s (% of one core): "
                f"{', '.join(rows)}; total {total:.0f} %")


def _env() -> dict[str, str]:
    import os

    env = dict(os.environ)
    dds_defaults(env)
    return env


def main(argv: Sequence[str] | None = None, simulate: bool = True) -> int:
    """Entry point of ``sim`` (``simulate``) and ``up``; the exit status."""
    parser = build_parser(simulate)
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    try:
        options = options_from(args, simulate)
    except CrawlerMotionError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 1
    logs = args.logs or Path(tempfile.mkdtemp(prefix="crawler-motion-"))
    import rclpy

    for sig in (signal.SIGTERM, signal.SIGINT):  # SIGINT too: ignored when started in the
        signal.signal(sig, signal.default_int_handler)  # background of a script
    rclpy.init(args=None, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    run = None
    try:
        run = BringUp(parser.prog, options, logs)
        run.options_timeout = args.ready_timeout
        return run.run()
    finally:
        if run is not None:
            run.node.destroy_node()
        rclpy.try_shutdown()


def main_up(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``up``."""
    return main(argv, simulate=False)


if __name__ == "__main__":
    sys.exit(main())
