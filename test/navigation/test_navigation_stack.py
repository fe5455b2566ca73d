"""Smoke test of the real stack: seabed_sim, driver, planner, terrain_mapper and navigator as
processes; the console stands the robot up and `goto` walks it to a goal 0.3 m ahead."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from nav_msgs.msg import OccupancyGrid  # noqa: E402

from crawler_motion.testing.bus import BusSpec  # noqa: E402
from crawler_motion.testing.stack import (  # noqa: E402
    StackProcesses,
    StackSpec,
    isolated_env,
    ros_args,
)
from crawler_motion.tools.console import Console  # noqa: E402
from crawler_motion.tools.goto import GoalConsole  # noqa: E402


def script(name: str) -> list[str]:
    import sys

    return [str(Path(sys.executable).parent / name)]


def test_goto_walks_the_simulated_robot_to_the_goal(tmp_path: Path, ros_domain: int) -> None:
    spec = StackSpec(BusSpec.fresh(), rate=100.0, seabed={"world": "flat"})
    commands = {**spec.commands(),
                "mapper": [*script("terrain_mapper"), *ros_args({})],
                "navigator": [*script("navigator"), *ros_args({"goal_tolerance": 0.05})]}
    procs = StackProcesses(tmp_path)
    procs.start(commands, isolated_env(ros_domain))
    console, goals = Console("nav_smoke_console"), GoalConsole("nav_smoke_goals")
    console.printer = goals.printer = lambda _line: None
    maps: list[OccupancyGrid] = []
    goals.node.create_subscription(OccupancyGrid, "terrain_map", maps.append, 2)
    try:
        assert console.connect(30.0), procs.log_tails(30)
        for _ in range(30):  # the driver configures itself after start
            ok, message = console.run_when_ready({"command": "stand"}, 30.0)
            if ok or "driver inactive" not in message:
                break
            console.spin_for(1.0)
        assert ok, f"{message}\n{procs.log_tails(30)}"
        ok, message = goals.goto(0.3, 0.0, "odom", 60.0)
        assert ok, f"{message}\n{procs.log_tails(30)}"
        status = goals.status
        assert status["state"] == "ARRIVED" and status["distance"] <= 0.05
        assert maps, "no terrain_map received"
        data = np.asarray(maps[-1].data)
        assert (data == 0).sum() > 100 and not (data == 100).any()  # flat: free, no obstacle
        ok, message = goals.goto(0.5, 0.0, "map", 10.0)  # wrong frame: refused
        assert not ok and "frame" in message
        # arrived: the walk's stop half steps end standing
        assert console.wait_until(
            lambda: (console.status or {}).get("state") == "STANDING", 15.0), console.status
        ok, message = goals.goto(1.0, 0.0, "odom", 1.5)  # walks off; times out, cancels
        assert not ok and "goal cancelled" in message
        assert goals.spin_until(lambda: (goals.status or {}).get("state") == "IDLE", 5.0)
        assert (goals.status or {}).get("reason") == "cancelled"
        assert console.wait_until(  # the navigator's zero twist stops the walk into standing
            lambda: (console.status or {}).get("state") == "STANDING", 15.0), console.status
        cli = subprocess.run([*script("crawler-motion"), "console", "--timeout", "10", "cancel"],
                             env=isolated_env(ros_domain), capture_output=True, text=True,
                             timeout=60)
        assert cli.returncode == 0 and "done: cancelled" in cli.stdout, cli.stderr
    finally:
        goals.close()
        console.close()
        procs.stop()
