"""Operator input of the planner, parsed and validated (pure: no rclpy).

- `parse_gait_command`: one JSON object from the ``gait_command`` topic -> a `Command`;
- `twist_to_params`: a ``cmd_vel`` twist -> `WalkParams` (stride vector and turn per step);
- `validate_joint_state`: a measured ``joint_states`` message -> joint angles ``(n_legs, 3)``;
- `validate_parameters`: the planner node's ROS parameters -> `PlannerSettings` (the one
  validator used at start-up and on every parameter change).

Everything that is wrong raises `CommandError` (never anything else) with a message that says
what was wrong and what would be right.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from crawler_motion.errors import CommandError, ConfigError, GaitError
from crawler_motion.model.config import Config
from crawler_motion.motion.gait import WalkParams, validate_params

#: Longest accepted ``gait_command`` text, in UTF-8 bytes.
MAX_COMMAND_BYTES = 4096
#: Largest ``steps`` of a finite walk.
MAX_STEPS = 10_000
#: The commands and the keys each one accepts (besides ``command``).
WALK_KEYS: tuple[str, ...] = ("steps", "gait", "profile", "stride", "heading", "turn", "lift",
                              "arc", "swing_time", "stance_time")
COMMAND_KEYS: dict[str, tuple[str, ...]] = {
    "stand": ("body_height",),
    "walk": WALK_KEYS,
    "stop": (),
    "sit": (),
    "estop": (),
    "reset": (),
}
#: Twists slower than this (m/s, rad/s) count as zero: "stop" for a cmd_vel walk.
ZERO_SPEED = 1e-4
ZERO_YAW_RATE = 1e-4
#: Range of the ``rate`` [Hz] and ``cmd_vel_timeout`` [s] parameters.
RATE_RANGE = (1.0, 1000.0)
CMD_VEL_TIMEOUT_RANGE = (0.05, 10.0)


@dataclass(frozen=True)
class Command:
    """One validated operator command.

    ``kind`` is one of `COMMAND_KEYS`. For ``stand``, ``body_height`` [m] (None: the default).
    For ``walk``, ``steps`` (None: until stopped) and ``overrides``: the walk parameters the
    command sets, as ``(name, value)`` pairs; the others come from the planner's current
    parameters (see `apply`).
    """

    kind: str
    body_height: float | None = None
    steps: int | None = None
    overrides: tuple[tuple[str, Any], ...] = ()

    def apply(self, base: WalkParams, cfg: Config) -> WalkParams:
        """``base`` with this command's overrides, validated (``stance_time`` resolved).

        A ``stance_time`` in ``base`` that the command does not set is recomputed from the
        new swing time and gait (``None``), unless the command sets it.
        """
        fields = dict(self.overrides)
        if "stance_time" not in fields and ({"swing_time", "gait"} & fields.keys()):
            fields["stance_time"] = None
        try:
            return validate_params(replace(base, **fields), cfg)
        except GaitError as exc:
            raise CommandError(f"walk refused: {exc}") from exc


def _reject_constant(name: str) -> float:
    raise CommandError(f"{name} is not a number JSON allows; send a finite number")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise CommandError(f"key '{key}' appears twice; send each key once")
        out[key] = value
    return out


def as_float(value: Any) -> float | None:
    """``value`` as a float if it is a real number (int, float, numpy scalar; not bool), an
    int beyond the float range as +-inf; None for anything else (str, None, ...)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        return None
    try:
        return float(value)
    except OverflowError:  # an int of more than ~308 digits
        return math.inf if value > 0 else -math.inf


def finite_float(value: Any) -> float | None:
    """``value`` as a finite float if it is a Python int or float (not bool) that is one; else
    None (NaN, inf, an int beyond the float range, anything else)."""
    if not isinstance(value, (int, float)):
        return None
    number = as_float(value)
    return number if number is not None and math.isfinite(number) else None


def _number(value: Any, name: str, lo: float, hi: float, unit: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CommandError(f"'{name}' must be a number in [{lo:g}, {hi:g}] {unit}, "
                           f"got {json.dumps(value)[:40]}")
    number = finite_float(value)
    if number is None:
        raise CommandError(f"'{name}' = {str(value)[:40]} {unit} is outside [{lo:g}, {hi:g}] "
                           f"{unit}")
    if not lo <= number <= hi:
        raise CommandError(f"'{name}' = {number:g} {unit} is outside [{lo:g}, {hi:g}] {unit}")
    return number


def _choice(value: Any, name: str, choices: Sequence[str]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise CommandError(f"'{name}' must be one of {sorted(choices)}, "
                           f"got {json.dumps(value)[:40]}")
    return value


def field_ranges(cfg: Config) -> dict[str, tuple[float, float, str]]:
    """Allowed range ``(lo, hi, unit)`` of every numeric walk field, from the config."""
    g = cfg.gait
    most = 10.0 * (max(len(t) for t in g.gaits.values()) - 1) * g.swing_time_range[1]
    return {
        "stride": (0.0, g.max_stride, "m"),
        "heading": (-math.pi, math.pi, "rad"),
        "turn": (-g.max_turn, g.max_turn, "rad"),
        "lift": (1e-3, g.max_clearance, "m"),
        "arc": (0.0, g.max_clearance, "m"),
        "swing_time": (*g.swing_time_range, "s"),
        "stance_time": (g.swing_time_range[0], most, "s"),
        "body_height": (*cfg.robot.body_height_range, "m"),
    }


def parse_gait_command(text: str, cfg: Config) -> Command:
    """Parse one ``gait_command`` JSON object into a `Command`; raise `CommandError` if bad.

    Checks every key and value on its own (types, finiteness, config ranges) and the pairs
    the command sets together (lift + arc, stance vs swing time); the complete parameter set
    is checked again with `gait.validate_params` when the command is applied (`Command.apply`).
    """
    example = '{"command": "walk", "steps": 4}'
    if not isinstance(text, str):
        raise CommandError(f"a gait command is JSON text, got {type(text).__name__}")
    if len(text) > MAX_COMMAND_BYTES or len(
            text.encode("utf-8", "surrogatepass")) > MAX_COMMAND_BYTES:
        raise CommandError(f"gait command too long ({len(text)} characters); the limit is "
                           f"{MAX_COMMAND_BYTES} bytes")
    try:
        data = json.loads(text, parse_constant=_reject_constant,
                          object_pairs_hook=_no_duplicates)
    except CommandError:
        raise
    except (ValueError, RecursionError) as exc:  # JSONDecodeError is a ValueError
        raise CommandError(f"gait command is not valid JSON ({exc}); send one object such as "
                           f"{example}") from None
    if not isinstance(data, dict):
        raise CommandError(f"gait command must be a JSON object such as {example}, "
                           f"got {type(data).__name__}")
    kind = data.get("command")
    if not isinstance(kind, str) or kind not in COMMAND_KEYS:
        shown = "missing" if "command" not in data else json.dumps(kind)[:40]
        raise CommandError(f"'command' must be one of {list(COMMAND_KEYS)}, got {shown}")
    allowed = COMMAND_KEYS[kind]
    unknown = sorted(str(k) for k in data if k != "command" and k not in allowed)
    if unknown:
        accepted = ", ".join(allowed) if allowed else "no other keys"
        raise CommandError(f"'{kind}' does not take {unknown}; it accepts {accepted}")
    ranges = field_ranges(cfg)
    if kind == "stand":
        height = data.get("body_height")
        if height is not None or "body_height" in data:
            height = _number(height, "body_height", *ranges["body_height"])
        return Command(kind="stand", body_height=height)
    if kind != "walk":
        return Command(kind=kind)
    steps = None
    if "steps" in data:
        steps = data["steps"]
        if isinstance(steps, bool) or not isinstance(steps, int) or not 1 <= steps <= MAX_STEPS:
            raise CommandError(f"'steps' must be an integer in [1, {MAX_STEPS}] (or absent: "
                               f"walk until stopped), got {json.dumps(steps)[:40]}")
    overrides: dict[str, Any] = {}
    for key in WALK_KEYS[1:]:
        if key not in data:
            continue
        if key == "gait":
            overrides[key] = _choice(data[key], key, list(cfg.gait.gaits))
        elif key == "profile":
            overrides[key] = _choice(data[key], key, list(cfg.gait.profiles))
        else:
            overrides[key] = _number(data[key], key, *ranges[key])
    if "lift" in overrides and "arc" in overrides and (
            overrides["lift"] + overrides["arc"] > cfg.gait.max_clearance + 1e-12):
        raise CommandError(f"lift + arc = {overrides['lift'] + overrides['arc']:g} m exceeds "
                           f"the maximum clearance {cfg.gait.max_clearance:g} m")
    if "swing_time" in overrides and "stance_time" in overrides:
        gait = overrides.get("gait", cfg.gait.gait)
        n = len(cfg.gait.gaits[gait])
        lo = (n - 1) * overrides["swing_time"]
        if not lo - 1e-12 <= overrides["stance_time"] <= 10 * lo:
            raise CommandError(f"stance_time = {overrides['stance_time']:g} s: the {gait} gait "
                               f"({n} groups) needs stance_time in [{lo:g}, {10 * lo:g}] s "
                               f"(>= {n - 1} x swing_time)")
    return Command(kind="walk", steps=steps, overrides=tuple(overrides.items()))


def twist_limits(cfg: Config, base: WalkParams) -> tuple[float, float]:
    """Largest body speed [m/s] and yaw rate [rad/s] a walk with ``base`` timing can do."""
    try:
        p = validate_params(base, cfg)
    except GaitError as exc:
        raise CommandError(f"cannot walk from cmd_vel: {exc}") from exc
    stance = float(p.stance_time)  # type: ignore[arg-type]
    return cfg.gait.max_stride / stance, cfg.gait.max_turn / (p.swing_time + stance)


def twist_to_params(vx: float, vy: float, wz: float, cfg: Config, base: WalkParams
                    ) -> WalkParams:
    """Walk parameters realising body velocity ``(vx, vy)`` [m/s] and yaw rate ``wz`` [rad/s].

    The gait, profile, heights and timing come from ``base``. Per slot the body moves
    ``b x stride`` with ``b = slot / stance``, so the speed is ``stride / stance_time``; the yaw
    per step (one gait cycle of ``n_groups`` slots) is ``wz x n_groups x slot_time``. A twist
    beyond the configured limits is refused, not clipped. The result is validated.
    """
    values = []
    for name, value in (("linear.x", vx), ("linear.y", vy), ("angular.z", wz)):
        number = finite_float(value)
        if number is None:
            raise CommandError(f"cmd_vel {name} must be a finite number, got {value!r:.40}")
        values.append(number)
    vx, vy, wz = values
    try:
        p = validate_params(base, cfg)
    except GaitError as exc:
        raise CommandError(f"cannot walk from cmd_vel: {exc}") from exc
    stance = float(p.stance_time)  # type: ignore[arg-type]
    n = len(cfg.gait.gaits[p.gait])
    slot = (p.swing_time + stance) / n
    v_max, w_max = twist_limits(cfg, p)
    speed = math.hypot(vx, vy)
    if speed > v_max * (1 + 1e-9):
        raise CommandError(f"cmd_vel speed {speed:.4g} m/s exceeds the maximum {v_max:.4g} m/s "
                           f"(max_stride {cfg.gait.max_stride:g} m per stance of {stance:g} s)")
    if abs(wz) > w_max * (1 + 1e-9):
        raise CommandError(f"cmd_vel yaw rate {wz:.4g} rad/s exceeds the maximum "
                           f"{w_max:.4g} rad/s (max_turn {cfg.gait.max_turn:g} rad per step "
                           f"of {n * slot:g} s)")
    stride = min(speed * stance, cfg.gait.max_stride)
    turn = max(-cfg.gait.max_turn, min(cfg.gait.max_turn, wz * n * slot))
    heading = math.atan2(vy, vx) if speed > 0.0 else p.heading
    try:
        return validate_params(replace(p, stride=stride, heading=heading, turn=turn), cfg)
    except GaitError as exc:  # pragma: no cover - the limits above are validate_params' ranges
        raise CommandError(f"cmd_vel refused: {exc}") from exc


def is_zero_twist(vx: float, vy: float, wz: float) -> bool:
    """True for a twist that means "stand still" (see `ZERO_SPEED`, `ZERO_YAW_RATE`)."""
    return math.hypot(vx, vy) < ZERO_SPEED and abs(wz) < ZERO_YAW_RATE


def validate_joint_state(names: Sequence[str], positions: Sequence[float],
                         velocities: Sequence[float], expected_names: Sequence[str]
                         ) -> np.ndarray:
    """Measured joint angles ``(len(expected_names) // 3, 3)`` [rad] in ``expected_names`` order.

    ``names`` and ``positions`` must have the same length, ``velocities`` that length or none;
    every expected joint exactly once, no others; every value finite.
    """
    names = list(names)
    if not all(isinstance(name, str) for name in names):
        raise CommandError("joint_states names must be strings")
    try:
        pos = np.asarray(positions, dtype=float).reshape(-1)
        vel = np.asarray(velocities, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise CommandError(f"joint_states position/velocity must be numbers ({exc})") from None
    if len(pos) != len(names):
        raise CommandError(f"joint_states has {len(names)} names but {len(pos)} positions; "
                           f"send one position per name")
    if len(vel) not in (0, len(names)):
        raise CommandError(f"joint_states has {len(names)} names but {len(vel)} velocities; "
                           f"send one velocity per name or none")
    seen: set[str] = set()
    duplicate: set[str] = set()
    for name in names:
        (duplicate if name in seen else seen).add(name)
    if duplicate:
        raise CommandError(f"joint_states names {sorted(duplicate)} appear more than once; "
                           f"send each joint once")
    expected = list(expected_names)
    missing = [name for name in expected if name not in seen]
    extra = sorted(seen - set(expected))
    if missing or extra:
        raise CommandError(f"joint_states must name exactly the joints {expected}; "
                           f"missing {missing}, unknown {extra}")
    if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
        bad = [n for n, p in zip(names, pos, strict=True) if not math.isfinite(p)]
        raise CommandError(f"joint_states contains NaN or inf (positions of {bad[:3]} or "
                           f"velocities); send finite values")
    index = {name: i for i, name in enumerate(names)}
    return pos[[index[name] for name in expected]].reshape(-1, 3)


@dataclass(frozen=True)
class PlannerSettings:
    """The validated ROS parameters of the planner node."""

    config_file: str
    rate: float  # [Hz]
    cmd_vel_timeout: float  # [s]
    fault_hardware_id: str
    defaults: WalkParams  # gait defaults; body_height resolved


#: The node's parameters besides the config-dependent gait defaults.
GAIT_PARAMETERS: tuple[str, ...] = ("gait", "profile", "stride", "lift", "arc", "swing_time",
                                    "body_height")


def parameter_ranges(cfg: Config) -> dict[str, tuple[float, float]]:
    """Numeric range of every numeric node parameter (for descriptors and `validate_parameters`).
    """
    ranges = field_ranges(cfg)
    out = {"rate": RATE_RANGE, "cmd_vel_timeout": CMD_VEL_TIMEOUT_RANGE}
    for name in ("stride", "lift", "arc", "swing_time", "body_height"):
        out[name] = ranges[name][:2]
    return out


def default_parameters(cfg: Config, config_file: str) -> dict[str, Any]:
    """Default values of the node's parameters (gait defaults from the config)."""
    g = cfg.gait
    return {"config_file": config_file, "rate": 100.0, "cmd_vel_timeout": 0.5,
            "fault_hardware_id": "motor_manager", "gait": g.gait, "profile": g.profile,
            "stride": g.stride, "lift": g.lift, "arc": g.arc, "swing_time": g.swing_time,
            "body_height": cfg.robot.body_height}


def validate_parameters(values: Mapping[str, Any], cfg: Config) -> PlannerSettings:
    """Validate a complete set of planner node parameters; raise `CommandError` with the reason.

    The one validator of the node: used at start-up and for every parameter change (with the
    current values updated by the change).
    """
    expected = set(default_parameters(cfg, ""))
    missing = sorted(expected - set(values))
    unknown = sorted(set(values) - expected)
    if missing or unknown:
        raise CommandError(f"planner parameters: missing {missing}, unknown {unknown}")
    ranges = parameter_ranges(cfg)
    units = {name: unit for name, (_, _, unit) in field_ranges(cfg).items()}
    units |= {"rate": "Hz", "cmd_vel_timeout": "s"}
    nums = {name: _number(values[name], name, lo, hi, units[name])
            for name, (lo, hi) in ranges.items()}
    config_file = values["config_file"]
    if not isinstance(config_file, str) or not config_file:
        raise CommandError("config_file must be the path of a robot.yaml")
    fault_id = values["fault_hardware_id"]
    if not isinstance(fault_id, str) or not fault_id.strip():
        raise CommandError("fault_hardware_id must be a non-empty string (the hardware_id of "
                           "the motor manager's diagnostics)")
    gait = _choice(values["gait"], "gait", list(cfg.gait.gaits))
    profile = _choice(values["profile"], "profile", list(cfg.gait.profiles))
    params = WalkParams(gait=gait, profile=profile, stride=nums["stride"], lift=nums["lift"],
                        arc=nums["arc"], swing_time=nums["swing_time"],
                        body_height=nums["body_height"])
    try:
        params = validate_params(params, cfg)
        cfg.robot.standing_feet(params.body_height)
    except (GaitError, ConfigError) as exc:
        raise CommandError(f"gait defaults refused: {exc}") from exc
    return PlannerSettings(config_file=config_file, rate=nums["rate"],
                           cmd_vel_timeout=nums["cmd_vel_timeout"],
                           fault_hardware_id=fault_id, defaults=params)
