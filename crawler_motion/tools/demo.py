"""``crawler-motion demo``: the whole stack on a cross-process virtual CAN bus, walking.

Starts the seabed simulator (the physical motor manager: a MuJoCo robot in water on the flat
world), the driver (activated) and the planner as separate processes on a python-can
``udp_multicast`` bus (``--interface socketcan --channel vcan0`` for a real virtual CAN), stands
up from the measured pose, walks, stops standing, and prints a summary: frames on the bus,
largest tracking error, final foot error and the body's advance measured by ``odom`` against
the plan's no-slip advance; the simulator writes a PNG and a GIF of the walk (``--out``).
``--sim joint`` runs the joint-only ``motor_manager_sim`` instead (no body, no pictures).
Exit 0 on success.
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

from crawler_motion.model.rotations import quaternion_matrix, roll_pitch
from crawler_motion.runtime.cli_args import OneLineParser, positive_int
from crawler_motion.testing.bus import BusSpec
from crawler_motion.testing.stack import (
    EXECUTABLES,
    STACK_COMMAND_TIMEOUT,
    StackProcesses,
    StackSpec,
    random_domain,
)
from crawler_motion.tools.args import add_gait_option, add_walk_options

PROG = "crawler-motion demo"
#: Driver watchdog of the demo [s] (see `STACK_COMMAND_TIMEOUT`).
DEMO_COMMAND_TIMEOUT = STACK_COMMAND_TIMEOUT
#: Planner states in which the tracking error is recorded.
MOVING = ("WALKING", "STOPPING")
#: ``--sim`` choices: the seabed physics, or the joint-only simulated manager.
SIMS = ("seabed", "joint")
#: File prefix of the pictures in ``--out``; states kept per second for them [Hz].
PICTURES = "demo_walk"
#: File prefix of the run's recording (``.mcap``), CAN log (``.log``) and report directory.
RECORDING = "demo_run"
RECORD_FPS = 10.0
#: The walk options the demo passes on to its walk command (None: not sent).
DIRECTION_OPTIONS = ("heading", "turn")
#: Time after the walk command before the body's attitude counts as steady [s] (the start's
#: half steps).
STEADY_AFTER = 1.5
#: Time the simulator gets to render its pictures after the run [s].
PICTURE_TIMEOUT = 90.0


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """The demo's options (``--rate`` checked to lie in [1, 1000] Hz)."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=positive_int, default=3, help="gait cycles (default 3)")
    add_gait_option(parser)
    add_walk_options(parser, DIRECTION_OPTIONS, " (default: the walk's)")
    parser.add_argument("--rate", type=float, default=100.0, help="planner rate [Hz]")
    parser.add_argument("--interface", default="udp_multicast")
    parser.add_argument("--channel", default=None, help="bus channel (default per interface)")
    parser.add_argument("--timeout", type=float, default=60.0, help="give up after [s]")
    parser.add_argument("--sim", choices=SIMS, default="seabed",
                        help="seabed: physics in water (default); joint: joint-only manager")
    parser.add_argument("--world", default="flat", help="seabed world: a shipped name or an "
                        "MJCF path (default flat)")
    parser.add_argument("--medium", choices=("water", "land"), default="water")
    parser.add_argument("--out", type=Path, default=Path("plots"),
                        help="directory of the pictures (default plots)")
    parser.add_argument("--record", action=argparse.BooleanOptionalAction, default=True,
                        help="record the run (MCAP, CAN log) and its report into --out")
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


class BodyTrack:
    """The body's planar pose (x [m], y [m], yaw [rad]) from ``odom``: latest and marked; and
    its roll and pitch [rad] while `steady` says the walk is in its steady cycles."""

    def __init__(self, steady: Callable[[], bool] = lambda: False) -> None:
        self.pose: np.ndarray | None = None
        self.start: np.ndarray | None = None
        self.steady = steady
        self.attitude: list[tuple[float, float]] = []

    def on_odom(self, msg: Any) -> None:
        """odom callback."""
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        yaw = np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
        self.pose = np.array([p.x, p.y, yaw])
        if self.steady():
            try:
                self.attitude.append(roll_pitch(quaternion_matrix(np.array([q.w, q.x, q.y,
                                                                            q.z]))))
            except ValueError:  # a quaternion without a direction: no attitude sample
                pass

    def attitude_line(self) -> str:
        """The summary line of the body's roll and pitch peak to peak in the steady cycles."""
        if len(self.attitude) < 2:
            return "  body attitude         no steady cycle measured (walk more steps)"
        roll, pitch = np.degrees(np.ptp(np.array(self.attitude), axis=0))
        return (f"  body attitude         roll {roll:.1f}°, pitch {pitch:.1f}° peak to peak over "
                f"the steady cycles ({len(self.attitude)} odom samples)")

    def mark(self) -> None:
        """Take the latest pose as the start of the walk."""
        self.start = None if self.pose is None else self.pose.copy()

    def moved(self) -> np.ndarray:
        """Displacement since `mark` in the body frame at the mark: forward, left [m]."""
        if self.pose is None or self.start is None:
            raise RuntimeError("no odom from seabed_sim")
        d = self.pose[:2] - self.start[:2]
        c, s = np.cos(self.start[2]), np.sin(self.start[2])
        return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


def planned_advance(args: argparse.Namespace) -> np.ndarray:
    """The walk's no-slip body displacement (forward, left [m]) of the plan the planner
    executes for ``--gait`` / ``--steps`` with the configured step."""
    from crawler_motion.model.config import load_config
    from crawler_motion.motion.gait import WalkParams, plan_walk
    from crawler_motion.sim.seabed.metrics import planned_displacement

    cfg = load_config()
    chosen = {name: getattr(args, name) for name in DIRECTION_OPTIONS
              if getattr(args, name, None) is not None}
    plan = plan_walk(cfg, WalkParams.defaults(cfg.gait, gait=args.gait, **chosen), args.steps)
    return planned_displacement(plan)[:2]


def advance_line(moved: np.ndarray, planned: np.ndarray) -> str:
    """The summary line of the body's advance ``moved`` against ``planned`` (forward, left
    [m]): along the planned direction, and to its left."""
    length = float(np.hypot(*planned))
    if length < 1e-6:
        return (f"  body advance          {moved[0] * 1e3:.1f} mm of 0.0 mm planned without "
                f"slip (nan), {moved[1] * 1e3:+.1f} mm left (odom)")
    unit = planned / length
    along, left = float(moved @ unit), float(unit[0] * moved[1] - unit[1] * moved[0])
    return (f"  body advance          {along * 1e3:.1f} mm of {length * 1e3:.1f} mm "
            f"planned without slip ({along / length:.2f}), {left * 1e3:+.1f} mm left (odom)")


def print_summary(status: dict[str, Any], counts: dict[str, int], errors: list[float],
                  feet_err: float, elapsed: float, extra: Sequence[str] = ()) -> None:
    """The demo's closing summary (``feet_err`` [m], ``elapsed`` [s]); ``extra`` lines go
    before the wall time."""
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
    for line in extra:
        print(line)
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
        self.physical = args.sim == "seabed"
        self.pictures = [args.out / f"{PICTURES}.png", args.out / f"{PICTURES}.gif"]
        seabed = {"world": args.world, "medium": args.medium, "record_fps": RECORD_FPS,
                  "record": str(args.out.resolve() / PICTURES)} if self.physical else None
        self.spec = StackSpec(self.bus, rate=args.rate, command_timeout=DEMO_COMMAND_TIMEOUT,
                              speed_limit=float(self.cfg.robot.velocity.max()),
                              planner={"gait": args.gait}, names={n: n for n in EXECUTABLES},
                              seabed=seabed)
        self.walk_sent: float | None = None
        self.body = BodyTrack(self._steady)
        self.procs = StackProcesses(Path(tempfile.mkdtemp(prefix="crawler-demo-")))
        self.tap: Any = None
        self.console: Any = None
        self.t_start = time.monotonic()

    def _steady(self) -> bool:
        """True in the walk's steady cycles: `STEADY_AFTER` after the walk command, while
        the planner walks (not yet stopping)."""
        status = self.console.status if self.console is not None else None
        return (self.walk_sent is not None and time.monotonic() - self.walk_sent > STEADY_AFTER
                and (status or {}).get("state") == "WALKING")

    def say(self, line: str) -> None:
        """A progress line with the time since the start."""
        print(f"[{time.monotonic() - self.t_start:6.2f} s] {line}", flush=True)

    def start(self) -> Tracker:
        """Start the processes, the tap and the console; returns the tracker once measured
        joint_states arrive."""
        from sensor_msgs.msg import JointState

        from crawler_motion.testing.tap import BusTap, FamilyCounter
        from crawler_motion.tools.console import Console

        manager = (f"seabed_sim ({self.args.world} world, {self.args.medium})"
                   if self.physical else "motor manager sim")
        self.say(f"starting {manager}, driver and planner on {self.bus} "
                 f"(logs in {self.procs.logs})")
        for old in self.pictures:
            old.unlink(missing_ok=True)
        self.procs.start({**self.recorder(), **self.spec.commands()}, os.environ.copy())
        self.tap = BusTap(self.bus.open(), [FamilyCounter(self.protocol)], timeout=0.1)
        console = self.console = Console("crawler_demo")
        console.printer = lambda line: self.say(f"planner: {line.split('] ', 1)[-1]}")
        tracker = Tracker(self.cfg.robot.joint_names,
                          lambda: (console.status or {}).get("state") in MOVING)
        console.node.create_subscription(JointState, "joint_commands", tracker.on_command, 50)
        console.node.create_subscription(JointState, "joint_states", tracker.on_state, 50)
        if self.physical:
            from nav_msgs.msg import Odometry

            console.node.create_subscription(Odometry, "odom", self.body.on_odom, 10)
        if not console.connect(30.0):
            raise RuntimeError(f"the planner did not come up within 30 s{self.procs.died()}")
        console.wait_until(lambda: tracker.measured is not None or self.procs.died(), 30.0)
        if self.procs.died():
            raise RuntimeError(f"the stack did not come up{self.procs.died()}")
        if tracker.measured is None:
            raise RuntimeError("no measured joint_states from the driver within 30 s "
                               "(is the driver active and the manager answering?)")
        if self.physical and not console.wait_until(lambda: self.body.pose is not None, 30.0):
            raise RuntimeError(f"no odom from seabed_sim within 30 s{self.procs.died()}")
        self.say("stack up: driver active, measured joint_states arriving")
        return tracker

    def walk(self) -> None:
        """Stand, walk ``--steps`` cycles, settle."""
        args = self.args
        walk = {"command": "walk", "steps": args.steps, "gait": args.gait,
                **{name: getattr(args, name) for name in DIRECTION_OPTIONS
                   if getattr(args, name) is not None}}
        for command in ({"command": "stand"}, walk):
            if command["command"] == "walk":
                self.console.spin_for(0.2)
                self.body.mark()
                self.walk_sent = time.monotonic()
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
        extra = [advance_line(self.body.moved(), planned_advance(self.args)),
                 self.body.attitude_line()] if self.physical else []
        print_summary(self.console.status or {}, counts, tracker.errors, feet_err, elapsed,
                      extra)

    def write_pictures(self) -> None:
        """Stop the stack (the simulator renders on shutdown) and say where the pictures are."""
        if not self.physical:
            return
        self.say("stopping the stack; seabed_sim renders its pictures on shutdown")
        self.procs.stop(timeout=PICTURE_TIMEOUT)
        if all(path.is_file() for path in self.pictures):
            print(f"  pictures              {', '.join(str(p) for p in self.pictures)}")
            return
        said = [line.split("]: ", 1)[-1] for line in
                self.procs.tail(self.spec.names["seabed_sim"], 20) if "pictures" in line]
        print(f"  pictures              none: {said[-1] if said else 'see the seabed_sim log'}")

    def recorder(self) -> dict[str, list[str]]:
        """The recorder's command line (``--record``: all topics and the CAN bus)."""
        from crawler_motion.recording.launch import record_command

        out = self.args.out
        if self.args.record:
            out.mkdir(parents=True, exist_ok=True)
        return {"recorder": record_command(out / f"{RECORDING}.mcap", self.bus,
                                           out / f"{RECORDING}.log")} if self.args.record else {}

    def write_report(self) -> None:
        """Stop the recorder and write the recording's report into ``--out``."""
        if not self.args.record:
            return
        from crawler_motion.recording.report import main as report

        self.procs.stop(["recorder"])
        out = self.args.out
        print(f"  recording             {out / RECORDING}.mcap, CAN log {out / RECORDING}.log")
        report([str(out / f"{RECORDING}.mcap"), "-o", str(out / f"{RECORDING}_report")])

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
        demo.write_pictures()
        demo.write_report()
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
