"""The navigator node's parameters as `ParamSpec`s and the settings they build (pure)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from crawler_motion.errors import ConfigError
from crawler_motion.navigation.methods import METHODS
from crawler_motion.navigation.navigator import Method, NavigatorSettings
from crawler_motion.navigation.steering import Steering
from crawler_motion.runtime.parameters import ParamSpec, not_empty, validate_parameters

NAVIGATOR_PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("config_file", "", "robot.yaml (leg geometry for the virtual body; default: the "
              "shipped one)", read_only=True),
    ParamSpec("method", Method.VIRTUAL_BODY.value, "obstacle-avoidance method: virtual_body "
              "(heading rules) or apf (improved potential field, re-planned on every map; "
              "also follows a structure)", read_only=True,
              choices=tuple(m.value for m in METHODS)),
    ParamSpec("steering", Steering.CRAB.value, "crab: walk along the heading without "
              "turning; turn: turn towards it on the radius law", read_only=True,
              choices=tuple(s.value for s in Steering)),
    ParamSpec("map_frame", "odom", "frame of goals, map and odometry", read_only=True,
              check=not_empty),
    ParamSpec("speed", 0.08, "walking speed [m/s] (the planner refuses a stride beyond "
              "max_stride)", read_only=True, minimum=0.005, maximum=1.0, unit="m/s"),
    ParamSpec("lever", 0.12, "S of the radius law: centre of mass to velocity point [m]",
              read_only=True, minimum=0.01, maximum=2.0, unit="m"),
    ParamSpec("max_yaw_rate", 0.2, "largest yaw rate of turn steering [rad/s]",
              read_only=True, minimum=0.01, maximum=2.0, unit="rad/s"),
    ParamSpec("goal_tolerance", 0.05, "arrived within this distance [m]", read_only=True,
              minimum=0.005, maximum=1.0, unit="m"),
    ParamSpec("slow_radius", 0.2, "speed falls to a quarter within this distance of the goal "
              "[m]", read_only=True, minimum=0.0, maximum=5.0, unit="m"),
    ParamSpec("margin", 0.10, "clearance added to the virtual radius [m]", read_only=True,
              minimum=0.0, maximum=1.0, unit="m"),
    ParamSpec("lookahead", 0.6, "obstacle cells farther than this do not block [m]",
              read_only=True, minimum=0.1, maximum=10.0, unit="m"),
    ParamSpec("max_turn", 100.0, "largest heading from the goal direction [deg]; beyond it "
              "on both sides the goal is unreachable", read_only=True, minimum=10.0,
              maximum=180.0, unit="deg"),
    ParamSpec("timeout", 300.0, "FAILED when not arrived this long after the goal [s]",
              read_only=True, minimum=1.0, maximum=86400.0, unit="s"),
    ParamSpec("standoff", 0.10, "apf: ρ_o, repulsion range and stand-off distance from a "
              "followed structure [m]", read_only=True, minimum=0.01, maximum=1.0, unit="m"),
    ParamSpec("path_lookahead", 0.25, "apf: steer towards the point of the path this far "
              "along it [m]", read_only=True, minimum=0.02, maximum=2.0, unit="m"),
    ParamSpec("max_goal_distance", 10.0, "a goal farther from the body is refused (send "
              "waypoints) [m]", read_only=True, minimum=0.1, maximum=1000.0, unit="m"),
    ParamSpec("odom_timeout", 0.5, "no walking on odometry older than this [s] (the goal is "
              "held, resumed when it returns)", read_only=True, minimum=0.05, maximum=10.0,
              unit="s"),
    ParamSpec("map_max_age", 1.0, "no walking on a map whose last fused scan (terrain_map's "
              "map_load_time) is older than this [s] (the goal is held, resumed when the map "
              "is fresh again)", read_only=True, minimum=0.1, maximum=10.0, unit="s"),
)


def navigator_settings(values: Mapping[str, Any]) -> NavigatorSettings:
    """Validated settings; `ConfigError` naming every bad value."""
    reasons = validate_parameters(NAVIGATOR_PARAMETERS, values)
    if reasons:
        raise ConfigError("; ".join(reasons))
    v = values
    return NavigatorSettings(
        steering=Steering(v["steering"]), speed=v["speed"], lever=v["lever"],
        max_yaw_rate=v["max_yaw_rate"], goal_tolerance=v["goal_tolerance"],
        slow_radius=v["slow_radius"], margin=v["margin"], lookahead=v["lookahead"],
        max_turn=math.radians(v["max_turn"]), timeout=v["timeout"], standoff=v["standoff"],
        path_lookahead=v["path_lookahead"], max_goal_distance=v["max_goal_distance"])
