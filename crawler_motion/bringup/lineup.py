"""What a bring-up starts, in which order, with which arguments (no ROS needed to build it).

A `Lineup` is the ordered list of `Member` processes of ``crawler-motion sim`` (the seabed
simulator first: it is the motors' side of the bus) or ``crawler-motion up`` (no simulator:
the driver opens the configured CAN bus). Every node gets the same parameter file (``--params-
file``, sections per node name as in ``config/params.yaml``) and the same namespace; what the
bring-up sets itself (the bus of the simulator, the world, the medium, the driver's autostart)
follows the file as ``-p`` overrides, which ROS applies after the file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from crawler_motion.errors import ConfigError
from crawler_motion.testing.bus import BusSpec
from crawler_motion.testing.stack import STACK_COMMAND_TIMEOUT, node_command, ros_args

#: Medium choices of the simulator.
MEDIA = ("water", "land")
#: Time the simulator gets after its node is up before the driver opens the bus [s]: its
#: physics and heartbeats start after the node appears (a driver started at once saw gaps).
SIM_SETTLE = 2.0
#: Heartbeat periods the driver waits for the simulator's heartbeat (the real manager: the
#: driver's default, 3). The simulated manager is a Python thread of ``seabed_sim``: when a
#: participant joins the graph, a DDS publish of the node can hold the interpreter, and the
#: heartbeat with it, for 0.25-0.45 s (measured, docs/running.md); 5 periods (0.5 s) keep that
#: from pausing the robot. The driver's own stalls never count (it judges the time it listened).
SIM_HEARTBEAT_TIMEOUT_PERIODS = 5
#: Niceness of the members that do not close the motion loop (mapper, navigator, recorder,
#: view): on a busy computer the simulator and the controller get the CPU first, so a burst
#: of mapping or a start-up never delays a heartbeat or a tick.
BACKGROUND_NICE = 5
#: Default Foxglove WebSocket port of ``--view``.
VIEW_PORT = 8765


@dataclass(frozen=True)
class Member:
    """One process: its short ``name``, the ROS node names it must show on the graph before it
    counts as ready (relative to the namespace), its command line, its start ``stage`` (the
    members of a stage start together once every member of the stages before is ready) and
    its niceness (0: the motion loop; `BACKGROUND_NICE`: the rest)."""

    name: str
    nodes: tuple[str, ...]
    command: tuple[str, ...]
    stage: int = 1
    settle: float = 0.0  # [s] waited after it is ready before the next stage starts
    nice: int = 0


@dataclass(frozen=True)
class BringUpOptions:
    """The options of ``sim`` (``simulate`` True) and ``up``."""

    simulate: bool = True
    world: str = "flat"
    medium: str = "water"
    params: Path | None = None
    namespace: str = ""
    split: bool = False
    record: Path | None = None
    view: bool = False
    view_port: int = VIEW_PORT
    bus: BusSpec = field(default_factory=BusSpec)
    extra: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)  # node -> params


def check_namespace(namespace: str) -> str:
    """``namespace`` as an absolute ROS namespace ('' for none); `ConfigError` when it is not a
    valid ROS name (letters, digits and underscores in ``/``-separated tokens, none starting
    with a digit)."""
    if namespace in ("", "/"):
        return ""
    full = namespace if namespace.startswith("/") else f"/{namespace}"
    tokens = full[1:].split("/")
    if any(not t or t[0].isdigit() or not t.replace("_", "a").isalnum() or not t.isascii()
           or "__" in t for t in tokens):
        raise ConfigError(f"namespace {namespace!r} is not a valid ROS namespace: use "
                          "'/'-separated tokens of letters, digits and single underscores, "
                          "none starting with a digit (e.g. /crawler1)")
    return full


def check_params_file(path: Path) -> dict[str, Any]:
    """The parsed parameter file; `ConfigError` naming the file when it cannot be read or is
    not a ROS parameter file (a mapping of node sections with ``ros__parameters``)."""
    try:
        tree = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"params file {path}: cannot read it ({exc.strerror})") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"params file {path}: not valid YAML ({exc})") from exc
    if not isinstance(tree, dict) or not all(
            isinstance(v, dict) and "ros__parameters" in v for v in tree.values()):
        raise ConfigError(f"params file {path}: not a ROS parameter file (a mapping of node "
                          "sections, each with ros__parameters, as config/params.yaml)")
    return tree


def _args(params: Mapping[str, Any], options: BringUpOptions) -> list[str]:
    """``--ros-args`` of a node: the namespace, the file, then ``params``."""
    remaps = (f"__ns:={options.namespace}",) if options.namespace else ()
    args = ros_args({}, remaps)
    if options.params is not None:
        args += ["--params-file", str(options.params)]
    for name, value in params.items():
        args += ros_args({name: value})[1:]
    return args


def lineup(options: BringUpOptions) -> list[Member]:
    """The processes in start order."""
    bus = options.bus.ros_params() if options.simulate else {}
    extra = options.extra
    out: list[Member] = []
    if options.simulate:
        sim = {**bus, "world": options.world, "medium": options.medium,
               **extra.get("seabed_sim", {})}
        out.append(Member("seabed_sim", ("seabed_sim",),
                          (*node_command("seabed_sim"), *_args(sim, options)), stage=0,
                          settle=SIM_SETTLE))
    driver = {**bus, "autostart": True, **extra.get("driver", {})}
    if options.simulate:  # a shared desktop starves processes now and then (see the demo)
        driver.setdefault("command_timeout", STACK_COMMAND_TIMEOUT)
        driver.setdefault("heartbeat_timeout_periods", SIM_HEARTBEAT_TIMEOUT_PERIODS)
    planner = dict(extra.get("planner", {}))
    if options.split:
        out.append(Member("driver_node", ("driver",),
                          (*node_command("driver_node"), *_args(driver, options))))
        out.append(Member("planner_node", ("planner",),
                          (*node_command("planner_node"), *_args(planner, options))))
    else:
        out.append(Member("controller_node", ("planner", "driver"), (
            *node_command("controller_node"), *_args({**driver, **planner}, options))))
    for name in ("terrain_mapper", "navigator"):
        out.append(_background(name, (name,), (*node_command(name),
                                               *_args(extra.get(name, {}), options))))
    if options.record is not None:
        out.append(_background("recorder", ("recorder",), (
            *node_command("recorder"), "-o", str(options.record), "--quiet",
            *_args({}, options))))
    if options.view:
        out.append(_background("view", ("foxglove_view",), (
            *node_command("crawler-motion"), "view", "--port", str(options.view_port),
            *_args({}, options))))
    return out


def _background(name: str, nodes: tuple[str, ...], command: tuple[str, ...]) -> Member:
    """A member outside the motion loop: started once the controller is ready (its start-up
    does not compete with the controller's), at `BACKGROUND_NICE`."""
    return Member(name, nodes, command, stage=2, nice=BACKGROUND_NICE)


def describe(members: Sequence[Member]) -> str:
    """The lineup in one line: ``a -> b -> c``."""
    return " -> ".join(m.name for m in members)
