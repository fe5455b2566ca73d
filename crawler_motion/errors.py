"""The exception tree of crawler_motion.

Every error the package raises on purpose derives from `CrawlerMotionError`, so callers can
catch one type. Messages say what was wrong and what would be right.

    CrawlerMotionError
    ├── ConfigError            invalid configuration file or parameter value
    │   ├── CalibrationError   unreadable or implausible leg calibration (path, key)
    │   └── MapFileError       unreadable or inconsistent map_server map (path)
    ├── KinematicsError
    │   ├── UnreachableError   foot target outside the leg's workspace
    │   └── JointLimitError    joint angle outside its configured limits
    ├── TrajectoryError        inconsistent trajectory constraints
    ├── GaitError              a walk that cannot be planned or executed
    │   └── PoseError          a body pose beyond its limits or a foot's workspace (field)
    ├── CommandError           a malformed or out-of-range operator command
    ├── BusOpenError           a CAN bus that cannot be opened (interface, channel, port)
    ├── RecordingError         a recording that cannot be written or read (path)
    └── ProtocolError          CAN protocol error (argument errors raise the base)
        ├── ProtocolParseError   unreadable or inconsistent DBC / axis-map file
        │                        (path, key, line)
        └── FrameError           a frame that cannot be built or read
            │                    (frame_id, signal, joint, value)
            ├── ProtocolEncodeError  a value that cannot be encoded (never clipped)
            └── ProtocolDecodeError  a received frame that is not a valid one
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


class CrawlerMotionError(Exception):
    """Base class of all errors raised by crawler_motion."""


class ConfigError(CrawlerMotionError, ValueError):
    """A configuration file or parameter value is invalid."""


class CalibrationError(ConfigError):
    """A leg calibration file or identification input is unreadable, inconsistent or
    implausible. ``path``: the file (None when not from a file); ``key``: the leg or
    ``leg.parameter`` concerned, when known."""

    def __init__(self, message: str, *, path: str | Path | None = None,
                 key: str | None = None) -> None:
        super().__init__(message)
        self.path = None if path is None else Path(path)
        self.key = key


class MapFileError(ConfigError):
    """A map_server map (YAML + image) is missing, malformed or inconsistent; ``path``: the
    file concerned."""

    def __init__(self, message: str, *, path: str | Path) -> None:
        super().__init__(message)
        self.path = Path(path)


class KinematicsError(CrawlerMotionError, ValueError):
    """A foot target or joint configuration cannot be realised.

    ``sample``: the index of the first failing sample over the leading (batch) dimensions of
    the input, or None for a single pose.
    """

    sample: tuple[int, ...] | None = None


class UnreachableError(KinematicsError):
    """A foot target lies outside the workspace of its leg."""


class JointLimitError(KinematicsError):
    """A joint angle lies outside its configured limits."""


class TrajectoryError(CrawlerMotionError, ValueError):
    """Trajectory constraints are inconsistent (e.g. non-positive segment time)."""


class GaitError(CrawlerMotionError, ValueError):
    """A walk cannot be planned, or would leave the workspace or the joint limits."""


class PoseError(GaitError):
    """A standing body pose (or the move to it) is beyond its limits or would take a foot out
    of its workspace or joint limits. ``field``: the pose field out of its range (``x``, ``y``,
    ``z``, ``roll``, ``pitch``, ``yaw``), None when the reason is a foot (the message names the
    leg)."""

    def __init__(self, message: str, *, field: str | None = None) -> None:
        super().__init__(message)
        self.field = field


class CommandError(CrawlerMotionError, ValueError):
    """An operator command is malformed, unknown or out of range."""


class BusOpenError(CrawlerMotionError, ValueError):
    """A CAN bus cannot be opened: ``interface``, ``channel``, ``port`` say which."""

    def __init__(self, message: str, *, interface: str, channel: str, port: int) -> None:
        super().__init__(message)
        self.interface = interface
        self.channel = channel
        self.port = port


class ProtocolError(CrawlerMotionError, ValueError):
    """A CAN frame cannot be encoded or decoded, or the DBC / axis map is inconsistent."""


class ProtocolParseError(ProtocolError):
    """A DBC or axis-map file cannot be read or is inconsistent.

    ``path`` is the file (None when the data did not come from a file), ``key`` the dotted place
    in the axis map (e.g. ``axes.lf_knee_joint.axis``) and ``line`` the 1-based line, when known.
    """

    def __init__(self, message: str, *, path: str | Path | None = None, key: str | None = None,
                 line: int | None = None) -> None:
        super().__init__(message)
        self.path = None if path is None else Path(path)
        self.key = key
        self.line = line


class FrameError(ProtocolError):
    """A frame cannot be built or read; the attributes say where, when known.

    ``frame_id`` is the arbitration id, ``signal`` the DBC signal name, ``joint`` the joint name
    and ``value`` the offending value (an angle in rad for positions).
    """

    def __init__(self, message: str, *, frame_id: int | None = None, signal: str | None = None,
                 joint: str | None = None, value: Any = None) -> None:
        super().__init__(message)
        self.frame_id = frame_id
        self.signal = signal
        self.joint = joint
        self.value = value


class ProtocolEncodeError(FrameError):
    """A value cannot be encoded: not finite, outside the joint limits or the DBC range."""


class ProtocolDecodeError(FrameError):
    """A received frame is not a valid frame of the protocol."""


class RecordingError(CrawlerMotionError, OSError):
    """A run recording (MCAP or CAN log) cannot be written or read: ``path`` is the file."""

    def __init__(self, message: str, *, path: str | Path) -> None:
        super().__init__(message)
        self.path = Path(path)
