"""``crawler-motion demo``: the whole stack on a cross-process virtual CAN bus, walking.

Starts the simulated motor manager, the driver (activated) and the planner as separate
processes on a python-can ``udp_multicast`` bus (``--interface socketcan --channel vcan0`` for
a real virtual CAN), stands up from the measured pose, walks, stops standing, and prints a
summary: frames on the bus, largest tracking error, final foot error. Exit 0 on success.
"""

from __future__ import annotations

import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.tools.args import OneLineParser, positive_int

PROG = "crawler-motion demo"
#: Driver watchdog of the demo [s]. The driver's default (0.2 s) is meant for a dedicated
#: controller; on a shared laptop or CI machine a starved planner process can miss it, and a
#: tripped watchdog (correctly) needs an explicit re-enable, which would end the demo.
DEMO_COMMAND_TIMEOUT = 1.0


def free_udp_port() -> int:
    """A UDP port free right now (one per cross-process bus: sockets bind the port)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        return int(s.getsockname()[1])


class BusTap:
    """Counts the frames on the bus by family (a passive listener in a thread)."""

    def __init__(self, bus: Any, protocol: Any) -> None:
        self.bus = bus
        self.families = {fid: kind for kind in ("control", "target", "position", "status",
                                                "heartbeat")
                         for fid in protocol.frame_ids(kind)}
        self.counts: Counter[str] = Counter()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bus-tap", daemon=True)

    def start(self) -> None:
        """Start listening."""
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self.bus.recv(timeout=0.1)
            except Exception:
                continue
            if msg is not None:
                kind = self.families.get(msg.arbitration_id, "other")
                self.counts[kind] += 1
                self.on_frame(msg, kind)

    def on_frame(self, msg: Any, kind: str) -> None:
        """Called in the listener thread for every frame, after counting it; a hook for
        subclasses (``kind``: control, target, position, status, heartbeat or other)."""

    def stop(self) -> None:
        """Stop listening and close the bus."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.bus.shutdown()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the demo; returns the exit status."""
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

    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(1, 101)))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    import can
    from can.interfaces.udp_multicast import UdpMulticastBus

    from crawler_motion.canbus.protocol import MotorProtocol
    from crawler_motion.model.config import load_config
    from crawler_motion.model.kinematics import forward_kinematics
    from crawler_motion.tools.console import Console, describe

    cfg = load_config()
    protocol = MotorProtocol.from_config(cfg.robot)
    udp = args.interface == "udp_multicast"
    channel = args.channel or (UdpMulticastBus.DEFAULT_GROUP_IPv4 if udp else "vcan0")
    port = free_udp_port() if udp else 0
    logs = Path(tempfile.mkdtemp(prefix="crawler-demo-"))
    py = sys.executable
    bus_args = ["--interface", args.interface, "--channel", channel]
    ros_bus = ["-p", f"can_interface:={args.interface}", "-p", f"can_channel:={channel}"]
    if udp:
        bus_args += ["--port", str(port)]
        ros_bus += ["-p", f"can_port:={port}"]
    commands = {
        "motor_manager_sim": [py, "-m", "crawler_motion.sim.motor_manager", *bus_args,
                              "--speed-limit", str(float(cfg.robot.velocity.max()))],
        "driver_node": [py, "-m", "crawler_motion.driver.node", "--ros-args",
                        "-p", "autostart:=true", "-p", f"command_timeout:={DEMO_COMMAND_TIMEOUT}",
                        *ros_bus],
        "planner_node": [py, "-m", "crawler_motion.planner.node", "--ros-args",
                         "-p", f"rate:={float(args.rate)}", "-p", f"gait:={args.gait}"],
    }
    procs: dict[str, subprocess.Popen[bytes]] = {}
    tap: BusTap | None = None
    import rclpy

    rclpy.init()
    console: Console | None = None
    t_start = time.monotonic()

    def say(line: str) -> None:
        print(f"[{time.monotonic() - t_start:6.2f} s] {line}", flush=True)

    try:
        where = f"{args.interface} {channel}" + (f":{port}" if udp else "")
        say(f"starting motor manager sim, driver and planner on {where} (logs in {logs})")
        for name, cmd in commands.items():
            procs[name] = subprocess.Popen(cmd, stdout=open(logs / f"{name}.log", "wb"),
                                           stderr=subprocess.STDOUT, env=os.environ.copy())
        bus_kwargs: dict[str, Any] = {"port": port, "receive_own_messages": False} if udp else {}
        tap = BusTap(can.Bus(interface=args.interface, channel=channel, **bus_kwargs), protocol)
        tap.start()
        from sensor_msgs.msg import JointState

        console = Console("crawler_demo")
        console.printer = lambda line: say(f"planner: {line.split('] ', 1)[-1]}")
        latest_cmd: dict[str, np.ndarray] = {}
        errors: list[float] = []
        measured: dict[str, np.ndarray] = {}
        names = list(cfg.robot.joint_names)

        def on_cmd(msg: JointState) -> None:
            if list(msg.name) == names:
                latest_cmd["q"] = np.array(msg.position)

        def on_state(msg: JointState) -> None:
            if list(msg.name) != names:
                return
            q = np.array(msg.position)
            measured["q"] = q
            if "q" in latest_cmd and console is not None and (console.status or {}).get(
                    "state") in ("WALKING", "STOPPING"):
                errors.append(float(np.abs(q - latest_cmd["q"]).max()))

        console.node.create_subscription(JointState, "joint_commands", on_cmd, 50)
        console.node.create_subscription(JointState, "joint_states", on_state, 50)
        if not console.connect(30.0):
            raise RuntimeError("the planner did not come up within 30 s")
        if not console.wait_until(lambda: "q" in measured, 30.0):
            raise RuntimeError("no measured joint_states from the driver within 30 s "
                               "(is the driver active and the manager answering?)")
        say("stack up: driver active, measured joint_states arriving")
        for command in ({"command": "stand"},
                        {"command": "walk", "steps": args.steps, "gait": args.gait}):
            say(f"operator: {command}")
            ok, message = console.run_when_ready(command, args.timeout)
            if not ok:
                raise RuntimeError(f"{command['command']}: {message}")
        console.spin_for(0.5)
        elapsed = time.monotonic() - t_start
        tap.stop()
        counts, tap = dict(tap.counts), None
        q_end = measured["q"].reshape(cfg.robot.n_legs, 3)
        feet_err = np.abs(forward_kinematics(cfg.robot, q_end)
                          - cfg.robot.standing_feet()).max()
        print()
        print("summary")
        print(f"  final state           {describe(console.status or {})}")
        print(f"  command frames        {counts.get('target', 0)} targets, "
              f"{counts.get('control', 0)} control (driver -> manager)")
        print(f"  feedback frames       {counts.get('position', 0)} positions, "
              f"{counts.get('status', 0)} status, {counts.get('heartbeat', 0)} heartbeats "
              f"(manager -> driver)")
        print(f"  largest tracking err  {max(errors) if errors else float('nan'):.4f} rad "
              f"over {len(errors)} measured samples while walking")
        print(f"  final foot error      {feet_err * 1e3:.2f} mm from the standing position")
        print(f"  wall time             {elapsed:.1f} s")
        return 0
    except (RuntimeError, OSError, can.CanError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        for name in procs:
            tail = (logs / f"{name}.log").read_text(errors="replace").splitlines()[-5:]
            print(f"--- {name} (last lines) ---\n" + "\n".join(tail), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        if tap is not None:
            tap.stop()
        if console is not None:
            console.close()
        rclpy.try_shutdown()
        for proc in procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in procs.values():
            try:
                proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


if __name__ == "__main__":
    sys.exit(main())
