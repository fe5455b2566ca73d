"""The exception tree of crawler_motion.

Every error the package raises on purpose derives from `CrawlerMotionError`, so callers can
catch one type. Messages say what was wrong and what would be right.

    CrawlerMotionError
    ├── ConfigError            invalid configuration file or parameter value
    ├── KinematicsError
    │   ├── UnreachableError   foot target outside the leg's workspace
    │   └── JointLimitError    joint angle outside its configured limits
    ├── TrajectoryError        inconsistent trajectory constraints
    ├── GaitError              a walk that cannot be planned or executed
    ├── CommandError           a malformed or out-of-range operator command
    └── ProtocolError          CAN encoding/decoding or axis-map error
"""

from __future__ import annotations


class CrawlerMotionError(Exception):
    """Base class of all errors raised by crawler_motion."""


class ConfigError(CrawlerMotionError, ValueError):
    """A configuration file or parameter value is invalid."""


class KinematicsError(CrawlerMotionError, ValueError):
    """A foot target or joint configuration cannot be realised."""


class UnreachableError(KinematicsError):
    """A foot target lies outside the workspace of its leg."""


class JointLimitError(KinematicsError):
    """A joint angle lies outside its configured limits."""


class TrajectoryError(CrawlerMotionError, ValueError):
    """Trajectory constraints are inconsistent (e.g. non-positive segment time)."""


class GaitError(CrawlerMotionError, ValueError):
    """A walk cannot be planned, or would leave the workspace or the joint limits."""


class CommandError(CrawlerMotionError, ValueError):
    """An operator command is malformed, unknown or out of range."""


class ProtocolError(CrawlerMotionError, ValueError):
    """A CAN frame cannot be encoded or decoded, or the axis map is inconsistent."""
