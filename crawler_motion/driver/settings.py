"""The driver's parameter table and its run-time settings (no ROS)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from enum import Enum
from typing import Any

from crawler_motion.runtime.bus_parameters import BUS_PARAMETERS
from crawler_motion.runtime.parameters import ParamSpec, not_empty, validate_parameters


class OnDeactivate(str, Enum):
    """Manager command sent on deactivation."""

    DISABLE = "disable"
    HOLD = "hold"


class OnTimeout(str, Enum):
    """Manager command sent when the command watchdog trips."""

    HOLD = "hold"
    DISABLE = "disable"


PARAMETERS: tuple[ParamSpec, ...] = (
    *BUS_PARAMETERS,
    ParamSpec("bitrate", 1_000_000, "CAN bitrate [bit/s] for interfaces that set it",
              read_only=True, minimum=10_000, maximum=1_000_000, unit="bit/s"),
    ParamSpec("dbc_file", "", "DBC file of the motor-manager protocol (default: the shipped "
              "config/motor_manager.dbc)", read_only=True, check=not_empty),
    ParamSpec("axes_file", "", "joint-to-axis map YAML (default: the shipped config/axes.yaml)",
              read_only=True, check=not_empty),
    ParamSpec("config_file", "", "robot.yaml with joint names and limits (default: the shipped "
              "config/robot.yaml)", read_only=True, check=not_empty),
    ParamSpec("autostart", False, "configure and activate right after start-up",
              read_only=True),
    ParamSpec("priority", 0, "0: normal scheduling; 1-99: SCHED_FIFO priority of the driver "
              "process, as real-time drivers run (needs CAP_SYS_NICE)", read_only=True,
              minimum=0, maximum=99),
    ParamSpec("on_deactivate", "hold", "manager command sent on deactivation: hold (axes "
              "powered, holding) or disable (axes unpowered)",
              choices=tuple(c.value for c in OnDeactivate)),
    ParamSpec("command_timeout", 0.2, "command watchdog [s]: no joint_commands for this long "
              "sends on_timeout and blocks motion until ~/enable", minimum=0.02, maximum=10.0,
              unit="s"),
    ParamSpec("on_timeout", "hold", "manager command sent when the watchdog trips: hold or "
              "disable", choices=tuple(c.value for c in OnTimeout)),
    ParamSpec("step_speed_limit", 10.0, "joint speed bounding every command's step from the "
              "last sent target (after enable: from the measured pose); a command stepping "
              "further than this x the time since the last one + step_margin is refused",
              minimum=0.01, maximum=100.0, unit="rad/s"),
    ParamSpec("step_margin", 0.05, "allowance added to the step bound (jitter of the command "
              "arrival, lag of the measurement)", minimum=0.0, maximum=1.0, unit="rad"),
    ParamSpec("heartbeat_timeout_periods", 3, "heartbeat periods without a heartbeat before "
              "the manager is reported lost (ERROR)", minimum=1, maximum=100),
    ParamSpec("heartbeat_startup_grace", 5.0, "time after the bus opens within which the "
              "manager's first heartbeat is awaited (WARN 'waiting') before it is reported "
              "missing (ERROR); a later loss uses heartbeat_timeout_periods", minimum=0.0,
              maximum=60.0, unit="s"),
    ParamSpec("diagnostics_period", 1.0, "period of /diagnostics [s]", minimum=0.05,
              maximum=60.0, unit="s"),
    ParamSpec("send_retries", 2, "immediate retries of a frame the bus refused (bounded; no "
              "waiting)", minimum=0, maximum=10),
    ParamSpec("reopen_period", 0.2, "period of reopen attempts while the bus is down [s]",
              minimum=0.01, maximum=1.0, unit="s"),
)
PARAMETER_SPECS: dict[str, ParamSpec] = {p.name: p for p in PARAMETERS}
#: File parameters whose empty default means "the shipped file" (see `default_files`).
FILE_PARAMETERS = {"dbc_file": "motor_manager.dbc", "axes_file": "axes.yaml",
                   "config_file": "robot.yaml"}


def default_files() -> dict[str, str]:
    """The shipped configuration files, as the defaults of the file parameters."""
    from crawler_motion.model.config import config_path

    return {name: str(config_path(file)) for name, file in FILE_PARAMETERS.items()}


@dataclass(frozen=True)
class DriverSettings:
    """The run-time settings of `DriverCore` (the changeable driver parameters)."""

    command_timeout: float = 0.2  # [s]
    on_timeout: str = OnTimeout.HOLD.value
    on_deactivate: str = OnDeactivate.HOLD.value
    heartbeat_timeout_periods: int = 3
    heartbeat_startup_grace: float = 5.0  # [s]
    step_speed_limit: float = 10.0  # [rad/s]
    step_margin: float = 0.05  # [rad]
    send_retries: int = 2
    reopen_period: float = 0.2  # [s]

    def __post_init__(self) -> None:
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        reasons = validate_parameters(PARAMETERS, values)
        if reasons:
            raise ValueError("; ".join(reasons))

    @classmethod
    def from_parameters(cls, values: Mapping[str, Any]) -> DriverSettings:
        """Settings from a parameter mapping (other keys are ignored)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in values.items() if k in names})
