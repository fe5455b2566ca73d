"""Topside and robot over a network link: the planner and the operator's console on the host,
the driver and the simulated manager in a network namespace of their own joined by a veth pair
(`testing.netns.Tether`); DDS discovers across it by unicast to the peer (``ROS_STATIC_PEERS``,
range LOCALHOST: no multicast crosses the link) with the shipped ``config/fastdds_tether.xml``.
Measured and printed (``pytest -s``): the joint command latency across the link (JointState
stamp on the topside -> CAN frame on the robot's bus), and a 1 s drop of the link mid-walk: the
driver's watchdog holds the robot, the operator recovers (``crawler-motion console recover``).
Skipped with the reason where network namespaces cannot be created (needs root).

This process only talks to the planner (on the host, over the loopback): a process keeps the
network interfaces Fast DDS found when it made its first participant, and this one may have
made it (another test) before the veth pair existed. What crosses the link is between
processes started after it: the planner, the driver and the console's ``recover``.
"""

from __future__ import annotations

import os
import random
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from crawler_motion.canbus.protocol import ControlFrame, MotorProtocol, TargetFrame  # noqa: E402
from crawler_motion.errors import ProtocolError  # noqa: E402
from crawler_motion.model.config import config_path, load_config  # noqa: E402
from crawler_motion.testing.bus import BusSpec  # noqa: E402
from crawler_motion.testing.netns import NetnsRecorder, Tether, netns_unavailable  # noqa: E402
from crawler_motion.testing.stack import StackProcesses, StackSpec  # noqa: E402
from crawler_motion.tools.console import Console  # noqa: E402

CFG = load_config()
PROTOCOL = MotorProtocol.from_config(CFG.robot)
NAMES = list(CFG.robot.joint_names)
WAIT = 30.0  # [s] generous bound of waits for a state (never a measured time)
RATE = 100.0  # [Hz] planner rate
WATCHDOG = 0.3  # [s] the driver's command_timeout in this test
DROP = 1.0  # [s] the link is down this long


def _discovery_env(domain: int, peer: str) -> dict[str, str]:
    """DDS across the tether: unicast discovery of ``peer``, the shipped tether profile."""
    return {"ROS_DOMAIN_ID": str(domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "ROS_STATIC_PEERS": peer,
            "FASTRTPS_DEFAULT_PROFILES_FILE": str(config_path("fastdds_tether.xml"))}


@pytest.fixture()
def tethered(tmp_path: Path) -> Iterator[dict[str, Any]]:
    reason = netns_unavailable()
    if reason is not None:
        pytest.skip(f"no topside/robot split here: {reason}")
    tether = Tether.create()
    domain = random.randint(102, 200)
    bus = BusSpec.fresh()
    procs = StackProcesses(tmp_path)
    commands = StackSpec(bus, rate=RATE, command_timeout=WATCHDOG, speed_limit=6.0,
                         driver={"diagnostics_period": 0.2}).commands()
    recorder = NetnsRecorder(tether.robot, bus)
    console = None
    topside = {**os.environ, **_discovery_env(domain, tether.robot_ip)}
    try:
        assert recorder.wait_ready(WAIT), "no bus recorder in the robot's namespace"
        procs.start({name: tether.command(commands[name]) for name in ("sim", "driver")},
                    {**os.environ, **_discovery_env(domain, tether.host_ip)})
        procs.start({"planner": commands["planner"]}, topside)
        rclpy.init(domain_id=domain)
        console = Console("tether_console")
        console.printer = lambda _line: None
        yield {"tether": tether, "procs": procs, "console": console, "recorder": recorder,
               "topside": topside}
    finally:
        if console is not None:
            console.close()
        rclpy.try_shutdown()
        procs.stop()
        recorder.kill()
        tether.close()


def _decode(frames: list[tuple[float, int, bytes]]) -> list[tuple[float, Any]]:
    import can

    out = []
    for t, fid, data in frames:
        try:
            out.append((t, PROTOCOL.decode(can.Message(arbitration_id=fid, data=data,
                                                       is_extended_id=False))))
        except ProtocolError:
            continue
    return out


def _latencies(commands: list[tuple[float, np.ndarray]], decoded: list[tuple[float, Any]]
               ) -> np.ndarray:
    """Per command: kernel time of the first target frame of its group - its stamp [s]
    (NaN where no group carried it); a group is keyed by its decoded positions."""
    groups: dict[int, tuple[float, dict[str, float]]] = {}
    first: dict[tuple[float, ...], float] = {}
    for t, frame in decoded:
        if isinstance(frame, TargetFrame):
            t0, positions = groups.setdefault(frame.counter, (t, {}))
            positions.update(frame.positions)
            if len(positions) == len(NAMES):
                first.setdefault(tuple(positions[n] for n in NAMES), t0)
                del groups[frame.counter]
    out = []
    for stamp, q in commands:
        key = {}
        for msg in PROTOCOL.encode_targets(q, 1):
            key.update(PROTOCOL.decode(msg).positions)
        t = first.get(tuple(key[n] for n in NAMES))
        out.append(np.nan if t is None else t - stamp)
    return np.array(out)


def test_planner_topside_driver_on_the_robot_across_a_tether_that_drops(tethered) -> None:
    tether, procs, console = tethered["tether"], tethered["procs"], tethered["console"]
    commands: list[tuple[float, np.ndarray]] = []

    def on_command(msg: JointState) -> None:
        commands.append((msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9,
                         np.array(msg.position)))

    console.node.create_subscription(JointState, "joint_commands", on_command, QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    assert console.connect(WAIT), f"no planner\n{procs.log_tails(10)}"
    ok, message = console.run_when_ready({"command": "stand"}, WAIT)
    assert ok, f"stand across the tether: {message}\n{procs.log_tails(10)}"
    assert console.run_when_ready({"command": "walk"}, WAIT)[0]
    t_walk = time.time()
    console.spin_for(2.0)
    walked = [c for c in commands if c[0] >= t_walk]

    t_down = time.time()
    tether.set_link(False)
    console.spin_for(DROP)
    tether.set_link(True)
    t_up = time.time()
    assert console.wait_until(lambda: (console.status or {}).get("state") == "IDLE", WAIT), (
        f"the planner did not end the walk after the link came back: {console.status}")
    t_idle = time.time()
    recovered = subprocess.run(
        [sys.executable, "-m", "crawler_motion.tools.cli", "console", "--timeout", "20",
         "recover"], env=tethered["topside"], capture_output=True, text=True, timeout=60)
    assert recovered.returncode == 0, recovered.stdout + recovered.stderr
    t_recovered = time.time()
    ok, message = console.run_when_ready({"command": "stand"}, WAIT)
    assert ok, f"stand after the recovery: {message}"
    assert console.run_when_ready({"command": "walk", "steps": 1}, WAIT)[0]
    console.spin_for(0.3)
    decoded = _decode(tethered["recorder"].finish())

    latency = _latencies(walked, decoded) * 1e3
    reached = np.isfinite(latency)
    controls = [(t, f.command) for t, f in decoded if isinstance(f, ControlFrame)]
    targets = [t for t, f in decoded if isinstance(f, TargetFrame)]
    holds = [t for t, c in controls if c == "hold" and t_down < t < t_up]
    t_hold = holds[0] if holds else float("nan")
    last_before = max((t for t in targets if t < t_hold), default=float("nan"))
    enables = [t for t, c in controls if c == "enable" and t > t_up]
    print(f"\n[tether] {len(walked)} commands across the link at {RATE:g} Hz, "
          f"{reached.mean() * 100:.1f} % on the robot's bus; JointState->CAN p50 "
          f"{np.nanpercentile(latency, 50):.2f} ms, p99 {np.nanpercentile(latency, 99):.2f} "
          f"ms, max {np.nanmax(latency):.2f} ms")
    print(f"[tether] link down {DROP:g} s: last target frame {(last_before - t_down) * 1e3:.0f}"
          f" ms after the drop, driver watchdog 'hold' {(t_hold - t_down) * 1e3:.0f} ms after "
          f"it (command_timeout {WATCHDOG:g} s); link up: planner IDLE after "
          f"{(t_idle - t_up) * 1e3:.0f} ms; `crawler-motion console recover` (a new process: "
          f"discovery included) {(t_recovered - t_idle):.2f} s, then stand and walk again")
    assert reached.mean() > 0.9, f"{reached.mean():.2f} of the commands reached the bus"
    assert holds, f"no watchdog hold on the robot during the drop: {controls}"
    # the robot held: no target frame from the hold until the operator's enable
    assert enables and not [t for t in targets if t_hold < t < enables[0]]
    assert [t for t in targets if t > enables[0]], "no walk after the recovery"
