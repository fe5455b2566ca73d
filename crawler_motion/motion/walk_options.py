"""The walk options: one table of name, type, unit, range, help, flag and JSON key (pure).

Each `WalkOption` is at once a `WalkParams` field (except ``steps``; the `POSE_OPTIONS` are the
fields of `crawler_motion.motion.body_pose.BodyPose` instead), the JSON key of the gait
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
from crawler_motion.model.gait_config import STANCE_PROFILES

#: Rounding allowance of the rules that tie two options together [m or s].
PAIR_TOLERANCE = 1e-12
#: Smallest lift [m]: the foot must leave the ground.
MIN_LIFT = 1e-3
#: Largest stance time, as a multiple of the gait's smallest ``(groups - 1) x swing_time``.
MAX_STANCE_FACTOR = 10
#: Shortest all-feet-down transfer of a crawl gait's slot [s] (its body sways in it).
MIN_TRANSFER_TIME = 0.05
#: Largest stability margin [m] a crawl walk may ask for.
MAX_MARGIN = 0.05
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
    when a tool does not set it (None: the tool leaves it unset): for the default gait's own
    table values (stride, swing time, stance profile), those of the default gait.
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
               default=lambda c: c.gait.stride_of(c.gait.gait)),
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
               default=lambda c: c.gait.swing_time_of(c.gait.gait)),
    WalkOption("stance_time", _NUMBER, "stance time", "s", Sign.POSITIVE,
               lambda c: (c.gait.swing_time_range[0], _most_stance(c)),
               default=lambda c: c.gait.stance_time),
    WalkOption("stance_profile", OptionType.CHOICE,
               "how the body moves: rest (stops at every lift-off and touch-down) or continuous "
               "(constant speed, ramps at start and stop; gaits without transfer)",
               choices=lambda c: STANCE_PROFILES,
               parameter="default stance profile of a new walk",
               default=lambda c: c.gait.stance_profile_of(c.gait.gait)),
    WalkOption("margin", _NUMBER, "static stability margin of a crawl gait (the body centre "
               "inside the support polygon)", "m", Sign.NONNEGATIVE,
               lambda c: (0.0, MAX_MARGIN),
               parameter="default stability margin of a crawl walk",
               default=lambda c: c.gait.stability_margin),
    WalkOption("body_height", _NUMBER, "hip height above the ground", "m", Sign.POSITIVE,
               lambda c: c.robot.body_height_range, commands=("stand",),
               parameter="default standing body height (stand without body_height)",
               default=lambda c: c.robot.body_height),
)


def _within(limit: Callable[[Config], float]) -> Bounds:
    return lambda c: (-limit(c), limit(c))


def _rise_span(cfg: Config) -> tuple[float, float]:
    lo, hi = cfg.robot.body_height_range
    span = round(hi - lo, 12)  # the span of the config's numbers (0.09 - 0.05 = 0.0399...96)
    return -span, span


#: The body pose of a standing robot (``pose`` command): shift and fixed-axis roll, pitch, yaw
#: of base_link from its neutral standing pose (REP-103), every foot fixed on the ground.
POSE_OPTIONS: tuple[WalkOption, ...] = (
    WalkOption("x", _NUMBER, "body shift forward", "m",
               bounds=_within(lambda c: c.body_pose.max_shift), commands=("pose",)),
    WalkOption("y", _NUMBER, "body shift to the left", "m",
               bounds=_within(lambda c: c.body_pose.max_shift), commands=("pose",)),
    WalkOption("z", _NUMBER, "body rise above the standing height (the posed height stays "
               "within body_height_range)", "m", bounds=_rise_span, commands=("pose",)),
    WalkOption("roll", _NUMBER, "body roll (about x; + left side up)", "rad",
               bounds=_within(lambda c: c.body_pose.max_tilt), commands=("pose",)),
    WalkOption("pitch", _NUMBER, "body pitch (about y; + nose down)", "rad",
               bounds=_within(lambda c: c.body_pose.max_tilt), commands=("pose",)),
    WalkOption("yaw", _NUMBER, "body yaw (about z; + counter-clockwise)", "rad",
               bounds=_within(lambda c: c.body_pose.max_yaw), commands=("pose",)),
)
#: Every option (walk and pose) by name.
OPTIONS: dict[str, WalkOption] = {option.name: option
                                  for option in (*WALK_OPTIONS, *POSE_OPTIONS)}


def options_of(command: str) -> tuple[WalkOption, ...]:
    """The options the gait command ``command`` takes, in table order."""
    return tuple(option for option in OPTIONS.values() if command in option.commands)


def field_ranges(cfg: Config) -> dict[str, tuple[float, float, str]]:
    """Allowed range ``(lo, hi, unit)`` of every numeric option (walk and pose), from the
    config."""
    return {option.name: (*option.range(cfg), option.unit) for option in OPTIONS.values()
            if option.type is OptionType.NUMBER}


def pose_height_error(cfg: Config, body_height: float, z: float) -> str | None:
    """Why the pose rise ``z`` [m] at the standing ``body_height`` [m] leaves the allowed body
    height range; None if it does not."""
    lo, hi = cfg.robot.body_height_range
    if lo - PAIR_TOLERANCE <= body_height + z <= hi + PAIR_TOLERANCE:
        return None
    return (f"z = {z:g} m puts the body at {body_height + z:g} m, outside body_height_range "
            f"[{lo:g}, {hi:g}] m; at the standing height {body_height:g} m z must be in "
            f"[{lo - body_height:g}, {hi - body_height:g}] m")


def stance_time_range(cfg: Config, gait: str, swing_time: float) -> tuple[float, float]:
    """Allowed stance time ``(lo, hi)`` [s] of ``gait`` with ``swing_time`` [s]: at least
    ``(groups - 1) x swing_time``, plus ``groups x MIN_TRANSFER_TIME`` for a crawl gait."""
    n = len(cfg.gait.gaits[gait])
    least = (n - 1) * swing_time
    extra = n * MIN_TRANSFER_TIME if is_crawl(cfg, gait) else 0.0
    return least + extra, MAX_STANCE_FACTOR * least


def is_crawl(cfg: Config, gait: str) -> bool:
    """True for a crawl gait: one leg per group, three or more feet on the ground during every
    swing, so its body sways to keep a static stability margin (`crawler_motion.motion.sway`)."""
    groups = cfg.gait.gaits[gait]
    return all(len(group) == 1 for group in groups) and cfg.robot.n_legs - 1 >= 3


def sways(cfg: Config, gait: str, swing_time: float, stance_time: float) -> bool:
    """True when a walk sways its body (`crawler_motion.motion.sway`): a crawl gait always;
    another gait (two feet on the ground: a support line) when its all-feet-down transfer
    per slot is at least `MIN_TRANSFER_TIME` (its default stance time has none: it rocks)."""
    if is_crawl(cfg, gait):
        return True
    n = len(cfg.gait.gaits[gait])
    transfer = (stance_time - (n - 1) * swing_time) / n
    return transfer >= MIN_TRANSFER_TIME - PAIR_TOLERANCE


def gait_transfer_time(cfg: Config, gait: str) -> float:
    """Mean all-feet-down time per slot [s] of ``gait``'s default stance time: its phase
    table's ``transfer_time``, else ``gait.transfer_time`` for a crawl gait, else 0."""
    own = cfg.gait.transfers.get(gait)
    if own is not None:
        return own
    return cfg.gait.transfer_time if is_crawl(cfg, gait) else 0.0


def default_stance_time(cfg: Config, gait: str, swing_time: float) -> float:
    """Stance time [s] of a walk that does not set one: ``(groups - 1) x swing_time`` plus
    ``groups x`` `gait_transfer_time` (a crawl gait's all-feet-down sway in every slot; the
    diagonal gait has none unless its table sets one, docs/gaits.md)."""
    n = len(cfg.gait.gaits[gait])
    return (n - 1) * swing_time + n * gait_transfer_time(cfg, gait)


def stance_time_error(cfg: Config, gait: str, swing_time: float, stance_time: float
                      ) -> str | None:
    """Why ``stance_time`` [s] does not fit ``gait`` with ``swing_time`` [s]; None if it does."""
    lo, hi = stance_time_range(cfg, gait, swing_time)
    if lo - PAIR_TOLERANCE <= stance_time <= hi:
        return None
    n = len(cfg.gait.gaits[gait])
    least = f"{n - 1} x swing_time" + (
        f" + {n} x {MIN_TRANSFER_TIME:g} s of all-feet-down transfer" if is_crawl(cfg, gait)
        else "")
    return (f"stance_time = {stance_time:g} s: the {gait} gait ({n} groups) needs stance_time "
            f"in [{lo:g}, {hi:g}] s (>= {least})")


def clearance_error(cfg: Config, lift: float, arc: float) -> str | None:
    """Why ``lift + arc`` [m] is too high for the config; None if it is not."""
    top = cfg.gait.max_clearance
    if lift + arc <= top + PAIR_TOLERANCE:
        return None
    return (f"arc = {arc:g} m: lift + arc = {lift + arc:g} m exceeds the maximum clearance "
            f"{top:g} m")
