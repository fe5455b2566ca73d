"""Operator input of the planner, parsed and validated (pure: no rclpy).

- `parse_gait_command`: one JSON object from the ``gait_command`` topic -> a `Command`;
- `twist_to_params`: a ``cmd_vel`` twist -> `WalkParams` (stride vector and turn per step).

The keys, ranges and choices of the walk options are those of `walk_options`. Everything that
is wrong raises `CommandError` (never anything else) with a message that says what was wrong
and what would be right.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from crawler_motion.errors import CommandError, GaitError
from crawler_motion.model.config import Config
from crawler_motion.model.joint_state import finite_float
from crawler_motion.motion.body_pose import BodyPose
from crawler_motion.motion.gait import WalkParams, validate_params
from crawler_motion.motion.walk_options import (
    MAX_STEPS,
    OPTIONS,
    OptionType,
    WalkOption,
    clearance_error,
    field_ranges,
    options_of,
    stance_time_error,
)
from crawler_motion.motion.walk_params import follow_gait, gait_defaults
from crawler_motion.planner.state import PlannerState

#: Longest accepted ``gait_command`` text, in UTF-8 bytes.
MAX_COMMAND_BYTES = 4096
#: The keys a walk command accepts (besides ``command``).
WALK_KEYS: tuple[str, ...] = tuple(option.name for option in options_of("walk"))
#: The commands and the keys each one accepts (besides ``command``).
COMMAND_KEYS: dict[str, tuple[str, ...]] = {
    kind: tuple(option.name for option in options_of(kind))
    for kind in ("stand", "walk", "pose", "stop", "sit", "estop", "reset")
}
#: Twists slower than this (m/s, rad/s) count as zero: "stop" for a cmd_vel walk.
ZERO_SPEED = 1e-4
ZERO_YAW_RATE = 1e-4
#: Relative allowance of the twist limits (rounding only).
TWIST_LIMIT_TOLERANCE = 1e-9
#: A command shown in the messages about malformed JSON.
_EXAMPLE = '{"command": "walk", "steps": 4}'

__all__ = ["COMMAND_KEYS", "MAX_COMMAND_BYTES", "MAX_STEPS", "NOT_UP_STATES", "STAND_FIRST",
           "TWIST_BEYOND_LIMITS", "TWIST_IGNORED", "WALK_KEYS", "Command", "field_ranges",
           "is_zero_twist", "needs_stand", "parse_gait_command", "twist_limits",
           "twist_to_params"]


@dataclass(frozen=True)
class Command:
    """One validated operator command.

    ``kind`` is one of `COMMAND_KEYS`. For ``stand``, ``body_height`` [m] (None: the default).
    For ``walk``, ``steps`` (None: until stopped) and ``overrides``: the walk parameters the
    command sets, as ``(name, value)`` pairs; the others come from the planner's current
    parameters (see `apply`). For ``pose``, ``pose``: the body pose (keys left out are 0).
    """

    kind: str
    body_height: float | None = None
    steps: int | None = None
    overrides: tuple[tuple[str, Any], ...] = ()
    pose: BodyPose | None = None

    def apply(self, base: WalkParams, cfg: Config) -> WalkParams:
        """``base`` with this command's overrides, validated (``stance_time`` resolved).

        A ``stance_time`` in ``base`` that the command does not set is recomputed from the
        new swing time and gait (``None``), unless the command sets it; a new gait without a
        ``swing_time`` takes its own default swing time if ``base`` has the old gait's
        (`GaitConfig.swing_time_of`; a chosen one is kept), and its own stance profile and
        stride likewise (`GaitConfig.stance_profile_of`, `GaitConfig.stride_of`).
        """
        fields = dict(self.overrides)
        gait = str(fields.get("gait", base.gait))
        kept = {name: getattr(base, name) for name in gait_defaults(cfg, gait)}
        own = follow_gait(kept, base.gait, gait, cfg, set(fields))
        fields = {**{k: v for k, v in own.items() if v != kept[k]}, **fields}
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


def _option_value(option: WalkOption, value: Any, cfg: Config) -> Any:
    """``value`` of one walk option checked on its own (type, finiteness, config range)."""
    if option.type is OptionType.CHOICE:
        return _choice(value, option.name, list(option.allowed(cfg)))
    if option.type is OptionType.COUNT:
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_STEPS:
            raise CommandError(f"'{option.name}' must be an integer in [1, {MAX_STEPS}] (or "
                               f"absent: walk until stopped), got {json.dumps(value)[:40]}")
        return value
    return _number(value, option.name, *option.range(cfg), option.unit)


def _load_object(text: str) -> dict[str, Any]:
    """The JSON object of one gait command (length, syntax, duplicate keys checked)."""
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
                           f"{_EXAMPLE}") from None
    if not isinstance(data, dict):
        raise CommandError(f"gait command must be a JSON object such as {_EXAMPLE}, "
                           f"got {type(data).__name__}")
    return data


def _command_kind(data: dict[str, Any]) -> str:
    """The ``command`` of ``data``, after checking that it takes every other key present."""
    kind = data.get("command")
    if not isinstance(kind, str) or kind not in COMMAND_KEYS:
        shown = "missing" if "command" not in data else json.dumps(kind)[:40]
        raise CommandError(f"'command' must be one of {list(COMMAND_KEYS)}, got {shown}")
    allowed = COMMAND_KEYS[kind]
    unknown = sorted(str(k) for k in data if k != "command" and k not in allowed)
    if unknown:
        accepted = ", ".join(allowed) if allowed else "no other keys"
        raise CommandError(f"'{kind}' does not take {unknown}; it accepts {accepted}")
    return kind


def _check_pairs(overrides: dict[str, Any], cfg: Config) -> None:
    """The rules tying two options together, for the pairs a walk command sets both of."""
    if "lift" in overrides and "arc" in overrides:
        problem = clearance_error(cfg, overrides["lift"], overrides["arc"])
        if problem is not None:
            raise CommandError(problem)
    if "swing_time" in overrides and "stance_time" in overrides:
        problem = stance_time_error(cfg, overrides.get("gait", cfg.gait.gait),
                                    overrides["swing_time"], overrides["stance_time"])
        if problem is not None:
            raise CommandError(problem)


def parse_gait_command(text: str, cfg: Config) -> Command:
    """Parse one ``gait_command`` JSON object into a `Command`; raise `CommandError` if bad.

    Checks every key and value on its own (types, finiteness, config ranges) and the pairs
    the command sets together (lift + arc, stance vs swing time); the complete parameter set
    is checked again with `gait.validate_params` when the command is applied (`Command.apply`);
    a pose, against the standing height and the feet's workspace when the planner moves to it.
    """
    data = _load_object(text)
    kind = _command_kind(data)
    values = {key: _option_value(OPTIONS[key], data[key], cfg)
              for key in COMMAND_KEYS[kind] if key in data}
    if kind == "stand":
        return Command(kind="stand", body_height=values.get("body_height"))
    if kind == "pose":
        return Command(kind="pose", pose=BodyPose(**values))
    if kind != "walk":
        return Command(kind=kind)
    steps = values.pop("steps", None)
    _check_pairs(values, cfg)
    return Command(kind="walk", steps=steps, overrides=tuple(values.items()))


#: How the refusals of a twist beyond what the walk can do begin (speed, yaw rate, parameters):
#: the same twist is refused again, so a navigator sending it fails its goal with the reason.
TWIST_BEYOND_LIMITS = ("cmd_vel speed", "cmd_vel yaw rate", "cannot walk from cmd_vel")
#: How a refused twist's text begins, and how it ends when the robot must stand first.
TWIST_IGNORED = "cmd_vel ignored"
STAND_FIRST = "send stand first"
#: States in which only ``stand`` gets the robot walking again (HOLDING says so only when no
#: resume from the measured pose is due); a twist is refused again at every twist.
NOT_UP_STATES = (PlannerState.IDLE, PlannerState.SITTING, PlannerState.HOLDING,
                 PlannerState.ESTOP)


def needs_stand(refusal: str) -> bool:
    """Whether ``refusal`` refuses every twist until ``stand`` is sent: the robot is not up
    (`NOT_UP_STATES`) or its body is posed."""
    if not (refusal.startswith(TWIST_IGNORED) and refusal.endswith(STAND_FIRST)):
        return False
    rest = refusal[len(TWIST_IGNORED):]
    return rest.startswith(": the body is posed") or any(
        rest.startswith(f" in state {state}:") for state in NOT_UP_STATES)


def _resolved(base: WalkParams, cfg: Config) -> WalkParams:
    try:
        return validate_params(base, cfg)
    except GaitError as exc:
        raise CommandError(f"{TWIST_BEYOND_LIMITS[2]}: {exc}") from exc


def twist_limits(cfg: Config, base: WalkParams) -> tuple[float, float]:
    """Largest body speed [m/s] and yaw rate [rad/s] a walk with ``base`` timing can do."""
    p = _resolved(base, cfg)
    stance = float(p.stance_time)  # type: ignore[arg-type]
    return cfg.gait.max_stride / stance, cfg.gait.max_turn / (p.swing_time + stance)


def _finite_twist(vx: float, vy: float, wz: float) -> tuple[float, float, float]:
    values = []
    for name, value in (("linear.x", vx), ("linear.y", vy), ("angular.z", wz)):
        number = finite_float(value)
        if number is None:
            raise CommandError(f"cmd_vel {name} must be a finite number, got {value!r:.40}")
        values.append(number)
    return values[0], values[1], values[2]


def twist_to_params(vx: float, vy: float, wz: float, cfg: Config, base: WalkParams
                    ) -> WalkParams:
    """Walk parameters realising body velocity ``(vx, vy)`` [m/s] and yaw rate ``wz`` [rad/s].

    The gait, profile, heights and timing come from ``base``. Per slot the body moves
    ``b x stride`` with ``b = slot / stance``, so the speed is ``stride / stance_time``; the yaw
    per step (one gait cycle of ``n_groups`` slots) is ``wz x n_groups x slot_time``. A twist
    beyond the configured limits is refused, not clipped. The result is validated.
    """
    vx, vy, wz = _finite_twist(vx, vy, wz)
    p = _resolved(base, cfg)
    stance = float(p.stance_time)  # type: ignore[arg-type]
    n = len(cfg.gait.gaits[p.gait])
    slot = (p.swing_time + stance) / n
    v_max, w_max = twist_limits(cfg, p)
    speed = math.hypot(vx, vy)
    if speed > v_max * (1 + TWIST_LIMIT_TOLERANCE):
        raise CommandError(f"{TWIST_BEYOND_LIMITS[0]} {speed:.4g} m/s exceeds the maximum "
                           f"{v_max:.4g} m/s "
                           f"(max_stride {cfg.gait.max_stride:g} m per stance of {stance:g} s)")
    if abs(wz) > w_max * (1 + TWIST_LIMIT_TOLERANCE):
        raise CommandError(f"{TWIST_BEYOND_LIMITS[1]} {wz:.4g} rad/s exceeds the maximum "
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
