"""The terrain_mapper node's parameters as `ParamSpec`s and the settings they build (pure).

Each parameter has its range, and together they must fit the mapper's budget: a grid of at
most `MAX_CELLS` cells, and at most `MAX_CELL_RATE` cells published per second (cells ×
``publish_rate``; one publication costs about 0.35 µs per cell on the reference machine, so
the budget is about a fifth of a core). ``size:=50.0 resolution:=0.02`` (6.25 M cells) is
refused with the reason instead of starving the node.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from crawler_motion.errors import ConfigError
from crawler_motion.mapping.mapper import MapperSettings
from crawler_motion.mapping.obstacles import step_threshold
from crawler_motion.mapping.odometry import OdometryLimits
from crawler_motion.mapping.points import NoiseModel
from crawler_motion.model.config import Config
from crawler_motion.runtime.parameters import ParamSpec, not_empty, validate_parameters

#: Most cells of the map window (memory, and the cost of one publication).
MAX_CELLS = 250_000
#: Most cells published per second (cells × publish_rate) [1/s].
MAX_CELL_RATE = 500_000.0


def mapper_parameters(cfg: Config) -> tuple[ParamSpec, ...]:
    """The parameters; the obstacle threshold's default is the robot's `step_threshold`."""
    return (
        ParamSpec("config_file", "", "robot.yaml (scanner mount, step height; default: the "
                  "shipped one)", read_only=True),
        ParamSpec("map_frame", "odom", "frame of the map and of odom's pose", read_only=True,
                  check=not_empty),
        ParamSpec("scanner_frame", "scanner_link", "frame_id a scan must have",
                  read_only=True, check=not_empty),
        ParamSpec("resolution", 0.05, "cell side [m]", read_only=True, minimum=0.005,
                  maximum=1.0, unit="m"),
        ParamSpec("size", 4.0, "side of the square map window around the robot [m] "
                  "(with resolution and publish_rate within the budget: at most "
                  f"{MAX_CELLS} cells and {MAX_CELL_RATE:.0f} cells published per second)",
                  read_only=True, minimum=0.5, maximum=50.0, unit="m"),
        ParamSpec("gate", 2.5, "Mahalanobis gate: a return farther from its cell's height (in "
                  "cell standard deviations) is not fused; the cell's variance grows",
                  read_only=True, minimum=0.5, maximum=100.0),
        ParamSpec("drift", 1e-5, "variance growth of every known cell per metre of travel "
                  "[m²/m]", read_only=True, minimum=0.0, maximum=1.0, unit="m²/m"),
        ParamSpec("range_noise", 0.005, "scanner range noise, standard deviation [m]",
                  read_only=True, minimum=0.0, maximum=1.0, unit="m"),
        ParamSpec("lateral_noise", 0.002, "scanner noise across the beam, standard deviation "
                  "per metre of range [m/m]", read_only=True, minimum=0.0, maximum=1.0,
                  unit="m/m"),
        ParamSpec("attitude_noise", 0.02, "body roll and pitch noise, standard deviation "
                  "[rad] (includes the attitude change in a scan's stamp error)", read_only=True,
                  minimum=0.0, maximum=1.0, unit="rad"),
        ParamSpec("obstacle_height", step_threshold(cfg), "a cell higher than its local "
                  "ground by more is an obstacle [m] (default: min(lift + arc, belly "
                  "clearance) of robot.yaml)", read_only=True, minimum=0.001, maximum=1.0,
                  unit="m"),
        ParamSpec("confidence", 2.0, "a cell must clear obstacle_height by this many standard "
                  "deviations of its height", read_only=True, minimum=0.0, maximum=10.0),
        ParamSpec("ground_radius", 0.25, "the local ground is the lowest known cell within "
                  "this [m]", read_only=True, minimum=0.0, maximum=5.0, unit="m"),
        ParamSpec("odom_window", 1.0, "odometry kept; an older scan is skipped [s]",
                  read_only=True, minimum=0.05, maximum=60.0, unit="s"),
        ParamSpec("pose_tolerance", 0.05, "a scan newer than the latest odometry by up to this "
                  "is held for the next sample, by more is skipped; a scan's pose is "
                  "interpolated between samples at most twice this apart [s]", read_only=True,
                  minimum=0.001, maximum=1.0, unit="s"),
        ParamSpec("scan_queue", 4, "scans held for odometry at or after their stamp at most; "
                  "one more drops the oldest held (counted)", read_only=True, minimum=0,
                  maximum=100),
        ParamSpec("odom_future_tolerance", 0.5, "an odometry sample stamped later than the "
                  "node's clock by more is refused [s]", read_only=True, minimum=0.0,
                  maximum=60.0, unit="s"),
        ParamSpec("odom_max_position", 1e5, "an odometry position farther from the origin "
                  "(per axis) is refused [m]", read_only=True, minimum=1.0, maximum=1e7,
                  unit="m"),
        ParamSpec("odom_max_speed", 2.0, "an odometry sample farther from the last one than "
                  "this speed (plus 0.2 m) allows is refused as a jump [m/s]", read_only=True,
                  minimum=0.01, maximum=100.0, unit="m/s"),
        ParamSpec("odom_reset_samples", 10, "this many refused samples in a row that agree with "
                  "each other are a new odometry stream: the map is cleared to unknown and "
                  "follows it", read_only=True, minimum=2, maximum=1000),
        ParamSpec("publish_rate", 10.0, "terrain_map and terrain_heights rate [Hz]",
                  read_only=True, minimum=0.1, maximum=50.0, unit="Hz"),
    )


def mapper_settings(specs: tuple[ParamSpec, ...], values: Mapping[str, Any]
                    ) -> MapperSettings:
    """Validated settings; `ConfigError` naming every bad value."""
    reasons = validate_parameters(specs, values)
    v = values
    if not reasons:
        reasons = budget_problems(v["size"], v["resolution"], v["publish_rate"])
    if reasons:
        raise ConfigError("; ".join(reasons))
    noise = NoiseModel(v["range_noise"], v["lateral_noise"], v["attitude_noise"])
    return MapperSettings(resolution=v["resolution"], size=v["size"], gate=v["gate"],
                          drift=v["drift"], noise=noise, obstacle_height=v["obstacle_height"],
                          confidence=v["confidence"],
                          ground_radius=v["ground_radius"], odom_window=v["odom_window"],
                          pose_tolerance=v["pose_tolerance"], scan_queue=v["scan_queue"],
                          odometry=OdometryLimits(
                              future_tolerance=v["odom_future_tolerance"],
                              max_position=v["odom_max_position"],
                              max_speed=v["odom_max_speed"],
                              reset_samples=v["odom_reset_samples"]))


def budget_problems(size: float, resolution: float, publish_rate: float) -> list[str]:
    """Why a map of ``size`` [m] in cells of ``resolution`` [m] published at ``publish_rate``
    [Hz] exceeds the budget (`MAX_CELLS`, `MAX_CELL_RATE`); empty when it fits."""
    cells = MapperSettings(resolution=resolution, size=size).cells ** 2
    problems = []
    if cells > MAX_CELLS:
        problems.append(f"size {size:g} m / resolution {resolution:g} m makes {cells} cells, "
                        f"more than the budget of {MAX_CELLS}: use a coarser resolution or a "
                        "smaller size")
    elif cells * publish_rate > MAX_CELL_RATE:
        problems.append(f"{cells} cells published at {publish_rate:g} Hz are "
                        f"{cells * publish_rate:.0f} cells/s, more than the budget of "
                        f"{MAX_CELL_RATE:.0f}: lower publish_rate, size or the resolution")
    return problems
