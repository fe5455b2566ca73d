"""The ``motor_manager_sim`` console script: runs `MotorManagerSim` on a CAN bus until a signal.

It takes its options, or ``--ros-args`` like the nodes (``-p can_port:=43113``,
``--params-file config/params.yaml``: `manager_parameters`); both may be mixed, options win.
"""

from __future__ import annotations

import math
import signal
import sys
import threading
from collections.abc import Sequence
from types import FrameType

import can

from crawler_motion.canbus.bus import (
    OPEN_ERRORS,
    UDP_MULTICAST,
    default_channel,
    describe_bus,
    open_bus,
)
from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.errors import ConfigError, CrawlerMotionError
from crawler_motion.runtime.cli_args import OneLineParser, split_ros_args
from crawler_motion.runtime.ros_args import parse_ros_args
from crawler_motion.sim.manager_parameters import NODE_NAME, manager_flags
from crawler_motion.sim.motor_manager import (
    DEFAULT_COMMAND_TIMEOUT,
    DEFAULT_SPEED_LIMIT,
    MotorManagerSim,
)

PROG = "motor_manager_sim"
#: UDP port of the ``udp_multicast`` bus by default (python-can's default).
DEFAULT_PORT = 43113
#: Options that must be finite numbers > 0 when given (argparse destinations).
POSITIVE_OPTIONS = ("rate", "speed_limit", "command_timeout", "heartbeat_period")
#: How often the main thread checks that the manager thread still runs [s].
WATCH_PERIOD = 0.2


def _parser() -> OneLineParser:
    parser = OneLineParser(prog=PROG, description="Simulated multi-axis motor manager of the "
                           "crawler: speaks config/motor_manager.dbc on a CAN bus until "
                           "SIGINT/SIGTERM.")
    parser.add_argument("--interface", default=UDP_MULTICAST,
                        help="python-can interface (default: %(default)s; e.g. socketcan)")
    parser.add_argument("--channel", default=None,
                        help=f"bus channel (default: {default_channel(UDP_MULTICAST)} for "
                        f"udp_multicast, {default_channel('socketcan')} for socketcan)")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT,
                        help="UDP port of udp_multicast (default: %(default)s)")
    parser.add_argument("--rate", type=float, default=None,
                        help="feedback rate [Hz] (default: the DBC cycle time, 100 Hz)")
    parser.add_argument("--speed-limit", type=float, default=DEFAULT_SPEED_LIMIT,
                        help="axis speed limit [rad/s] (default: %(default)s)")
    parser.add_argument("--command-timeout", type=float, default=DEFAULT_COMMAND_TIMEOUT,
                        help="hold after this long without target frames [s] "
                        "(default: %(default)s)")
    parser.add_argument("--heartbeat-period", type=float, default=None,
                        help="heartbeat period [s] (default: the DBC cycle time, 0.1 s)")
    parser.add_argument("--initial-pose", choices=("mid", "zero"), default="mid",
                        help="joint angles at power-up: 'mid' = the middle of every joint's "
                             "limits (default), 'zero' = all zero (outside the knee limit)")
    parser.add_argument("--no-effort", action="store_true",
                        help="send no effort frames (a manager without them)")
    parser.add_argument("--dbc", default=None, help="DBC file (default: the shipped one)")
    parser.add_argument("--axes", default=None, help="axis map YAML (default: the shipped one)")
    parser.add_argument("--config", default=None,
                        help="robot.yaml for joint names and limits (default: the shipped one)")
    return parser


def _open(interface: str, channel: str | None, port: int) -> tuple[can.BusABC, str]:
    """Open the bus; returns it and a description such as ``udp_multicast 239.74.163.2:43113``."""
    channel = channel or default_channel(interface)
    if channel is None:
        raise ValueError(f"--channel is required for interface {interface!r}")
    # as a real manager on SocketCAN, it does not receive the frames it sends
    bus = open_bus(interface, channel, port, own_frames=False)
    return bus, describe_bus(interface, channel, port)


def _run(sim: MotorManagerSim, stop: threading.Event, where: str) -> int:
    """Run ``sim`` on the bus ``where`` until ``stop`` is set; the exit code."""
    sim.start()
    print(f"{PROG}: running on {where}, feedback every {sim.period:g} s, heartbeat every "
          f"{sim.heartbeat_period:g} s", flush=True)
    while not stop.wait(WATCH_PERIOD):
        if not sim.running:
            print(f"{PROG}: error: the manager thread stopped: {sim.last_error}",
                  file=sys.stderr)
            return 1
    sim.stop()
    print(f"{PROG}: stopped; {sim.counters}", flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the simulated manager until SIGINT/SIGTERM; returns the exit code."""
    parser = _parser()
    own, ros = split_ros_args(sys.argv[1:] if argv is None else argv)
    if ros:
        try:
            own = [*manager_flags(parse_ros_args(ros, NODE_NAME)), *own]
        except ConfigError as exc:
            parser.error(f"--ros-args: {exc}")
    args = parser.parse_args(own)
    for name in POSITIVE_OPTIONS:
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            parser.error(f"--{name.replace('_', '-')} must be a finite number > 0, "
                         f"got {value}")
    if not 0 < args.port < 65536:
        parser.error(f"--port must be 1..65535, got {args.port}")
    from crawler_motion.model.config import load_config  # heavy only when actually running

    try:
        config = load_config(args.config)
        protocol = MotorProtocol.from_config(config.robot, args.dbc, args.axes)
        bus, where = _open(args.interface, args.channel, args.port)
    except (CrawlerMotionError, *OPEN_ERRORS) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    stop = threading.Event()

    def _on_signal(signum: int, _frame: FrameType | None) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    sim: MotorManagerSim | None = None
    try:
        initial = (None if args.initial_pose == "zero"
                   else (protocol.lower + protocol.upper) / 2.0)
        sim = MotorManagerSim(bus, protocol, speed_limit=args.speed_limit, rate=args.rate,
                              initial_positions=initial,
                              heartbeat_period=args.heartbeat_period,
                              command_timeout=args.command_timeout,
                              effort=not args.no_effort)
        return _run(sim, stop, where)
    except (CrawlerMotionError, ValueError, RuntimeError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    finally:
        if sim is not None and sim.running:
            sim.stop()
        bus.shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


if __name__ == "__main__":
    sys.exit(main())
