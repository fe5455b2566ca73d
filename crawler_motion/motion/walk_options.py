"""The walk options: one table of name, type, unit, range, help, flag and JSON key (pure).

Each `WalkOption` is at once a `WalkParams` field (except ``steps``), the JSON key of the gait
commands that take it, the ``--flag`` of the command-line tools and, where ``parameter`` is
set, a ROS parameter of the planner (its default for a new walk). Ranges and choices that the
robot config defines are functions of the loaded `Config`. The rules that tie two options
together (lift + arc, stance vs swing time) are here too, so every checker uses the same ones.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum

from crawler_motion.model.config import Config

#: Rounding allowance of the rules that tie two options together [m or s].
PAIR_TOLERANCE = 1e-12
#: Smallest lift [m]: the foot must leave the ground.
MIN_LIFT = 1e-3
#: Largest stance time, as a multiple of the gait's smallest ``(groups - 1) x swing_time``.
MAX_STANCE_FACTOR = 10
#: Largest ``steps`` of a finite walk.
MAX_STEPS = 10_000


class OptionType(str, Enum):
    """How the value of an option is written and checked."""

    NUMBER = "number"  # a finite float within `WalkOption.bounds`
    CHOICE = "choice"  # a name of `WalkOption.choices`
    COUNT = "count"  # an integer in [1, MAX_STEPS]


class Sign(str, Enum):
    """The sign a number must have whatever the config says (checked before it is loaded)."""

    ANY = "any"
    POSITIVE = "positive"
    NONNEGATIVE = "nonnegative"


Bounds = Callable[[Config], tuple[float, float]]


@dataclass(frozen=True)
class WalkOption:
    """One walk option.

    ``commands``: the gait commands taking it as a JSON key; ``parameter``: the description
    of the planner parameter of the same name (None: not a parameter); ``default``: its value
    when a tool does not set it (None: the tool leaves it unset).
    """

    name: str
    type: OptionType
    help: str
    unit: str = ""
    sign: Sign = Sign.ANY
    bounds: Bounds | None = None
    choices: Callable[[Config], tuple[str, ...]] | None = None
    commands: tuple[str, ...] = ("walk",)
    parameter: str | None = None
    default: Callable[[Config], float | str] | None = None

    @property
    def flag(self) -> str:
        """The command-line flag, e.g. ``--swing-time``."""
        return "--" + self.name.replace("_", "-")

    @property
    def label(self) -> str:
        """The name in words, e.g. ``swing time``."""
        return self.name.replace("_", " ")

    def described(self, text: str) -> str:
        """``text`` followed by the unit in brackets (if the option has one)."""
        return f"{text} [{self.unit}]" if self.unit else text

    def range(self, cfg: Config) -> tuple[float, float]:
        """Allowed ``(lo, hi)`` of a number in ``cfg`` (``unit``)."""
        assert self.bounds is not None, f"{self.name} is not a number"
        return self.bounds(cfg)

    def allowed(self, cfg: Config) -> tuple[str, ...]:
        """The names a choice may take in ``cfg``."""
        assert self.choices is not None, f"{self.name} is not a choice"
        return self.choices(cfg)


def _most_stance(cfg: Config) -> float:
    most_groups = max(len(groups) for groups in cfg.gait.gaits.values())
    return MAX_STANCE_FACTOR * (most_groups - 1) * cfg.gait.swing_time_range[1]


_NUMBER = OptionType.NUMBER
WALK_OPTIONS: tuple[WalkOption, ...] = (
    WalkOption("steps", OptionType.COUNT, "gait cycles"),
    WalkOption("gait", OptionType.CHOICE, "gait (a phase table of the config)",
               choices=lambda c: tuple(c.gait.gaits), parameter="default gait of a new walk",
               default=lambda c: c.gait.gait),
    WalkOption("profile", OptionType.CHOICE, "swing profile (a profile of the config)",
               choices=lambda c: tuple(c.gait.profiles),
               parameter="default swing profile of a new walk", default=lambda c: c.gait.profile),
    WalkOption("stride", _NUMBER, "stride length", "m", Sign.NONNEGATIVE,
               lambda c: (0.0, c.gait.max_stride), parameter="default stride of a new walk",
               default=lambda c: c.gait.stride),
    WalkOption("heading", _NUMBER, "direction of travel in the body frame (0: forward)", "rad",
               bounds=lambda c: (-math.pi, math.pi), default=lambda c: 0.0),
    WalkOption("turn", _NUMBER, "yaw per step", "rad",
               bounds=lambda c: (-c.gait.max_turn, c.gait.max_turn), default=lambda c: 0.0),
    WalkOption("lift", _NUMBER, "A->B rise", "m", Sign.POSITIVE,
               lambda c: (MIN_LIFT, c.gait.max_clearance), parameter="default lift of a new walk",
               default=lambda c: c.gait.lift),
    WalkOption("arc", _NUMBER, "apex C above B", "m", Sign.NONNEGATIVE,
               lambda c: (0.0, c.gait.max_clearance),
               parameter="default arc (apex above the lift) of a new walk",
               default=lambda c: c.gait.arc),
    WalkOption("swing_time", _NUMBER, "swing time", "s", Sign.POSITIVE,
               lambda c: c.gait.swing_time_range, parameter="default swing time of a new walk",
               default=lambda c: c.gait.swing_time),
    WalkOption("stance_time", _NUMBER, "stance time", "s", Sign.POSITIVE,
               lambda c: (c.gait.swing_time_range[0], _most_stance(c)),
               default=lambda c: c.gait.stance_time),
    WalkOption("body_height", _NUMBER, "hip height above the ground", "m", Sign.POSITIVE,
               lambda c: c.robot.body_height_range, commands=("stand",),
               parameter="default standing body height (stand without body_height)",
               default=lambda c: c.robot.body_height),
)
#: The options by name.
OPTIONS: dict[str, WalkOption] = {option.name: option for option in WALK_OPTIONS}


def options_of(command: str) -> tuple[WalkOption, ...]:
    """The options the gait command ``command`` takes, in table order."""
    return tuple(option for option in WALK_OPTIONS if command in option.commands)


def field_ranges(cfg: Config) -> dict[str, tuple[float, float, str]]:
    """Allowed range ``(lo, hi, unit)`` of every numeric walk option, from the config."""
    return {option.name: (*option.range(cfg), option.unit) for option in WALK_OPTIONS
            if option.type is OptionType.NUMBER}


def stance_time_range(cfg: Config, gait: str, swing_time: float) -> tuple[float, float]:
    """Allowed stance time ``(lo, hi)`` [s] of ``gait`` with ``swing_time`` [s]."""
    lo = (len(cfg.gait.gaits[gait]) - 1) * swing_time
    return lo, MAX_STANCE_FACTOR * lo


def stance_time_error(cfg: Config, gait: str, swing_time: float, stance_time: float
                      ) -> str | None:
    """Why ``stance_time`` [s] does not fit ``gait`` with ``swing_time`` [s]; None if it does."""
    lo, hi = stance_time_range(cfg, gait, swing_time)
    if lo - PAIR_TOLERANCE <= stance_time <= hi:
        return None
    n = len(cfg.gait.gaits[gait])
    return (f"stance_time = {stance_time:g} s: the {gait} gait ({n} groups) needs stance_time "
            f"in [{lo:g}, {hi:g}] s (>= {n - 1} x swing_time)")


def clearance_error(cfg: Config, lift: float, arc: float) -> str | None:
    """Why ``lift + arc`` [m] is too high for the config; None if it is not."""
    top = cfg.gait.max_clearance
    if lift + arc <= top + PAIR_TOLERANCE:
        return None
    return (f"arc = {arc:g} m: lift + arc = {lift + arc:g} m exceeds the maximum clearance "
            f"{top:g} m")
