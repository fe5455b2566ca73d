"""The parameters of ``seabed_sim`` and the simulator they build (no ROS)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.errors import ConfigError
from crawler_motion.runtime.bus_parameters import BUS_PARAMETERS
from crawler_motion.runtime.parameters import ParamSpec, not_empty, validate_parameters
from crawler_motion.sim.motor_manager import DEFAULT_COMMAND_TIMEOUT
from crawler_motion.sim.seabed.model import SeabedModel, SimSettings
from crawler_motion.sim.seabed.plant import PlantSettings, SeabedPlant
from crawler_motion.sim.seabed.scanner import RangeScanner, ScannerSettings
from crawler_motion.sim.seabed.water import Medium, WaterSettings
from crawler_motion.sim.seabed.world import DEFAULT_WORLD


def _vector3(limit: float, unit: str) -> Any:
    """A `Check`: three numbers, each within ±``limit`` [``unit``]."""
    def check(value: Sequence[float]) -> str | None:
        if len(value) != 3:
            return f"must be 3 numbers, got {list(value)!r}"
        if any(abs(v) > limit for v in value):
            return f"must have every value within [-{limit:g}, {limit:g}] {unit}, got " \
                   f"{list(value)!r}"
        return None
    return check


SEABED_PARAMETERS: tuple[ParamSpec, ...] = (
    *BUS_PARAMETERS,
    ParamSpec("config_file", "", "robot.yaml (geometry, limits, scanner mount; default: the "
              "shipped one)", read_only=True),
    ParamSpec("calibration_file", "", "leg calibration YAML of the simulated (\"true\") robot, "
              "which may differ from the planner's; empty: robot.yaml's "
              "robot.calibration_file, else the nominal legs", read_only=True),
    ParamSpec("world", DEFAULT_WORLD.removesuffix(".xml"), "world MJCF file: a path or a "
              "shipped name (flat, relief, rocks, step, wall, u_trap)", read_only=True,
              check=not_empty),
    ParamSpec("medium", Medium.WATER.value, "what surrounds the robot",
              read_only=True, choices=tuple(m.value for m in Medium)),
    ParamSpec("start_pose", (0.0, 0.0, 0.0), "start pose in the world: x [m], y [m], yaw [rad]",
              read_only=True, check=_vector3(100.0, "m / rad")),
    ParamSpec("timestep", 0.0005, "physics time step [s]", read_only=True, minimum=1e-5,
              maximum=0.0025, unit="s"),
    ParamSpec("net_weight_fraction", 0.3, "weight in water / dry weight (water only)",
              read_only=True, minimum=0.001, maximum=1.0),
    ParamSpec("current", (0.0, 0.0, 0.0), "uniform water current in the world [m/s] (water "
              "only)", read_only=True, check=_vector3(5.0, "m/s")),
    ParamSpec("command_timeout", DEFAULT_COMMAND_TIMEOUT, "the manager holds after this long "
              "without target frames [s]", read_only=True, minimum=0.01, maximum=10.0,
              unit="s"),
    ParamSpec("imu_noise", 0.002, "IMU angular velocity noise, standard deviation [rad/s]",
              read_only=True, minimum=0.0, maximum=1.0, unit="rad/s"),
    ParamSpec("imu_accel_noise", 0.02, "IMU linear acceleration noise, standard deviation "
              "[m/s²]", read_only=True, minimum=0.0, maximum=10.0, unit="m/s²"),
    ParamSpec("range_noise", 0.005, "scan range noise, standard deviation [m]", read_only=True,
              minimum=0.0, maximum=1.0, unit="m"),
    ParamSpec("max_range", 3.0, "scan range limit (turbidity) [m]", read_only=True,
              minimum=0.01, maximum=100.0, unit="m"),
    ParamSpec("dropout", 0.0, "probability that a scan ray returns nothing", read_only=True,
              minimum=0.0, maximum=1.0),
    ParamSpec("record", "", "pictures of the run, rendered on shutdown: a path prefix P "
              "(P.png, P.gif) or a directory (seabed_walk.png, seabed_walk.gif in it); empty: "
              "none", read_only=True),
    ParamSpec("record_fps", 10.0, "states kept per second of the run for the pictures [Hz] "
              "(the GIF has at most 10 frames/s and 150 frames)", read_only=True,
              minimum=0.5, maximum=30.0, unit="Hz"),
)


@dataclass
class Simulator:
    """What the parameters build: model, plant, protocol and the manager's settings."""

    model: SeabedModel
    plant: SeabedPlant
    protocol: MotorProtocol
    command_timeout: float  # [s]
    record: str = ""  # picture target (`record_paths`); empty: none
    record_fps: float = 10.0  # [Hz]


def check_values(values: Mapping[str, Any]) -> None:
    """Raise `ConfigError` with every reason when a value is out of range."""
    reasons = validate_parameters(SEABED_PARAMETERS, values)
    if reasons:
        raise ConfigError(f"invalid seabed_sim parameters: {'; '.join(reasons)}")


def build_simulator(values: Mapping[str, Any],
                    clock: Callable[[], float] | None = None) -> Simulator:
    """The simulator of checked parameter values (name -> value), its plant stamping states
    with ``clock`` [s] (`SeabedPlant`); `ConfigError` naming the file and the problem when
    the configuration or the world is bad."""
    from crawler_motion.model.calibration_file import config_with_calibration
    from crawler_motion.model.config import load_config, load_scanner

    check_values(values)
    config_file = values.get("config_file") or None
    cfg = config_with_calibration(load_config(config_file),
                                  values.get("calibration_file") or None)
    water = WaterSettings(medium=values["medium"],
                          net_weight_fraction=float(values["net_weight_fraction"]),
                          current=tuple(float(v) for v in values["current"]))
    settings = SimSettings(timestep=float(values["timestep"]), water=water,
                           start_pose=tuple(float(v) for v in values["start_pose"]))
    sm = SeabedModel(cfg.robot, settings, values["world"])
    mount = load_scanner(config_file)
    scanner = RangeScanner(sm, mount, ScannerSettings(
        range_noise=float(values["range_noise"]), dropout=float(values["dropout"]),
        max_range=float(values["max_range"])))
    protocol = MotorProtocol.from_config(cfg.robot)
    record, fps = str(values["record"]), float(values["record_fps"])
    plant = SeabedPlant(sm, protocol, scanner, PlantSettings(
        gyro_noise=float(values["imu_noise"]), accel_noise=float(values["imu_accel_noise"]),
        scan_period=1.0 / mount.rate, snapshot_period=1.0 / fps if record else 0.0), clock)
    return Simulator(sm, plant, protocol, float(values["command_timeout"]), record, fps)
