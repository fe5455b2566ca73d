"""Injecting the faults of a mission soak into a running simulated stack, and the operator's
recovery (docs/safety.md "After a fault"): what `fault_plan.Fault` says, done to the processes
of a `Supervisor`, the motors' CAN bus and the ROS topics.

`Injector.begin` starts a fault, `Injector.end` ends it (a killed process started again, a
stopped one continued; the others end by themselves), `Injector.recover` runs the motion
chain's documented way back as an operator would (``crawler-motion console recover`` and
``stand`` as commands) and `Injector.send_mission` sends a mission on ``mission``.
"""

from __future__ import annotations

import json
import random
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from crawler_motion.bringup.supervisor import Supervisor
from crawler_motion.testing.bus import BusSpec
from crawler_motion.tools.fault_plan import Fault, FaultKind

#: Time a restarted process gets to show its nodes [s].
RESTART_TIMEOUT = 30.0
#: Time a console command of the recovery gets [s].
CONSOLE_TIMEOUT = 40.0
#: An odometry message's stamp ahead of the clock in the future_odom fault [s].
FUTURE = 3600.0
#: Frames per second of the CAN garbage burst and goals per second of the flood.
BURST_RATE = 1000.0


class Injector:
    """Faults into the stack of ``sup`` (bus ``bus``, environment ``env``); ``node`` is an
    rclpy node of the soak (spun elsewhere) that publishes the topic faults."""

    def __init__(self, sup: Supervisor, bus: BusSpec, env: Mapping[str, str], node: Any,
                 seed: int) -> None:
        from geometry_msgs.msg import PoseStamped
        from nav_msgs.msg import Odometry
        from std_msgs.msg import String

        self.sup, self.bus, self.env, self.node = sup, bus, dict(env), node
        self.rng = random.Random(seed)
        self._odom = node.create_publisher(Odometry, "odom", 10)
        self._goal = node.create_publisher(PoseStamped, "goal_pose", 10)
        self._command = node.create_publisher(String, "gait_command", 10)
        self._mission = node.create_publisher(String, "mission", 10)
        self.lines: list[str] = []  # what the recovery commands printed

    def begin(self, fault: Fault, pose: tuple[float, float]) -> None:
        """Start ``fault``; returns once it is in place (a burst or a flood: when sent)."""
        kind = fault.kind
        if kind is FaultKind.KILL:
            self.sup.send(str(fault.target), signal.SIGKILL)
            self.sup.procs[str(fault.target)].wait(5.0)
        elif kind is FaultKind.STOP:
            self.sup.send(str(fault.target), signal.SIGSTOP)
        elif kind is FaultKind.CAN_GARBAGE:
            self._garbage(fault.length)
        elif kind is FaultKind.ESTOP:
            from std_msgs.msg import String

            self._command.publish(String(data=json.dumps({"command": "estop"})))
        elif kind is FaultKind.FUTURE_ODOM:
            self._future_odom(pose)
        elif kind is FaultKind.GOAL_FLOOD:
            self._flood(fault.length)

    def end(self, fault: Fault, began: float) -> None:
        """End ``fault`` (``began``: its start, monotonic [s]): a stop lasts its length, then
        SIGCONT; a killed process is started again."""
        if fault.kind is FaultKind.STOP:
            time.sleep(max(0.0, began + fault.length - time.monotonic()))
            self.sup.send(str(fault.target), signal.SIGCONT)
        elif fault.kind is FaultKind.KILL:
            self.sup.restart(str(fault.target), RESTART_TIMEOUT)

    def recover(self) -> bool:
        """``console recover`` then ``stand``; True when both succeeded (their output kept in
        `lines`)."""
        return self.console("recover") and self.console("stand")

    def console(self, action: str) -> bool:
        """``crawler-motion console <action>`` as an operator runs it; True on exit 0."""
        cli = str(Path(sys.executable).parent / "crawler-motion")
        done = subprocess.run([cli, "console", "--timeout", str(CONSOLE_TIMEOUT), action],
                              env=self.env, capture_output=True, text=True,
                              timeout=CONSOLE_TIMEOUT + 30.0)
        text = (done.stdout + done.stderr).strip().splitlines()
        self.lines += [f"console {action}: {line}" for line in text[-3:]]
        return done.returncode == 0

    def send_mission(self, text: str, acknowledged: Callable[[], bool],
                     timeout: float = 15.0) -> bool:
        """Publish a mission's text on ``mission`` until ``acknowledged()`` (a restarted
        navigator may not have matched the topic yet), once a second for ``timeout`` [s]."""
        from std_msgs.msg import String

        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self._mission.publish(String(data=text))
            wait = time.monotonic() + 1.0
            while time.monotonic() < wait:
                if acknowledged():
                    return True
                time.sleep(0.05)
        return False

    def _garbage(self, seconds: float) -> None:
        """Random frames (any 11-bit id, 0-8 random bytes) on the motors' bus."""
        import can

        bus = self.bus.open()
        try:
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                data = bytes(self.rng.randrange(256) for _ in range(self.rng.randrange(9)))
                bus.send(can.Message(arbitration_id=self.rng.randrange(0x800), data=data,
                                     is_extended_id=False))
                time.sleep(1.0 / BURST_RATE)
        finally:
            bus.shutdown()

    def _future_odom(self, pose: tuple[float, float]) -> None:
        """One odometry message at the body's position, stamped `FUTURE` ahead."""
        from nav_msgs.msg import Odometry

        msg = Odometry()
        now = self.node.get_clock().now().nanoseconds + int(FUTURE * 1e9)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(now, 1_000_000_000)
        msg.header.frame_id, msg.child_frame_id = "odom", "base_link"
        msg.pose.pose.position.x, msg.pose.pose.position.y = float(pose[0]), float(pose[1])
        msg.pose.pose.orientation.w = 1.0
        self._odom.publish(msg)

    def _flood(self, seconds: float) -> None:
        """Goals 1e9 m away (refused: beyond the maximum goal range) at `BURST_RATE`."""
        from geometry_msgs.msg import PoseStamped

        msg = PoseStamped()
        msg.header.frame_id = "odom"
        msg.pose.position.x, msg.pose.orientation.w = 1e9, 1.0
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self._goal.publish(msg)
            time.sleep(1.0 / BURST_RATE)


def rss_by_process(sup: Supervisor, rss: Callable[[int], float | None]) -> dict[str, float]:
    """RSS [MB] of every running member of ``sup`` (pid-keyed names: ``name@pid``)."""
    out = {}
    for name, proc in sup.procs.items():
        if proc.poll() is None and (value := rss(proc.pid)) is not None:
            out[f"{name}@{proc.pid}"] = value
    return out

