"""``seabed_sim`` as a process, launch-free, on a cross-process bus and a ROS domain of its own:
the stack walks it forward, its scan sees the shipped wall, its IMU agrees with odom, and a bad
world file is refused before anything starts."""

from __future__ import annotations

import json
import random
import subprocess
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from nav_msgs.msg import Odometry  # noqa: E402
from sensor_msgs.msg import Imu, PointCloud2  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from crawler_motion.model.config import load_config, load_scanner  # noqa: E402
from crawler_motion.model.rotations import rpy_matrix  # noqa: E402
from crawler_motion.motion.gait import WalkParams, plan_walk  # noqa: E402
from crawler_motion.sim.seabed.metrics import planned_displacement  # noqa: E402
from crawler_motion.sim.seabed.model import SimSettings  # noqa: E402
from crawler_motion.testing.bus import BusSpec  # noqa: E402
from crawler_motion.testing.stack import (  # noqa: E402
    StackProcesses,
    StackSpec,
    isolated_env,
    node_command,
    ros_args,
)
from crawler_motion.tools.console import Console  # noqa: E402
from crawler_motion.tools.procstat import cpu_seconds  # noqa: E402

STEPS = 2  # gait cycles walked


def planned_advance(steps: int) -> float:
    """The forward body path of the default walk if no foot slipped [m]."""
    return float(planned_displacement(plan_walk(load_config(), WalkParams(), steps))[0])

WALL_X = 0.60  # near face of the shipped wall [m]


#: The simulator's physics timestep [s].
TIMESTEP = SimSettings().timestep


def _quat(q: Any) -> np.ndarray:
    return np.array([q.w, q.x, q.y, q.z])


def _xyz(v: Any) -> np.ndarray:
    return np.array([v.x, v.y, v.z])


def _rotation(wxyz: np.ndarray) -> np.ndarray:
    w, x, y, z = wxyz
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


class Recorder:
    """A console node that also keeps odom, imu and scan messages (with arrival order)."""

    def __init__(self, name: str) -> None:
        self.console = Console(name)
        self.console.printer = lambda _line: None
        self.odom: list[Odometry] = []
        self.imu: list[Imu] = []
        self.scan: list[PointCloud2] = []
        self.contacts: list[dict[str, Any]] = []  # the planner's foot_contacts
        node = self.console.node
        node.create_subscription(String, "foot_contacts",
                                 lambda m: self.contacts.append(json.loads(m.data)), 100)
        node.create_subscription(Odometry, "odom", self.odom.append, 100)
        node.create_subscription(Imu, "imu", self.imu.append, 100)
        node.create_subscription(PointCloud2, "scan", self.scan.append, 10)


def _start(tmp_path: Path, spec: StackSpec, domain: int) -> StackProcesses:
    procs = StackProcesses(tmp_path)
    procs.start(spec.commands(), isolated_env(domain))
    return procs


def test_the_stack_walks_the_physical_robot_forward(tmp_path: Path, ros_domain: int) -> None:
    spec = StackSpec(BusSpec.fresh(), rate=100.0, seabed={"world": "flat"})
    procs = _start(tmp_path, spec, ros_domain)
    rec = Recorder("seabed_walk_console")
    try:
        console = rec.console
        assert console.connect(30.0), procs.log_tails(30)
        assert console.wait_until(lambda: len(rec.odom) > 10, 30.0), procs.log_tails(30)
        ok, message = console.run_when_ready({"command": "stand"}, 30.0)
        assert ok, f"{message}\n{procs.log_tails(30)}"
        # the efforts reach the planner: every standing foot is in contact
        assert console.wait_until(lambda: rec.contacts and rec.contacts[-1]["effort"] and {
            f["contact"] for f in rec.contacts[-1]["feet"].values()} == {"yes"}, 5.0), (
            rec.contacts[-1:])
        walking_from = len(rec.contacts)
        start = rec.odom[-1].pose.pose.position.x
        pid = procs.pids()["seabed"]
        cpu0, wall0 = cpu_seconds(pid), time.monotonic()
        ok, message = console.run_when_ready({"command": "walk", "steps": STEPS}, 30.0)
        assert ok, f"{message}\n{procs.log_tails(30)}"
        cpu = (cpu_seconds(pid) or 0.0) - (cpu0 or 0.0)
        cpu_share = cpu / (time.monotonic() - wall0)
        console.spin_for(0.5)
        lifted = {leg for c in rec.contacts[walking_from:] for leg, f in c["feet"].items()
                  if f["contact"] == "no"}
        assert lifted == {"lf", "lb", "rb", "rf"}  # each swinging foot seen off the ground
        advance = rec.odom[-1].pose.pose.position.x - start
        plan = planned_advance(STEPS)
        assert 0.5 * plan < advance < 1.5 * plan, (
            f"advance {advance:.4f} m of {plan:.4f} m planned\n{procs.log_tails(30)}")
        # the IMU's attitude is the body's (same stamp), while moving
        odom = {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in rec.odom}
        # (MuJoCo computes the sensors before it integrates a step: the IMU's orientation is
        # one timestep older than the body's, so they differ by up to |ω| × timestep)
        pairs = [(_quat(m.orientation), _quat(odom[k].pose.pose.orientation),
                  float(np.linalg.norm(_xyz(m.angular_velocity))))
                 for m in rec.imu if (k := (m.header.stamp.sec, m.header.stamp.nanosec)) in odom]
        assert len(pairs) > 100
        excess = [2 * np.arccos(min(1.0, abs(float(a @ b)))) - 1.5 * w * TIMESTEP
                  for a, b, w in pairs]
        assert max(excess) < 1e-4, max(excess)
        print(f"\nseabed_sim: body advanced {advance * 1e3:.1f} mm of {plan * 1e3:.1f} mm "
              f"planned in {STEPS} steps; CPU while walking {100 * cpu_share:.0f} % of a core")
    finally:
        rec.console.close()
        procs.stop()


def test_the_scan_sees_the_wall_at_its_true_distance(tmp_path: Path, ros_domain: int) -> None:
    bus = BusSpec.fresh()
    procs = StackProcesses(tmp_path)
    procs.start({"seabed": [*node_command("seabed_sim"), *ros_args(
        {**bus.ros_params(), "world": "wall"})]}, isolated_env(ros_domain))
    rec = Recorder("seabed_scan_console")
    try:
        assert rec.console.wait_until(lambda: len(rec.scan) >= 2 and rec.odom, 30.0), (
            procs.log_tails(30))
        msg, odom = rec.scan[-1], rec.odom[-1].pose.pose
        assert msg.header.frame_id == "scanner_link"
        assert [f.name for f in msg.fields] == ["x", "y", "z"]
        points = np.frombuffer(bytes(msg.data), dtype=np.float32).reshape(-1, 3)
        mount = load_scanner()
        body = _rotation(_quat(odom.orientation))
        origin = np.array([odom.position.x, odom.position.y, odom.position.z])
        world = origin + (mount.position + points @ rpy_matrix(mount.rpy).T) @ body.T
        on_wall = world[world[:, 2] > 0.03]
        assert len(on_wall) >= 20, world
        assert np.abs(on_wall[:, 0] - WALL_X).max() < 0.02, on_wall
        assert abs(np.median(on_wall[:, 0]) - WALL_X) < 0.005
    finally:
        rec.console.close()
        procs.stop()


def test_a_bad_world_file_is_refused_in_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "broken.xml"
    bad.write_text("<mujoco><worldbody><geom name='seabed' type='plane'")
    result = subprocess.run([*node_command("seabed_sim"), "--ros-args", "-p",
                             f"world:={bad}"], capture_output=True, text=True, timeout=60,
                            env=isolated_env(random.randint(102, 200)))
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and "error" in lines[0], result.stderr
