"""The parameters of ``motor_manager_sim`` (``--ros-args``), each one of its options (no ROS).

The simulated manager is no ROS node, but it takes ``--ros-args -p name:=value`` and
``--params-file`` like the nodes (read by `runtime.ros_args`), so one parameter file configures a
whole stack; its bus parameters are the driver's (``can_interface``, ``can_channel``,
``can_port``). Each parameter stands for one command-line option (`OPTIONS`), and `manager_flags`
turns parameters into those options, so the options stay the one way the program is configured.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from crawler_motion.errors import ConfigError
from crawler_motion.runtime.bus_parameters import BUS_PARAMETERS
from crawler_motion.runtime.parameters import ParamSpec, validate_parameters
from crawler_motion.runtime.ros_args import RosArgs
from crawler_motion.sim.motor_manager import DEFAULT_COMMAND_TIMEOUT, DEFAULT_SPEED_LIMIT

#: The node name its parameter-file sections and node-specific parameters use.
NODE_NAME = "motor_manager_sim"

MANAGER_PARAMETERS: tuple[ParamSpec, ...] = (
    *BUS_PARAMETERS,
    ParamSpec("rate", 0.0, "feedback rate [Hz]; 0: the DBC's cycle time (100 Hz)",
              read_only=True, minimum=0.0, maximum=10_000.0, unit="Hz"),
    ParamSpec("speed_limit", DEFAULT_SPEED_LIMIT, "axis speed limit [rad/s]", read_only=True,
              minimum=0.001, maximum=1000.0, unit="rad/s"),
    ParamSpec("command_timeout", DEFAULT_COMMAND_TIMEOUT, "the manager holds after this long "
              "without target frames [s]", read_only=True, minimum=0.001, maximum=3600.0,
              unit="s"),
    ParamSpec("heartbeat_period", 0.0, "heartbeat period [s]; 0: the DBC's cycle time (0.1 s)",
              read_only=True, minimum=0.0, maximum=60.0, unit="s"),
    ParamSpec("initial_pose", "mid", "joint angles at power-up: mid (the middle of every "
              "joint's limits) or zero", read_only=True, choices=("mid", "zero")),
    ParamSpec("effort", True, "send effort frames (false: a manager without them)",
              read_only=True),
    ParamSpec("dbc_file", "", "DBC file ('': the shipped config/motor_manager.dbc)",
              read_only=True),
    ParamSpec("axes_file", "", "joint-to-axis map YAML ('': the shipped config/axes.yaml)",
              read_only=True),
    ParamSpec("config_file", "", "robot.yaml ('': the shipped config/robot.yaml)",
              read_only=True),
)
#: The command-line option of each parameter.
OPTIONS = {"can_interface": "--interface", "can_channel": "--channel", "can_port": "--port",
           "rate": "--rate", "speed_limit": "--speed-limit",
           "command_timeout": "--command-timeout", "heartbeat_period": "--heartbeat-period",
           "initial_pose": "--initial-pose", "effort": "--no-effort", "dbc_file": "--dbc",
           "axes_file": "--axes", "config_file": "--config"}
#: Parameters whose zero or empty value means "the option's own default".
UNSET_WHEN_EMPTY = frozenset({"can_port", "rate", "heartbeat_period", "dbc_file", "axes_file",
                              "config_file"})


def manager_flags(ros: RosArgs) -> list[str]:
    """The options that say what the ``--ros-args`` parameters say; `ConfigError` for a bad
    value or an unknown name given with ``-p`` (a parameter file's other nodes' names are
    left to them)."""
    known = {spec.name for spec in MANAGER_PARAMETERS}
    unknown = sorted(ros.explicit - known)
    if unknown:
        raise ConfigError(f"unknown parameters {unknown}; {NODE_NAME} takes {sorted(known)}")
    values: Mapping[str, Any] = {k: v for k, v in ros.parameters.items() if k in known}
    reasons = validate_parameters(MANAGER_PARAMETERS, values)
    if reasons:
        raise ConfigError("; ".join(reasons))
    flags: list[str] = []
    for name, value in values.items():
        if name == "effort":
            flags += [] if value else [OPTIONS[name]]
        elif not (name in UNSET_WHEN_EMPTY and value in (0, "")):
            flags += [OPTIONS[name], str(value)]
    return flags
