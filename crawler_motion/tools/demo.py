"""``crawler-motion demo``: the whole stack on a cross-process virtual CAN bus, walking.

Starts the simulated motor manager, the driver (activated) and the planner as separate
processes on a python-can ``udp_multicast`` bus (``--interface socketcan --channel vcan0`` for
a real virtual CAN), stands up from the measured pose, walks, stops standing, and prints a
summary: frames on the bus, largest tracking error, final foot error. Exit 0 on success.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.runtime.cli_args import OneLineParser, positive_int
from crawler_motion.testing.bus import BusSpec
from crawler_motion.testing.stack import (
    EXECUTABLES,
    STACK_COMMAND_TIMEOUT,
    StackProcesses,
    StackSpec,
    random_domain,
)

PROG = "crawler-motion demo"
#: Driver watchdog of the demo [s] (see `STACK_COMMAND_TIMEOUT`).
DEMO_COMMAND_TIMEOUT = STACK_COMMAND_TIMEOUT
#: Planner states in which the tracking error is recorded.
MOVING = ("WALKING", "STOPPING")


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """The demo's options (``--rate`` checked to lie in [1, 1000] Hz)."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=positive_int, default=3, help="gait cycles (default 3)")
    parser.add_argument("--gait", choices=("diagonal", "wave"), default="diagonal")
    parser.add_argument("--rate", type=float, default=100.0, help="planner rate [Hz]")
    parser.add_argument("--interface", default="udp_multicast")
    parser.add_argument("--channel", default=None, help="bus channel (default per interface)")
    parser.add_argument("--timeout", type=float, default=60.0, help="give up after [s]")
    args = parser.parse_args(argv)
    if not (np.isfinite(args.rate) and 1.0 <= args.rate <= 1000.0):
        parser.error(f"--rate must be in [1, 1000] Hz, got {args.rate}")
    return args


class Tracker:
    """Measured joint_states against the latest joint_commands while the planner walks [rad]."""

    def __init__(self, names: Sequence[str], moving: Callable[[], bool]) -> None:
        self.names = list(names)
        self.moving = moving
        self.command: np.ndarray | None = None
        self.measured: np.ndarray | None = None
        self.errors: list[float] = []

    def on_command(self, msg: Any) -> None:
        """joint_commands callback."""
        if list(msg.name) == self.names:
            self.command = np.array(msg.position)

    def on_state(self, msg: Any) -> None:
        """joint_states callback."""
        if list(msg.name) != self.names:
            return
        self.measured = np.array(msg.position)
        if self.command is not None and self.moving():
            self.errors.append(float(np.abs(self.measured - self.command).max()))


def print_summary(status: dict[str, Any], counts: dict[str, int], errors: list[float],
                  feet_err: float, elapsed: float) -> None:
    """The demo's closing summary (``feet_err`` [m], ``elapsed`` [s])."""
    from crawler_motion.tools.console import describe

    print()
    print("summary")
    print(f"  final state           {describe(status)}")
    print(f"  command frames        {counts.get('target', 0)} targets, "
          f"{counts.get('control', 0)} control (driver -> manager)")
    print(f"  feedback frames       {counts.get('position', 0)} positions, "
          f"{counts.get('status', 0)} status, {counts.get('heartbeat', 0)} heartbeats "
          f"(manager -> driver)")
    print(f"  largest tracking err  {max(errors) if errors else float('nan'):.4f} rad "
          f"over {len(errors)} measured samples while walking")
    print(f"  final foot error      {feet_err * 1e3:.2f} mm from the standing position")
    print(f"  wall time             {elapsed:.1f} s")


class Demo:
    """One demo run: the stack's processes, a bus tap counting frames and an operator console."""

    def __init__(self, args: argparse.Namespace) -> None:
        from crawler_motion.canbus.protocol import MotorProtocol
        from crawler_motion.model.config import load_config

        self.args = args
        self.cfg = load_config()
        self.protocol = MotorProtocol.from_config(self.cfg.robot)
        self.bus = BusSpec.fresh(args.interface, args.channel)
        self.spec = StackSpec(self.bus, rate=args.rate, command_timeout=DEMO_COMMAND_TIMEOUT,
                              speed_limit=float(self.cfg.robot.velocity.max()),
                              planner={"gait": args.gait}, names={n: n for n in EXECUTABLES})
        self.procs = StackProcesses(Path(tempfile.mkdtemp(prefix="crawler-demo-")))
        self.tap: Any = None
        self.console: Any = None
        self.t_start = time.monotonic()

    def say(self, line: str) -> None:
        """A progress line with the time since the start."""
        print(f"[{time.monotonic() - self.t_start:6.2f} s] {line}", flush=True)

    def start(self) -> Tracker:
        """Start the processes, the tap and the console; returns the tracker once measured
        joint_states arrive."""
        from sensor_msgs.msg import JointState

        from crawler_motion.testing.tap import BusTap, FamilyCounter
        from crawler_motion.tools.console import Console

        self.say(f"starting motor manager sim, driver and planner on {self.bus} "
                 f"(logs in {self.procs.logs})")
        self.procs.start(self.spec.commands(), os.environ.copy())
        self.tap = BusTap(self.bus.open(), [FamilyCounter(self.protocol)], timeout=0.1)
        console = self.console = Console("crawler_demo")
        console.printer = lambda line: self.say(f"planner: {line.split('] ', 1)[-1]}")
        tracker = Tracker(self.cfg.robot.joint_names,
                          lambda: (console.status or {}).get("state") in MOVING)
        console.node.create_subscription(JointState, "joint_commands", tracker.on_command, 50)
        console.node.create_subscription(JointState, "joint_states", tracker.on_state, 50)
        if not console.connect(30.0):
            raise RuntimeError("the planner did not come up within 30 s")
        if not console.wait_until(lambda: tracker.measured is not None, 30.0):
            raise RuntimeError("no measured joint_states from the driver within 30 s "
                               "(is the driver active and the manager answering?)")
        self.say("stack up: driver active, measured joint_states arriving")
        return tracker

    def walk(self) -> None:
        """Stand, walk ``--steps`` cycles, settle."""
        args = self.args
        for command in ({"command": "stand"},
                        {"command": "walk", "steps": args.steps, "gait": args.gait}):
            self.say(f"operator: {command}")
            ok, message = self.console.run_when_ready(command, args.timeout)
            if not ok:
                raise RuntimeError(f"{command['command']}: {message}")
        self.console.spin_for(0.5)

    def finish(self, tracker: Tracker) -> None:
        """Stop the tap and print the summary."""
        from crawler_motion.model.kinematics import forward_kinematics

        elapsed = time.monotonic() - self.t_start
        self.tap.stop()
        counts = dict(self.tap.listeners[0].counts)
        robot = self.cfg.robot
        assert tracker.measured is not None
        q_end = tracker.measured.reshape(robot.n_legs, 3)
        feet_err = float(np.abs(forward_kinematics(robot, q_end) - robot.standing_feet()).max())
        print_summary(self.console.status or {}, counts, tracker.errors, feet_err, elapsed)

    def report_failure(self, exc: Exception) -> None:
        """The error and the last lines of every log, on stderr."""
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        print(self.procs.log_tails(5, "--- {name} (last lines) ---"), file=sys.stderr)

    def close(self) -> None:
        """Tear everything down (idempotent)."""
        import rclpy

        if self.tap is not None:
            self.tap.stop()
        if self.console is not None:
            self.console.close()
        rclpy.try_shutdown()
        self.procs.stop()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the demo; returns the exit status."""
    args = parse_args(argv)
    os.environ.setdefault("ROS_DOMAIN_ID", str(random_domain()))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    import can
    import rclpy

    demo = Demo(args)
    rclpy.init()
    try:
        tracker = demo.start()
        demo.walk()
        demo.finish(tracker)
        return 0
    except (RuntimeError, OSError, can.CanError) as exc:
        demo.report_failure(exc)
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        demo.close()


if __name__ == "__main__":
    sys.exit(main())
