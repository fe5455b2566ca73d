"""The planner node's ROS parameters as `ParamSpec`s, and the settings they validate to (pure).

The gait defaults among them are the walk options with a ``parameter`` description, with the
ranges and choices of the loaded config (`walk_options`). `planner_settings` is the one check
of a complete set of values, used at start-up and on every parameter change.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from crawler_motion.errors import CommandError, ConfigError, GaitError
from crawler_motion.model.config import Config
from crawler_motion.motion.attitude import AttitudeMode, AttitudeSettings
from crawler_motion.motion.contact_estimation import ContactSettings
from crawler_motion.motion.foothold import FootholdSettings
from crawler_motion.motion.gait import WalkParams, validate_params
from crawler_motion.motion.stumble import StumbleSettings
from crawler_motion.motion.walk_options import WALK_OPTIONS, OptionType, WalkOption
from crawler_motion.motion.walk_params import follow_gait
from crawler_motion.runtime.parameters import ParamSpec, validate_parameters

#: Name of the read-only parameter naming the robot.yaml (declared before the others).
CONFIG_FILE = "config_file"
#: Name of the read-only parameter naming the leg calibration file (declared second).
CALIBRATION_FILE = "calibration_file"
#: The ``calibration_file`` parameter: the planner's per-leg geometry.
CALIBRATION_SPEC = ParamSpec(CALIBRATION_FILE, "", "leg calibration YAML (per-leg geometry, "
                             "crawler-motion calibrate identify); empty: robot.yaml's "
                             "robot.calibration_file, else the nominal legs", read_only=True)
#: Range of the ``tick_priority`` parameter (0: normal scheduling; else SCHED_FIFO).
TICK_PRIORITY_RANGE = (0, 99)


@dataclass(frozen=True)
class PlannerSettings:
    """The validated ROS parameters of the planner node."""

    config_file: str
    rate: float  # [Hz]
    cmd_vel_timeout: float  # [s]
    fault_hardware_id: str
    tick_priority: int  # 0 or a SCHED_FIFO priority
    defaults: WalkParams  # gait defaults; body_height resolved
    contacts: ContactSettings = field(default_factory=ContactSettings)  # foot contacts
    foothold: FootholdSettings = field(default_factory=FootholdSettings)  # touch-down
    stumble: StumbleSettings = field(default_factory=StumbleSettings)  # swing hits
    attitude: AttitudeSettings = field(default_factory=AttitudeSettings)  # body attitude


def _config_file_check(value: str) -> str | None:
    return "must be the path of a robot.yaml" if not value else None


def _hardware_id_check(value: str) -> str | None:
    return ("must be a non-empty string (the hardware_id of the motor manager's diagnostics)"
            if not value.strip() else None)


def config_file_spec(default: str) -> ParamSpec:
    """The ``config_file`` parameter, with the shipped robot.yaml ``default``."""
    return ParamSpec(CONFIG_FILE, default, "robot.yaml (geometry, limits, gait ranges)",
                     read_only=True, check=_config_file_check)


#: The parameters that do not depend on the robot config.
NODE_PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("rate", 100.0, "joint_commands rate [Hz]; a change applies from the next tick",
              minimum=1.0, maximum=1000.0, unit="Hz"),
    ParamSpec("cmd_vel_timeout", 0.5, "a cmd_vel walk stops into standing after this long "
              "without a twist [s]", minimum=0.05, maximum=10.0, unit="s"),
    ParamSpec("fault_hardware_id", "motor_manager", "hardware_id of the motor manager in "
              "/diagnostics (ERROR pauses)", check=_hardware_id_check),
    ParamSpec("tick_priority", 0, "0: normal scheduling; 1-99: SCHED_FIFO priority of the tick "
              "thread, the rest of the process one below (needs CAP_SYS_NICE)", read_only=True,
              minimum=TICK_PRIORITY_RANGE[0], maximum=TICK_PRIORITY_RANGE[1]),
    ParamSpec("contact_threshold", ContactSettings.threshold, "foot contact (touch-down) when "
              "the foot force estimated from the efforts reaches this [N] (docs/contact.md)",
              minimum=0.01, maximum=100.0, unit="N"),
    ParamSpec("contact_hysteresis", ContactSettings.hysteresis, "lift-off when the force "
              "drops below contact_threshold minus this [N]; at most contact_threshold",
              minimum=0.0, maximum=100.0, unit="N"),
    ParamSpec("contact_drive_inertia", ContactSettings.drive_inertia, "reflected rotor inertia "
              "of each joint drive, removed from the efforts before the foot force [kg m²]",
              minimum=0.0, maximum=1.0, unit="kg m²"),
    ParamSpec("contact_period", ContactSettings.period, "feedback period of the motor manager "
              "(the DBC's position cycle time) [s]: joint-state times are whole multiples of "
              "it", minimum=0.001, maximum=0.1, unit="s"),
    ParamSpec("foothold_adapt", FootholdSettings.enabled, "terrain-adaptive touch-down: stop "
              "a lowering foot at early contact, search below the planned ground without one "
              "(docs/contact.md); needs efforts that carry the ground load (seabed_sim, the "
              "robot), not motor_manager_sim's; false: the blind plan"),
    ParamSpec("foothold_tolerance", FootholdSettings.tolerance, "a contact counts as early "
              "while the foot is more than this above its planned ground [m]", minimum=0.0,
              maximum=0.05, unit="m"),
    ParamSpec("foothold_stop_time", FootholdSettings.stop_time, "duration of the smooth stop "
              "of a foot at early contact [s]", minimum=0.005, maximum=1.0, unit="s"),
    ParamSpec("foothold_search_depth", FootholdSettings.search_depth, "how far below its "
              "planned ground a foot without contact searches before the walk holds [m]",
              minimum=0.0, maximum=0.1, unit="m"),
    ParamSpec("foothold_search_speed", FootholdSettings.search_speed, "peak speed of the "
              "search below the planned ground [m/s]", minimum=0.001, maximum=1.0,
              unit="m/s"),
    ParamSpec("foothold_touch_force", FootholdSettings.touch_force, "normal force an early "
              "contact needs in 2 estimates in a row [N] (a swinging leg's own dynamics reach "
              "contact_threshold)", minimum=0.0, maximum=100.0, unit="N"),
    ParamSpec("stumble_retry", StumbleSettings.enabled, "with foothold_adapt: a swinging foot "
              "that hits an obstacle before lowering is lifted higher and retried once, a "
              "second hit holds the walk (docs/seabed.md, rough seabed)"),
    ParamSpec("stumble_force", StumbleSettings.force, "horizontal ground force on a swinging "
              "foot that makes a hit, in 2 contact estimates in a row [N] (a swing's own "
              "dynamics reach about 7 N)", minimum=0.0, maximum=100.0, unit="N"),
    ParamSpec("stumble_lift", StumbleSettings.lift, "a retried swing passes this much above "
              "the rest of its planned swing [m]", minimum=0.0, maximum=0.05, unit="m"),
    ParamSpec("stumble_retreat", StumbleSettings.retreat, "a retried foot first backs off this "
              "far along its swing [m]", minimum=0.0, maximum=0.03, unit="m"),
    ParamSpec("stumble_lift_time", StumbleSettings.lift_time, "longest duration of a retry's "
              "rise and of its lowering [s]", minimum=0.05, maximum=1.0, unit="s"),
    ParamSpec("stumble_stop_time", StumbleSettings.stop_time, "duration of a hit foot's smooth "
              "stop before the retry [s]", minimum=0.005, maximum=0.5, unit="s"),
    ParamSpec("attitude_mode", AttitudeSettings.mode.value, "with foothold_adapt: the body's "
              "roll, pitch and height during a walk: stance_plane (follow the plane of the "
              "footholds), imu (level it from an IMU's attitude), off (the plan's)",
              choices=tuple(m.value for m in AttitudeMode)),
    ParamSpec("attitude_max_tilt", AttitudeSettings.max_tilt, "largest |roll| and |pitch| the "
              "attitude commands [rad]", minimum=0.0, maximum=0.5, unit="rad"),
    ParamSpec("attitude_max_lift", AttitudeSettings.max_lift, "largest body lift or lowering "
              "the attitude commands [m]", minimum=0.0, maximum=0.05, unit="m"),
)


def _walk_spec(option: WalkOption, cfg: Config) -> ParamSpec:
    assert option.parameter is not None and option.default is not None
    description = option.described(option.parameter)
    if option.type is OptionType.CHOICE:
        return ParamSpec(option.name, str(option.default(cfg)), description,
                         choices=tuple(sorted(option.allowed(cfg))))
    lo, hi = option.range(cfg)
    return ParamSpec(option.name, float(option.default(cfg)), description, minimum=lo,
                     maximum=hi, unit=option.unit)


def planner_parameters(cfg: Config, config_file: str) -> tuple[ParamSpec, ...]:
    """Every parameter of the planner node, ``config_file`` and ``calibration_file`` first,
    for the loaded ``cfg``."""
    walk = tuple(_walk_spec(option, cfg) for option in WALK_OPTIONS if option.parameter)
    return (config_file_spec(config_file), CALIBRATION_SPEC, *NODE_PARAMETERS, *walk)


def default_values(specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """The default value of every parameter, by name."""
    return {spec.name: spec.default for spec in specs}


def planner_settings(specs: Sequence[ParamSpec], values: Mapping[str, Any], cfg: Config
                     ) -> PlannerSettings:
    """Validate a complete set of planner parameter ``values``; raise `CommandError` if bad.

    Each value is checked against its spec (`runtime.parameters.validate_parameters`), then
    the gait defaults together (`gait.validate_params`, the standing pose of the height).
    """
    missing = sorted(spec.name for spec in specs if spec.name not in values)
    reasons = [f"missing {missing}: every planner parameter needs a value"] if missing else []
    reasons += validate_parameters(specs, values)
    if reasons:
        raise CommandError("; ".join(reasons))
    fields = {option.name: float(values[option.name]) if option.type is OptionType.NUMBER
              else values[option.name] for option in WALK_OPTIONS if option.parameter}
    # a gait parameter other than the config's: its table's own swing time, stride and stance
    # profile where those parameters keep the default gait's (the walk command's rule)
    fields = follow_gait(fields, cfg.gait.gait, str(fields["gait"]), cfg)
    try:
        params = validate_params(WalkParams(**fields), cfg)
        cfg.robot.standing_feet(params.body_height)
    except (GaitError, ConfigError) as exc:
        raise CommandError(f"gait defaults refused: {exc}") from exc
    try:
        contacts = ContactSettings(float(values["contact_threshold"]),
                                   float(values["contact_hysteresis"]),
                                   float(values["contact_drive_inertia"]),
                                   float(values["contact_period"]))
        foothold = FootholdSettings(bool(values["foothold_adapt"]),
                                    float(values["foothold_tolerance"]),
                                    float(values["foothold_stop_time"]),
                                    float(values["foothold_search_depth"]),
                                    float(values["foothold_search_speed"]),
                                    float(values["foothold_touch_force"]))
        stumble = StumbleSettings(bool(values["stumble_retry"]), float(values["stumble_force"]),
                                  float(values["stumble_lift"]),
                                  float(values["stumble_retreat"]),
                                  float(values["stumble_lift_time"]),
                                  float(values["stumble_stop_time"]))
        attitude = AttitudeSettings(AttitudeMode(values["attitude_mode"]),
                                    float(values["attitude_max_tilt"]),
                                    float(values["attitude_max_lift"]))
    except ConfigError as exc:
        raise CommandError(str(exc)) from exc
    return PlannerSettings(config_file=values[CONFIG_FILE], rate=float(values["rate"]),
                           cmd_vel_timeout=float(values["cmd_vel_timeout"]),
                           fault_hardware_id=values["fault_hardware_id"],
                           tick_priority=values["tick_priority"], defaults=params,
                           contacts=contacts, foothold=foothold, stumble=stumble,
                           attitude=attitude)
