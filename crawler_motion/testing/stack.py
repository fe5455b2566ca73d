"""The three-process stack (simulated manager, driver, planner) launched as logged subprocesses."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from crawler_motion.testing.bus import BusSpec

#: Console scripts of the stack and the modules behind them.
EXECUTABLES = {"motor_manager_sim": "crawler_motion.sim.manager_cli",
               "driver_node": "crawler_motion.driver.node",
               "planner_node": "crawler_motion.planner.node",
               "controller_node": "crawler_motion.controller.node",
               "seabed_sim": "crawler_motion.sim.seabed.node",
               "terrain_mapper": "crawler_motion.mapping.node",
               "navigator": "crawler_motion.navigation.node",
               "recorder": "crawler_motion.recording.recorder",
               "crawler-motion": "crawler_motion.tools.cli"}
#: Short process names (log files ``<name>.log``) of the benches and tests.
SHORT_NAMES = {"motor_manager_sim": "sim", "driver_node": "driver", "planner_node": "planner",
               "seabed_sim": "seabed", "controller_node": "controller"}
#: Driver watchdog of the demo and benches [s]. The driver's default (0.2 s) is meant for a
#: dedicated controller; on a shared laptop or CI machine a starved planner process can miss it,
#: and a tripped watchdog (correctly) needs an explicit re-enable, which would end the run.
STACK_COMMAND_TIMEOUT = 1.0
#: ROS domains drawn for isolated stacks (``ROS_DOMAIN_ID``; 1..101 fit every RMW's port map).
DOMAINS = (1, 101)


def node_command(name: str) -> list[str]:
    """The installed console script ``name`` next to this interpreter, else ``python -m``."""
    script = Path(sys.executable).parent / name
    return [str(script)] if script.exists() else [sys.executable, "-m", EXECUTABLES[name]]


def ros_value(value: Any) -> str:
    """A parameter value as ``--ros-args -p name:=value`` reads it back with the same type."""
    return ("true" if value else "false") if isinstance(value, bool) else str(value)


def ros_args(params: Mapping[str, Any], remaps: Sequence[str] = ()) -> list[str]:
    """``--ros-args`` with ``-r`` ``remaps`` and ``-p name:=value`` ``params``."""
    args = ["--ros-args"]
    for remap in remaps:
        args += ["-r", remap]
    for name, value in params.items():
        args += ["-p", f"{name}:={ros_value(value)}"]
    return args


def random_domain() -> int:
    """A random ROS domain id in `DOMAINS`."""
    return random.randint(*DOMAINS)


def isolated_env(domain: int | None = None) -> dict[str, str]:
    """This process's environment on ROS domain ``domain`` (kept when None) with discovery
    limited to this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``)."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    if domain is not None:
        env["ROS_DOMAIN_ID"] = str(domain)
    return env


@dataclass
class StackSpec:
    """What to launch: the manager (unless ``sim`` is False: it runs elsewhere), the driver
    (activated, watchdog ``command_timeout`` [s]) and the planner (``rate`` [Hz]; none when
    ``planner`` is None) on ``bus``; ``driver`` / ``planner`` hold extra parameters, ``remaps``
    ROS remappings of both nodes, ``names`` the process names by executable. With ``seabed``
    (its parameters) the manager is ``seabed_sim``, the physical one, instead. With
    ``controller`` the planner and the driver run composed in one ``controller_node``
    process, which takes both parameter sets."""

    bus: BusSpec
    rate: float = 100.0
    command_timeout: float = STACK_COMMAND_TIMEOUT
    speed_limit: float = 6.0
    driver: dict[str, Any] = field(default_factory=dict)
    planner: dict[str, Any] | None = field(default_factory=dict)
    sim: bool = True
    remaps: tuple[str, ...] = ()
    names: Mapping[str, str] = field(default_factory=lambda: dict(SHORT_NAMES))
    seabed: dict[str, Any] | None = None
    controller: bool = False

    def commands(self) -> dict[str, list[str]]:
        """Process name -> command line, in start order."""
        out = {}
        if self.sim and self.seabed is not None:
            out[self.names["seabed_sim"]] = [*node_command("seabed_sim"), *ros_args(
                {**self.bus.ros_params(), **self.seabed}, self.remaps)]
        elif self.sim:  # its --ros-args (its options would do as well: `BusSpec.cli_args`)
            out[self.names["motor_manager_sim"]] = [*node_command("motor_manager_sim"), *ros_args(
                {**self.bus.ros_params(), "speed_limit": float(self.speed_limit)}, self.remaps)]
        driver = {"autostart": True, "command_timeout": float(self.command_timeout),
                  **self.bus.ros_params(), **self.driver}
        planner = None if self.planner is None else {"rate": float(self.rate), **self.planner}
        if self.controller:  # the planner composed with the driver: both parameter sets
            out[self.names["controller_node"]] = [*node_command("controller_node"), *ros_args(
                {**driver, **(planner or {})}, self.remaps)]
            return out
        out[self.names["driver_node"]] = [*node_command("driver_node"),
                                          *ros_args(driver, self.remaps)]
        if planner is not None:
            out[self.names["planner_node"]] = [*node_command("planner_node"),
                                               *ros_args(planner, self.remaps)]
        return out


class StackProcesses:
    """Processes started from command lines, each logging to ``logs/<name>.log``; stops them
    with SIGINT (SIGKILL after a timeout)."""

    def __init__(self, logs: Path) -> None:
        self.logs = Path(logs)
        self.procs: dict[str, subprocess.Popen[bytes]] = {}

    def start(self, commands: Mapping[str, Sequence[str]], env: Mapping[str, str]) -> None:
        """Start every command with its output in its log file."""
        for name, cmd in commands.items():
            with open(self.log_path(name), "wb") as log:
                self.procs[name] = subprocess.Popen(list(cmd), stdout=log,
                                                    stderr=subprocess.STDOUT, env=dict(env))

    def log_path(self, name: str) -> Path:
        """The log file of process ``name``."""
        return self.logs / f"{name}.log"

    def pids(self) -> dict[str, int]:
        """Process ids by name."""
        return {name: proc.pid for name, proc in self.procs.items()}

    def died(self) -> str:
        """' (<name> exited <code>, ...; logs in <dir>)' for processes that ended, else ''."""
        dead = [f"{n} exited {p.returncode}" for n, p in self.procs.items()
                if p.poll() is not None]
        return f" ({', '.join(dead)}; logs in {self.logs})" if dead else ""

    def tail(self, name: str, lines: int) -> list[str]:
        """The last ``lines`` lines of the log of ``name`` (none when it has no log)."""
        path = self.log_path(name)
        return path.read_text(errors="replace").splitlines()[-lines:] if path.exists() else []

    def log_tails(self, lines: int = 5, header: str = "--- {name} ---") -> str:
        """The last lines of every log, each under ``header`` (fields ``name``, ``path``)."""
        return "\n".join(header.format(name=name, path=self.log_path(name)) + "\n"
                         + "\n".join(self.tail(name, lines)) for name in self.procs)

    def kill(self, name: str) -> None:
        """SIGKILL process ``name`` and reap it."""
        self.procs[name].send_signal(signal.SIGKILL)
        self.procs[name].wait(5)

    def stop(self, names: Sequence[str] | None = None, timeout: float = 5.0) -> None:
        """SIGINT the processes ``names`` (default all) still running, then wait for each
        (SIGKILL after ``timeout`` [s])."""
        procs = [self.procs[n] for n in (self.procs if names is None else names)]
        for proc in procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in procs:
            try:
                proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def manager_process(options: Sequence[str]) -> subprocess.Popen[str]:
    """The simulated manager alone as a subprocess (``python -m``, this package first on the
    module path) with ``options``; its stdout and stderr piped as text."""
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(root), *filter(None, [os.environ.get("PYTHONPATH")])]))
    return subprocess.Popen(
        [sys.executable, "-m", EXECUTABLES["motor_manager_sim"], *options],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
