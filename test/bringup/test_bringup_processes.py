"""``crawler-motion sim`` and ``up`` as a user runs them: every process up and ready, Ctrl-C
or SIGTERM ends them all with exit 0, a killed node ends the run with exit 1 naming it while
the robot holds, bad options start nothing."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mujoco")

from crawler_motion.bringup.lineup import BACKGROUND_NICE
from crawler_motion.testing.bus import BusSpec
from crawler_motion.testing.stack import isolated_env, manager_process

CLI = [str(Path(sys.executable).parent / "crawler-motion")]
#: Time a bring-up gets to be ready on a loaded CI machine [s] (the target on an idle
#: machine is 15 s; docs/running.md has the measured figure).
READY_LIMIT = 60.0


class Run:
    """A ``crawler-motion sim|up`` subprocess with its output collected line by line."""

    def __init__(self, args: list[str], env: dict[str, str]) -> None:
        self.proc = subprocess.Popen([*CLI, *args], stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, env=env)
        self.lines: list[str] = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:  # type: ignore[union-attr]
            self.lines.append(line.rstrip("\n"))

    def read(self) -> None:
        """Lines arrive from the reader thread."""

    def wait_for(self, word: str, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.read()
            if any(word in line for line in self.lines):
                return True
            if self.proc.poll() is not None:
                self.read()
                return any(word in line for line in self.lines)
            time.sleep(0.1)
        return False

    def pids(self) -> dict[str, int]:
        """Ready processes by name, from the 'ready: NAME (pid N)' lines."""
        out = {}
        for line in self.lines:
            if ": ready: " in line:
                name, rest = line.split(": ready: ")[1].split(" (pid ")
                out[name] = int(rest.split(")")[0])
        return out

    def finish(self, timeout: float) -> int:
        code = self.proc.wait(timeout)
        self.reader.join(5.0)
        return code

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    @property
    def text(self) -> str:
        return "\n".join(self.lines)


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}").exists() and "Z" not in Path(
        f"/proc/{pid}/stat").read_text().split(")")[1][:3]


def niceness(pid: int) -> int:
    """The niceness of ``pid`` (field 19 of ``/proc/PID/stat``)."""
    return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[16])


def test_sim_comes_up_without_error_and_ctrl_c_ends_every_process(tmp_path: Path,
                                                                  ros_domain: int) -> None:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

    node = rclpy.create_node("bringup_diagnostics")
    errors: list[str] = []

    def on_diagnostics(msg: DiagnosticArray) -> None:
        errors.extend(f"{s.name}: {s.message}" for s in msg.status
                      if s.level == DiagnosticStatus.ERROR)

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 50)
    recording = tmp_path / "run.mcap"
    run = Run(["sim", "--logs", str(tmp_path / "logs"), "--split", "--record", str(recording)],
              isolated_env(ros_domain))
    names = ["seabed_sim", "driver_node", "planner_node", "terrain_mapper", "navigator",
             "recorder"]
    try:
        assert run.wait_for("up: 6 processes", READY_LIMIT), run.text
        pids = run.pids()
        assert set(pids) == set(names) and run.lines[0].startswith(
            "crawler-motion sim: ready: seabed_sim"), run.text
        assert all(alive(pid) for pid in pids.values())
        mine = os.nice(0)  # the motion loop at the bring-up's niceness, the rest nicer
        assert {n: niceness(p) - mine for n, p in pids.items()} == {
            "seabed_sim": 0, "driver_node": 0, "planner_node": 0,
            "terrain_mapper": BACKGROUND_NICE, "navigator": BACKGROUND_NICE,
            "recorder": BACKGROUND_NICE}
        stand = subprocess.run([*CLI, "console", "--timeout", "30", "stand"],
                               env=isolated_env(ros_domain), capture_output=True, text=True,
                               timeout=90)
        assert stand.returncode == 0, stand.stdout + stand.stderr
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
        assert not errors, errors  # a nominal start-up: no ERROR on /diagnostics
        began = time.monotonic()
        run.proc.send_signal(signal.SIGINT)
        assert run.finish(20.0) == 0, run.text
        assert time.monotonic() - began < 10.0  # 1 s on an idle machine (docs/running.md)
        assert "stopped: every process ended" in run.text and "killed" not in run.text
        assert not [name for name, pid in pids.items() if alive(pid)]
        assert recording.stat().st_size > 0
    finally:
        run.kill()
        node.destroy_node()


def test_a_killed_node_holds_the_robot_and_names_the_node(tmp_path: Path,
                                                          ros_domain: int) -> None:
    run = Run(["sim", "--logs", str(tmp_path)], isolated_env(ros_domain))
    try:
        assert run.wait_for("up: 4 processes", READY_LIMIT), run.text
        pids = run.pids()
        env = isolated_env(ros_domain)
        stand = subprocess.run([*CLI, "console", "--timeout", "30", "stand"], env=env,
                               capture_output=True, text=True, timeout=90)
        assert stand.returncode == 0, stand.stdout + stand.stderr
        goto = subprocess.Popen([*CLI, "console", "--timeout", "60", "goto", "2.0", "0.0"],
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True)
        try:
            time.sleep(4.0)  # walking
            os.kill(pids["navigator"], signal.SIGKILL)
            assert run.finish(40.0) == 1, run.text
        finally:
            goto.kill()
            goto.wait()
        assert "error: navigator (pid" in run.text and "exited with status -9" in run.text
        assert "robot held: STANDING" in run.text, run.text
        assert not [name for name, pid in pids.items() if alive(pid)]
    finally:
        run.kill()


def test_up_brings_the_controller_up_on_the_robot_bus_and_sigterm_stops_it(
        tmp_path: Path, ros_domain: int) -> None:
    bus = BusSpec.fresh()
    manager = manager_process([*bus.cli_args()])
    run = Run(["up", "--logs", str(tmp_path), "--interface", bus.interface, "--channel",
               bus.channel, "--port", str(bus.port)], isolated_env(ros_domain))
    try:
        assert run.wait_for("up: 3 processes", READY_LIMIT), run.text
        assert "seabed_sim" not in run.text
        pids = run.pids()
        run.proc.send_signal(signal.SIGTERM)
        assert run.finish(20.0) == 0, run.text
        assert not [name for name, pid in pids.items() if alive(pid)]
    finally:
        run.kill()
        manager.send_signal(signal.SIGINT)
        manager.wait(10)


@pytest.mark.parametrize("args, words", [
    (["sim", "--world", "nope"], "unknown world 'nope'"),
    (["sim", "--namespace", "9lives"], "not a valid ROS namespace"),
    (["sim", "--params", "missing.yaml"], "params file missing.yaml: cannot read"),
    (["up", "--interface", "socketcan", "--channel", "can9"], "CAN bus socketcan can9"),
])
def test_bad_options_are_one_line_and_start_nothing(tmp_path: Path, args: list[str],
                                                    words: str) -> None:
    done = subprocess.run([*CLI, *args, "--logs", str(tmp_path / "logs")], capture_output=True,
                          text=True, timeout=60, cwd=tmp_path)
    assert done.returncode == 1 and words in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not done.stdout
    assert not (tmp_path / "logs").exists()  # nothing started
