"""Robot and gait configuration, loaded from YAML and validated once.

Arrays are shaped ``(4, 3)`` with one row per leg in ``legs`` order (lf, lb, rb, rf); columns
are x, y, z for positions [m] and root, shoulder, knee for joints [rad].
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from crawler_motion.errors import ConfigError
from crawler_motion.model.calibration_file import LegCalibration, with_calibration
from crawler_motion.model.gait_config import (  # re-exported: part of the loaded `Config`
    GaitConfig,
    parse_gait,
)
from crawler_motion.model.medium import MediumConfig, parse_medium
from crawler_motion.model.pose_limits import BodyPoseConfig, parse_body_pose
from crawler_motion.model.yaml_values import number as _number
from crawler_motion.model.yaml_values import number_in
from crawler_motion.model.yaml_values import positive as _positive
from crawler_motion.model.yaml_values import section as _section

PACKAGE = "crawler_motion"
JOINT_KINDS: tuple[str, ...] = ("root", "shoulder", "knee")
DEFAULT_LEGS: tuple[str, ...] = ("lf", "lb", "rb", "rf")


def config_dir() -> Path:
    """Directory holding the shipped configuration files.

    Looks in the source tree first (editable installs, tests), then the ament share directory,
    then ``<prefix>/share/crawler_motion/config`` of a plain pip install.
    """
    here = Path(__file__).resolve().parents[2] / "config"
    if (here / "robot.yaml").is_file():
        return here
    try:  # pragma: no cover - depends on the ROS workspace
        from ament_index_python.packages import get_package_share_directory

        share = Path(get_package_share_directory(PACKAGE)) / "config"
        if (share / "robot.yaml").is_file():
            return share
    except Exception:
        pass
    share = Path(sys.prefix) / "share" / PACKAGE / "config"
    if (share / "robot.yaml").is_file():
        return share
    raise ConfigError(f"cannot find the {PACKAGE} config directory (looked in {here}, {share})")


def config_path(name: str) -> Path:
    """Path of a shipped configuration file, e.g. ``config_path("robot.yaml")``."""
    return config_dir() / name


def joint_names(legs: tuple[str, ...] = DEFAULT_LEGS) -> tuple[str, ...]:
    """The 12 joint names in array order: ``lf_root_joint, lf_shoulder_joint, ...``."""
    return tuple(f"{leg}_{kind}_joint" for leg in legs for kind in JOINT_KINDS)


@dataclass(frozen=True)
class RobotConfig:
    """Leg geometry and joint limits; see ``config/robot.yaml`` for conventions."""

    legs: tuple[str, ...]
    hips: np.ndarray  # (4, 3) root-axis positions in base_link [m]
    neutral_yaw: np.ndarray  # (4,) [rad]
    knee_sign: np.ndarray  # (4,) +1 knee up, -1 knee down
    l1: float
    l2: float
    l3: float
    lower: np.ndarray  # (3,) root, shoulder, knee [rad]
    upper: np.ndarray  # (3,) [rad]
    velocity: np.ndarray  # (3,) [rad/s]
    effort: np.ndarray  # (3,) [N m]
    reach: float  # standing foot: horizontal distance from the root axis [m]
    body_height: float  # standing hip height above the ground [m]
    body_height_range: tuple[float, float]
    name: str = "crawler"
    #: Per-leg geometry with assembly errors (None: the nominal geometry above).
    geometry: LegCalibration | None = None

    @property
    def calibrated(self) -> bool:
        """True when a leg's geometry differs from the nominal one (the IK then refines)."""
        return self.geometry is not None and not self.geometry.is_nominal

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The 12 joint names in array order."""
        return joint_names(self.legs)

    @property
    def n_legs(self) -> int:
        """Number of legs."""
        return len(self.legs)

    def lower_limits(self) -> np.ndarray:
        """Lower position limits as a ``(n_legs, 3)`` array [rad]."""
        return np.broadcast_to(self.lower, (self.n_legs, 3))

    def upper_limits(self) -> np.ndarray:
        """Upper position limits as a ``(n_legs, 3)`` array [rad]."""
        return np.broadcast_to(self.upper, (self.n_legs, 3))

    def standing_feet(self, body_height: float | None = None) -> np.ndarray:
        """Standing foot positions in base_link, ``(n_legs, 3)`` [m]."""
        height = self.body_height if body_height is None else float(body_height)
        lo, hi = self.body_height_range
        if not (math.isfinite(height) and lo <= height <= hi):
            raise ConfigError(f"body height {height} m is outside the allowed [{lo}, {hi}] m")
        feet = self.hips.copy()
        feet[:, 0] += self.reach * np.cos(self.neutral_yaw)
        feet[:, 1] += self.reach * np.sin(self.neutral_yaw)
        feet[:, 2] = self.hips[:, 2] - height
        return feet


@dataclass(frozen=True)
class Config:
    """Everything in ``robot.yaml``."""

    robot: RobotConfig
    gait: GaitConfig
    body_pose: BodyPoseConfig
    source: str = "<memory>"
    #: The medium as the body planner sees it (section ``medium``; `crawler_motion.model.medium`).
    medium: MediumConfig = field(default_factory=MediumConfig)
    #: Width of the survey or cleaning tool under the hull, centred on the body [m] (section
    #: ``tool``): what a mission's ``cover`` task counts as covered along the walked path.
    tool_width: float = 0.16


def parse_tool_width(data: Any, where: str) -> float:
    """The ``tool`` section's ``width`` [m] in (0, 1] (the default when the section is
    absent)."""
    if data is None:
        return Config.tool_width
    if not isinstance(data, Mapping) or set(data) != {"width"}:
        raise ConfigError(f"{where} must be a mapping with the one key width [m], got {data!r}")
    return number_in(data["width"], f"{where}.width", 0.0, 1.0, "m", above=True)


def _per_leg(section: Mapping[str, Any], legs: tuple[str, ...], what: str) -> list[Any]:
    missing = [leg for leg in legs if leg not in section]
    extra = [key for key in section if key not in legs]
    if missing or extra:
        raise ConfigError(f"{what}: expected exactly the legs {list(legs)}, "
                          f"missing {missing}, unknown {extra}")
    return [section[leg] for leg in legs]


def _parse_limits(limits: Mapping[str, Any], where: str) -> tuple[list[float], ...]:
    """Lower and upper position [rad], velocity [rad/s] and effort [N m] limits per joint
    kind, in `JOINT_KINDS` order."""
    lower, upper, vel, eff = [], [], [], []
    for kind in JOINT_KINDS:
        lim = limits.get(kind)
        if not isinstance(lim, Mapping):
            raise ConfigError(f"{where}.{kind} missing (lower, upper, velocity, effort)")
        lo = _number(lim.get("lower"), f"{where}.{kind}.lower")
        hi = _number(lim.get("upper"), f"{where}.{kind}.upper")
        if not -math.pi <= lo < hi <= math.pi:
            raise ConfigError(f"{where}.{kind}: need -pi <= lower < upper <= pi, "
                              f"got [{lo}, {hi}]")
        lower.append(lo)
        upper.append(hi)
        vel.append(_positive(lim.get("velocity"), f"{where}.{kind}.velocity"))
        eff.append(_positive(lim.get("effort"), f"{where}.{kind}.effort"))
    return lower, upper, vel, eff


def parse_robot(data: Mapping[str, Any], where: str = "robot") -> RobotConfig:
    """Validate the ``robot`` section of the YAML and build a `RobotConfig`."""
    legs_raw = data.get("legs", list(DEFAULT_LEGS))
    if (not isinstance(legs_raw, list) or len(legs_raw) != 4
            or not all(isinstance(leg, str) for leg in legs_raw) or len(set(legs_raw)) != 4):
        raise ConfigError(f"{where}.legs must list 4 distinct leg names, got {legs_raw!r}")
    legs = tuple(legs_raw)
    hips_raw = _per_leg(_section(data, "hips", where), legs, f"{where}.hips")
    hips = np.zeros((4, 3))
    for i, (leg, hip) in enumerate(zip(legs, hips_raw, strict=True)):
        if not isinstance(hip, list) or len(hip) != 3:
            raise ConfigError(f"{where}.hips.{leg} must be [x, y, z] in m, got {hip!r}")
        hips[i] = [_number(v, f"{where}.hips.{leg}") for v in hip]
    yaw = np.array([_number(v, f"{where}.neutral_yaw")
                    for v in _per_leg(_section(data, "neutral_yaw", where), legs,
                                      f"{where}.neutral_yaw")])
    knees = _per_leg(_section(data, "knee", where), legs, f"{where}.knee")
    for leg, knee in zip(legs, knees, strict=True):
        if knee not in ("up", "down"):
            raise ConfigError(f"{where}.knee.{leg} must be 'up' or 'down', got {knee!r}")
    knee_sign = np.array([1.0 if k == "up" else -1.0 for k in knees])
    links = _section(data, "links", where)
    l1, l2, l3 = (_positive(links.get(k), f"{where}.links.{k}") for k in ("l1", "l2", "l3"))
    lower, upper, vel, eff = _parse_limits(_section(data, "limits", where), f"{where}.limits")
    stance = _section(data, "stance", where)
    reach = _positive(stance.get("reach"), f"{where}.stance.reach")
    height = _positive(stance.get("body_height"), f"{where}.stance.body_height")
    rng = data.get("body_height_range", [height, height])
    if not isinstance(rng, list) or len(rng) != 2:
        raise ConfigError(f"{where}.body_height_range must be [min, max] in m, got {rng!r}")
    rng_t = (_positive(rng[0], f"{where}.body_height_range"),
             _positive(rng[1], f"{where}.body_height_range"))
    if not rng_t[0] <= height <= rng_t[1]:
        raise ConfigError(f"{where}.stance.body_height {height} m outside "
                          f"body_height_range {list(rng_t)}")
    if reach <= l1:
        raise ConfigError(f"{where}.stance.reach {reach} m must exceed the coxa l1 = {l1} m")
    knee_lo, knee_hi = lower[-1], upper[-1]
    for leg, knee in zip(legs, knees, strict=True):
        if (knee == "up" and knee_hi <= 0.0) or (knee == "down" and knee_lo >= 0.0):
            raise ConfigError(f"{where}.knee.{leg} is '{knee}' (knee angle "
                              f"{'> 0' if knee == 'up' else '< 0'}) but {where}.limits.knee "
                              f"[{knee_lo}, {knee_hi}] allows no such angle")
    return RobotConfig(legs=legs, hips=hips, neutral_yaw=yaw, knee_sign=knee_sign,
                       l1=l1, l2=l2, l3=l3, lower=np.array(lower), upper=np.array(upper),
                       velocity=np.array(vel), effort=np.array(eff), reach=reach,
                       body_height=height, body_height_range=rng_t,
                       name=str(data.get("name", "crawler")))


def load_config(path: str | Path | None = None) -> Config:
    """Load and validate ``robot.yaml`` (the shipped default when ``path`` is None)."""
    file = Path(path) if path is not None else config_path("robot.yaml")
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read config file {file}: {exc.strerror}") from exc
    except UnicodeDecodeError as exc:
        raise ConfigError(f"cannot read config file {file}: not UTF-8 text ({exc})") from exc
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"config file {file} is not valid YAML: {exc}") from exc
    if not isinstance(data, Mapping):
        raise ConfigError(f"config file {file} must hold a mapping with 'robot' and 'gait'")
    robot = parse_robot(_section(data, "robot", str(file)), f"{file}: robot")
    gait = parse_gait(_section(data, "gait", str(file)), robot.legs, f"{file}: gait")
    calibration = data["robot"].get("calibration_file")
    if calibration is not None:  # relative to robot.yaml
        robot = with_calibration(robot, file.parent / str(calibration))
    body_pose = parse_body_pose(_section(data, "body_pose", str(file)), f"{file}: body_pose")
    medium = parse_medium(data.get("medium"), f"{file}: medium")
    tool_width = parse_tool_width(data.get("tool"), f"{file}: tool")
    return Config(robot=robot, gait=gait, body_pose=body_pose, source=str(file), medium=medium,
                  tool_width=tool_width)


@dataclass(frozen=True)
class ScannerConfig:
    """Mount and ray fan of the forward range scanner (section ``scanner`` of robot.yaml)."""

    position: np.ndarray  # (3,) scanner_link origin in base_link [m]
    rpy: np.ndarray  # (3,) roll, pitch, yaw of scanner_link in base_link [rad]
    horizontal_fov: float  # [rad]
    columns: int
    vertical_fov: float  # [rad]
    rows: int
    max_range: float  # [m]
    rate: float  # [Hz]


def load_scanner(path: str | Path | None = None) -> ScannerConfig:
    """Read and validate the ``scanner`` section of ``robot.yaml`` (default: the shipped one)."""
    file = Path(path) if path is not None else config_path("robot.yaml")
    try:
        data = yaml.safe_load(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(f"cannot read the scanner section of {file}: {exc}") from exc
    where = f"{file}: scanner"
    sec = _section(data if isinstance(data, Mapping) else {}, "scanner", str(file))
    vectors = {}
    for key in ("position", "rpy"):
        raw = sec.get(key)
        if not isinstance(raw, list) or len(raw) != 3:
            raise ConfigError(f"{where}.{key} must be [x, y, z] / [roll, pitch, yaw], got {raw!r}")
        vectors[key] = np.array([_number(v, f"{where}.{key}") for v in raw])
    counts = {}
    for key in ("columns", "rows"):
        raw = sec.get(key)
        if isinstance(raw, bool) or not isinstance(raw, int) or not 1 <= raw <= 4096:
            raise ConfigError(f"{where}.{key} must be an integer in [1, 4096], got {raw!r}")
        counts[key] = raw
    angles = {k: _number(sec.get(k), f"{where}.{k}") for k in ("horizontal_fov", "vertical_fov")}
    for key, value in angles.items():
        if not 0.0 <= value < math.pi:
            raise ConfigError(f"{where}.{key} must be in [0, pi) rad, got {value}")
    return ScannerConfig(position=vectors["position"], rpy=vectors["rpy"], **angles, **counts,
                         max_range=_positive(sec.get("max_range"), f"{where}.max_range"),
                         rate=_positive(sec.get("rate"), f"{where}.rate"))
