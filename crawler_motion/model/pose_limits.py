"""Limits and peak speeds of the standing body pose: section ``body_pose`` of robot.yaml."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from crawler_motion.model.yaml_values import positive


@dataclass(frozen=True)
class BodyPoseConfig:
    """How far the standing body may shift and tilt with every foot on the ground, and how
    fast a pose move goes (its height stays within ``robot.body_height_range``)."""

    max_shift: float  # |x|, |y| [m]
    max_tilt: float  # |roll|, |pitch| [rad]
    max_yaw: float  # |yaw| [rad]
    speed: float  # peak body speed of a pose move [m/s]
    turn_rate: float  # peak body turn rate of a pose move [rad/s]


def parse_body_pose(data: Mapping[str, Any], where: str = "body_pose") -> BodyPoseConfig:
    """Validate the ``body_pose`` section (every value a finite number > 0)."""
    return BodyPoseConfig(**{f.name: positive(data.get(f.name), f"{where}.{f.name}")
                             for f in fields(BodyPoseConfig)})
