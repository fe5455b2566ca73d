"""The ``gait`` section of the robot configuration: defaults, ranges, phase tables, profiles.

Loaded and validated once with the rest of ``robot.yaml`` (`crawler_motion.model.config`).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from crawler_motion.errors import ConfigError
from crawler_motion.model.yaml_values import number as _number
from crawler_motion.model.yaml_values import positive as _positive
from crawler_motion.model.yaml_values import section as _section

#: The lift, arc and lower fractions of a profile must sum to 1 within this (rounding only).
FRACTION_SUM_TOL = 1e-9
#: The stance profiles (`crawler_motion.motion.slot.StanceProfile`).
STANCE_PROFILES: tuple[str, ...] = ("rest", "continuous")


@dataclass(frozen=True)
class ProfileConfig:
    """Time split of the swing and junction velocity ratios of one profile.

    The fractions are parts of the swing time (robot.yaml keys ``lift``, ``arc``, ``lower`` of
    ``gait.profiles.<name>``); not to be confused with the heights ``lift`` and ``arc`` [m] of
    `GaitConfig` and `WalkParams`. ``v_b`` / ``v_d`` are the junction speeds at B / D in units
    of the mean vertical speed of the lift / lower segment.
    """

    lift_fraction: float
    arc_fraction: float
    lower_fraction: float
    v_b: float
    v_d: float


@dataclass(frozen=True)
class GaitConfig:
    """Gait defaults, ranges, phase tables and profiles."""

    gait: str
    profile: str
    stride: float
    lift: float
    arc: float
    swing_time: float
    #: Stance time [s] of the single-leg step cycle (the default of ``crawler-motion
    #: trajectory``, the comparison plots); walks (planner, ``crawler-motion walk``) default
    #: to ``(groups - 1) x swing_time`` of their gait instead (`gait.validate_params`).
    stance_time: float
    max_stride: float
    max_turn: float
    max_clearance: float
    swing_time_range: tuple[float, float]
    gaits: dict[str, tuple[tuple[str, ...], ...]] = field(default_factory=dict)
    profiles: dict[str, ProfileConfig] = field(default_factory=dict)
    #: Mean all-feet-down time [s] per slot of a crawl gait (one leg per group), in which the
    #: body sways over the next support triangle (`crawler_motion.motion.sway`; each transfer
    #: sized to the body's travel in it, `crawler_motion.motion.gait.GaitSequencer`).
    transfer_time: float = 0.3
    #: Default static stability margin of crawl gaits [m]: the body centre's distance inside
    #: the support polygon at every instant.
    stability_margin: float = 0.015
    #: Default stance profile of walks: "rest" or "continuous" (`crawler_motion.motion.slot`).
    stance_profile: str = "rest"
    #: The phase tables' own mean all-feet-down time per slot [s] of their default stance time,
    #: by gait (key ``transfer_time`` of a table; without it: ``transfer_time`` for a crawl
    #: gait, none for another, `crawler_motion.motion.walk_options.gait_transfer_time`).
    transfers: dict[str, float] = field(default_factory=dict)
    #: By gait of pairs (key ``sway_weight`` of a table, dimensionless): the body moves along
    #: its support line in the swings, trading the sway's size against the transfer's travel
    #: (`crawler_motion.motion.sway.line_sways`); without it the sway is the nearest point of
    #: the line and the transfer carries the whole step.
    sway_weights: dict[str, float] = field(default_factory=dict)
    #: By gait: the table's own default swing time [s] (key ``swing_time`` of a table, within
    #: ``swing_time_range``); without it a walk of the gait defaults to ``swing_time``.
    swings: dict[str, float] = field(default_factory=dict)
    #: By gait: the table's own default stride [m] (key ``stride`` of a table, within
    #: ``max_stride``); without it a walk of the gait defaults to ``stride``.
    strides: dict[str, float] = field(default_factory=dict)
    #: By gait: the table's own default stance profile (key ``stance_profile`` of a table).
    stance_profiles: dict[str, str] = field(default_factory=dict)
    #: Gaits of pairs whose body motion is planned from the zero-moment point (key ``body:
    #: zmp`` of a table; `crawler_motion.motion.zmp`): the body sways so that the ZMP of the
    #: inverted pendulum on the two stance feet stays on their support line.
    zmp_gaits: frozenset[str] = frozenset()

    def swing_time_of(self, gait: str) -> float:
        """The default swing time [s] of a walk of ``gait``: its table's own, else
        ``swing_time``."""
        return self.swings.get(gait, self.swing_time)

    def stride_of(self, gait: str) -> float:
        """The default stride [m] of a walk of ``gait``: its table's own, else ``stride``."""
        return self.strides.get(gait, self.stride)

    def stance_profile_of(self, gait: str) -> str:
        """The default stance profile of a walk of ``gait``: its table's own, else
        ``stance_profile``."""
        return self.stance_profiles.get(gait, self.stance_profile)


def _parse_gaits(data: Mapping[str, Any], legs: tuple[str, ...], where: str
                 ) -> dict[str, tuple[tuple[str, ...], ...]]:
    gaits: dict[str, tuple[tuple[str, ...], ...]] = {}
    for name, table in _section(data, "gaits", where).items():
        groups = table.get("groups") if isinstance(table, Mapping) else None
        if (not isinstance(groups, list) or len(groups) < 2
                or not all(isinstance(group, list) and group
                           and all(isinstance(leg, str) for leg in group) for group in groups)):
            raise ConfigError(f"{where}.gaits.{name}.groups must list >= 2 groups (lists) of "
                              f"leg names, got {groups!r}")
        flat = [leg for group in groups for leg in group]
        if sorted(flat) != sorted(legs):
            raise ConfigError(f"{where}.gaits.{name}: every leg {list(legs)} must swing exactly "
                              f"once per step, got {groups}")
        gaits[str(name)] = tuple(tuple(group) for group in groups)
    return gaits


def _table_entries(data: Mapping[str, Any], key: str, where: str
                   ) -> Iterator[tuple[str, Any, str]]:
    """The phase tables that set ``key``: (gait, the value, where it is)."""
    for name, table in _section(data, "gaits", where).items():
        if isinstance(table, Mapping) and key in table:
            yield str(name), table[key], f"{where}.gaits.{name}.{key}"


def _parse_table_values(data: Mapping[str, Any], key: str, unit: str, where: str
                        ) -> dict[str, float]:
    """The phase tables' own ``key`` (a number >= 0, in ``unit``), by gait."""
    values: dict[str, float] = {}
    for name, raw, what in _table_entries(data, key, where):
        value = _number(raw, what)
        if value < 0:
            raise ConfigError(f"{what} must be >= 0{unit}, got {value}")
        values[name] = value
    return values


def _parse_sway_weights(data: Mapping[str, Any], gaits: Mapping[str, tuple[tuple[str, ...], ...]],
                        n_legs: int, where: str) -> dict[str, float]:
    """The tables' ``sway_weight``: only for a gait of pairs (every swing leaves a support
    line of two feet), where it is used."""
    weights = _parse_table_values(data, "sway_weight", "", where)
    for name in weights:
        if any(n_legs - len(group) != 2 for group in gaits[name]):
            raise ConfigError(f"{where}.gaits.{name}.sway_weight applies to a gait whose every "
                              f"swing leaves two feet on the ground (a support line), got "
                              f"groups {[list(g) for g in gaits[name]]}; remove it")
    return weights


#: The values of a table's ``body`` key: how the body moves in a walk of the gait.
BODY_PLANS: tuple[str, ...] = ("plan", "zmp")


def _parse_table_choices(data: Mapping[str, Any], key: str, allowed: tuple[str, ...],
                         where: str) -> dict[str, str]:
    """The phase tables' own ``key`` (one of ``allowed``), by gait."""
    values: dict[str, str] = {}
    for name, raw, what in _table_entries(data, key, where):
        if raw not in allowed:
            raise ConfigError(f"{what} must be one of {list(allowed)}, got {raw!r}")
        values[name] = str(raw)
    return values


def _parse_zmp_gaits(data: Mapping[str, Any], gaits: Mapping[str, tuple[tuple[str, ...], ...]],
                     n_legs: int, where: str) -> frozenset[str]:
    """The tables with ``body: zmp``: only a gait whose every swing leaves a support line."""
    bodies = _parse_table_choices(data, "body", BODY_PLANS, where)
    zmp = frozenset(name for name, body in bodies.items() if body == "zmp")
    for name in zmp:
        if any(n_legs - len(group) != 2 for group in gaits[name]):
            raise ConfigError(f"{where}.gaits.{name}.body: zmp applies to a gait whose every "
                              f"swing leaves two feet on the ground (a support line), got "
                              f"groups {[list(g) for g in gaits[name]]}; use body: plan")
    return zmp


def _parse_profiles(data: Mapping[str, Any], where: str) -> dict[str, ProfileConfig]:
    profiles: dict[str, ProfileConfig] = {}
    for name, prof in _section(data, "profiles", where).items():
        if not isinstance(prof, Mapping):
            raise ConfigError(f"{where}.profiles.{name} must be a mapping")
        values = {k: _number(prof.get(k), f"{where}.profiles.{name}.{k}")
                  for k in ("lift", "arc", "lower", "v_b", "v_d")}
        fractions = (values["lift"], values["arc"], values["lower"])
        if min(fractions) <= 0 or abs(sum(fractions) - 1.0) > FRACTION_SUM_TOL:
            raise ConfigError(f"{where}.profiles.{name}: lift + arc + lower must be positive "
                              f"fractions summing to 1, got {fractions}")
        if values["v_b"] < 0 or values["v_d"] < 0:
            raise ConfigError(f"{where}.profiles.{name}: v_b and v_d must be >= 0")
        profiles[str(name)] = ProfileConfig(
            lift_fraction=values["lift"], arc_fraction=values["arc"],
            lower_fraction=values["lower"], v_b=values["v_b"], v_d=values["v_d"])
    for needed in ("rest", "smooth"):
        if needed not in profiles:
            raise ConfigError(f"{where}.profiles must define '{needed}'")
    return profiles


def parse_gait(data: Mapping[str, Any], legs: tuple[str, ...], where: str = "gait") -> GaitConfig:
    """Validate the ``gait`` section of the YAML and build a `GaitConfig`."""
    gaits = _parse_gaits(data, legs, where)
    profiles = _parse_profiles(data, where)
    rng = data.get("swing_time_range", [0.1, 5.0])
    if not isinstance(rng, list) or len(rng) != 2:
        raise ConfigError(f"{where}.swing_time_range must be [min, max] in s, got {rng!r}")
    cfg = GaitConfig(
        gait=str(data.get("gait", "diagonal")), profile=str(data.get("profile", "smooth")),
        stride=_number(data.get("stride"), f"{where}.stride"),
        lift=_positive(data.get("lift"), f"{where}.lift"),
        arc=_positive(data.get("arc"), f"{where}.arc"),
        swing_time=_positive(data.get("swing_time"), f"{where}.swing_time"),
        stance_time=_positive(data.get("stance_time"), f"{where}.stance_time"),
        max_stride=_positive(data.get("max_stride"), f"{where}.max_stride"),
        max_turn=_positive(data.get("max_turn"), f"{where}.max_turn"),
        max_clearance=_positive(data.get("max_clearance"), f"{where}.max_clearance"),
        swing_time_range=(_positive(rng[0], f"{where}.swing_time_range"),
                          _positive(rng[1], f"{where}.swing_time_range")),
        gaits=gaits, profiles=profiles,
        transfer_time=_positive(data.get("transfer_time", 0.3), f"{where}.transfer_time"),
        stability_margin=_number(data.get("stability_margin", 0.015),
                                 f"{where}.stability_margin"),
        stance_profile=str(data.get("stance_profile", "rest")),
        transfers=_parse_table_values(data, "transfer_time", " s", where),
        sway_weights=_parse_sway_weights(data, gaits, len(legs), where),
        swings=_parse_table_values(data, "swing_time", " s", where),
        strides=_parse_table_values(data, "stride", " m", where),
        stance_profiles=_parse_table_choices(data, "stance_profile", STANCE_PROFILES, where),
        zmp_gaits=_parse_zmp_gaits(data, gaits, len(legs), where))
    if cfg.stance_profile not in STANCE_PROFILES:
        raise ConfigError(f"{where}.stance_profile must be one of {list(STANCE_PROFILES)}, got "
                          f"{cfg.stance_profile!r}")
    if cfg.stability_margin < 0:
        raise ConfigError(f"{where}.stability_margin must be >= 0 m, got {cfg.stability_margin}")
    if cfg.swing_time_range[0] > cfg.swing_time_range[1]:
        raise ConfigError(f"{where}.swing_time_range must be [min, max] with min <= max, "
                          f"got {list(cfg.swing_time_range)}")
    for name, value in cfg.swings.items():
        if not cfg.swing_time_range[0] <= value <= cfg.swing_time_range[1]:
            raise ConfigError(f"{where}.gaits.{name}.swing_time must be within "
                              f"swing_time_range {list(cfg.swing_time_range)} s, got {value}")
    for name, value in cfg.strides.items():
        if value > cfg.max_stride:
            raise ConfigError(f"{where}.gaits.{name}.stride must be within [0, max_stride = "
                              f"{cfg.max_stride:g}] m, got {value}")
    if cfg.gait not in gaits:
        raise ConfigError(f"{where}.gait '{cfg.gait}' is not one of {sorted(gaits)}")
    if cfg.profile not in profiles:
        raise ConfigError(f"{where}.profile '{cfg.profile}' is not one of {sorted(profiles)}")
    return cfg
