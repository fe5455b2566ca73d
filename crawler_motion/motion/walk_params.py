"""Walk parameters and their validation (pure): the `WalkParams` of every walk.

Ranges come from the one option table (`crawler_motion.motion.walk_options`) and the loaded
robot config; every problem raises `GaitError` naming the field, its value and what is allowed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from crawler_motion.errors import GaitError
from crawler_motion.model.config import Config, GaitConfig
from crawler_motion.model.gait_config import STANCE_PROFILES
from crawler_motion.motion.walk_options import (
    OPTIONS,
    clearance_error,
    default_stance_time,
    stance_time_error,
    sways,
)

#: Smallest arc/lift ratio for profiles with a junction speed at B (below it the arc dips under
#: B's height: with the shipped smooth profile the bound is 0.0245).
MIN_ARC_RATIO = 0.05


@dataclass(frozen=True)
class WalkParams:
    """Parameters of a walk. Lengths in m, angles in rad, times in s."""

    gait: str = "diagonal"
    profile: str = "smooth"
    stride: float = 0.06  # foot travel relative to the body during one stance [m]
    heading: float = 0.0  # direction of travel in base_link [rad] (0 forward, pi/2 left)
    turn: float = 0.0  # body yaw per step (one gait cycle) [rad], + counter-clockwise
    lift: float = 0.01
    arc: float = 0.01
    swing_time: float = 0.6
    stance_time: float | None = None  # None: (groups - 1) x swing_time
    body_height: float | None = None  # None: the configured standing height
    margin: float | None = None  # crawl gaits' static stability margin [m]; None: configured
    stance_profile: str = "rest"  # "rest" or "continuous" (`crawler_motion.motion.slot`)

    @classmethod
    def defaults(cls, gait_cfg: GaitConfig, **overrides: object) -> WalkParams:
        """Walk parameters from the config defaults, with ``overrides`` (the swing time,
        stride and stance profile default to those of the walk's gait, `GaitConfig.swing_time_of`,
        `GaitConfig.stride_of`, `GaitConfig.stance_profile_of`)."""
        gait = str(overrides.get("gait", gait_cfg.gait))
        base = cls(gait=gait_cfg.gait, profile=gait_cfg.profile, stride=gait_cfg.stride_of(gait),
                   lift=gait_cfg.lift, arc=gait_cfg.arc, swing_time=gait_cfg.swing_time_of(gait),
                   stance_time=None, margin=gait_cfg.stability_margin,
                   stance_profile=gait_cfg.stance_profile_of(gait))
        return replace(base, **overrides)  # type: ignore[arg-type]


def validate_params(params: WalkParams, cfg: Config) -> WalkParams:
    """Check ranges and consistency; return params with ``stance_time`` resolved.

    Raises `GaitError` naming the field, its value and the allowed range.
    """
    g = cfg.gait
    if params.gait not in g.gaits:
        raise GaitError(f"gait '{params.gait}' unknown; choose one of {sorted(g.gaits)}")
    if params.profile not in g.profiles:
        raise GaitError(f"profile '{params.profile}' unknown; choose one of {sorted(g.profiles)}")
    margin = g.stability_margin if params.margin is None else params.margin
    params = replace(params, margin=margin)
    for name in ("stride", "heading", "turn", "lift", "arc", "swing_time", "margin"):
        value = getattr(params, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
                value):
            raise GaitError(f"{name} must be a finite number, got {value!r}")

    def in_range(name: str, value: float, lo: float, hi: float, unit: str) -> None:
        if not lo <= value <= hi:
            raise GaitError(f"{name} = {value} {unit} is outside [{lo}, {hi}] {unit}")

    for name in ("stride", "turn", "lift", "arc", "margin"):
        in_range(name, getattr(params, name), *OPTIONS[name].range(cfg), OPTIONS[name].unit)
    clearance = clearance_error(cfg, params.lift, params.arc)
    if clearance is not None:
        raise GaitError(clearance)
    if params.profile in g.profiles and g.profiles[params.profile].v_b > 0 and (
            params.arc < MIN_ARC_RATIO * params.lift):
        raise GaitError(f"arc = {params.arc} m: the {params.profile} profile reaches B still "
                        f"rising and needs arc >= {MIN_ARC_RATIO} x lift = "
                        f"{MIN_ARC_RATIO * params.lift:.4g} m to stay above B on the arc")
    in_range("swing_time", params.swing_time, *OPTIONS["swing_time"].range(cfg), "s")
    stance = default_stance_time(cfg, params.gait, params.swing_time) if (
        params.stance_time is None) else params.stance_time
    if isinstance(stance, bool) or not isinstance(stance, (int, float)) or not math.isfinite(
            stance):
        raise GaitError(f"stance_time must be a finite number, got {stance!r}")
    stance_error = stance_time_error(cfg, params.gait, params.swing_time, stance)
    if stance_error is not None:
        raise GaitError(stance_error)
    if params.stance_profile not in STANCE_PROFILES:
        raise GaitError(f"stance_profile '{params.stance_profile}' unknown; choose one of "
                        f"{list(STANCE_PROFILES)}")
    if params.stance_profile == "continuous":
        n = len(g.gaits[params.gait])
        if sways(cfg, params.gait, params.swing_time, float(stance)):
            raise GaitError(f"the continuous stance_profile moves the body at constant speed, "
                            f"but this {params.gait} walk sways its body in all-feet-down "
                            f"transfers; use stance_profile rest, or a gait with two or more "
                            f"legs per group and stance_time = {n - 1} x swing_time")
        if abs(float(stance) - (n - 1) * params.swing_time) > 1e-9:
            raise GaitError(f"stance_time = {stance:g} s: the continuous stance_profile needs "
                            f"stance_time = {n - 1} x swing_time = "
                            f"{(n - 1) * params.swing_time:g} s (no dwell)")
    height = cfg.robot.body_height if params.body_height is None else params.body_height
    lo, hi = OPTIONS["body_height"].range(cfg)
    if not (isinstance(height, (int, float)) and math.isfinite(height) and lo <= height <= hi):
        raise GaitError(f"body_height = {height} m is outside [{lo}, {hi}] m")
    return replace(params, stance_time=float(stance), body_height=float(height))


def gait_defaults(cfg: Config, gait: str) -> dict[str, object]:
    """The walk options whose default is the gait table's own: swing time, stride and stance
    profile (`GaitConfig.swing_time_of`, `stride_of`, `stance_profile_of`)."""
    g = cfg.gait
    return {"swing_time": g.swing_time_of(gait), "stride": g.stride_of(gait),
            "stance_profile": g.stance_profile_of(gait)}


def follow_gait(values: dict[str, object], old: str, new: str, cfg: Config,
                chosen: set[str] | frozenset[str] = frozenset()) -> dict[str, object]:
    """``values`` (walk options by name) for a change of gait from ``old`` to ``new``: each
    option of `gait_defaults` that has ``old``'s default and is not in ``chosen`` takes
    ``new``'s (a value chosen otherwise is kept). The one rule of a walk command that changes
    the gait and of the planner's gait parameter."""
    if new == old or new not in cfg.gait.gaits or old not in cfg.gait.gaits:
        return dict(values)
    before, after = gait_defaults(cfg, old), gait_defaults(cfg, new)
    out = dict(values)
    for name, value in before.items():
        if name not in chosen and out.get(name) == value:
            out[name] = after[name]
    return out
