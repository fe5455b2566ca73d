"""The frame families of the motor-manager protocol and the decoded frames, as data."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class FrameKind(str, Enum):
    """A frame family of the DBC (the value is the family name used in text and APIs)."""

    CONTROL = "control"  # MM_Control: Command, CommandInv
    TARGET = "target"  # MM_Target_<g>: Axis<n>_Target, Counter, Checksum
    POSITION = "position"  # MM_Position_<g>: Axis<n>_Position, Counter, Checksum
    EFFORT = "effort"  # MM_Effort_<g> (optional): Axis<n>_Effort, Counter, Checksum
    STATUS = "status"  # MM_Status_<g>: Axis<n>_<Flag>, Counter, Checksum
    HEARTBEAT = "heartbeat"  # MM_Heartbeat: State, Counter

    def __str__(self) -> str:
        return self.value


class Side(str, Enum):
    """Which end of the bus sends a frame."""

    CONTROLLER = "controller"  # the driver: control and target frames
    MANAGER = "manager"  # the motor manager: positions, efforts, status, heartbeat

    def __str__(self) -> str:
        return self.value


#: Grouped frame families (``MM_<Family>_<g>``) -> the family word in message and signal names.
GROUPED: dict[FrameKind, str] = {FrameKind.TARGET: "Target", FrameKind.POSITION: "Position",
                                 FrameKind.EFFORT: "Effort", FrameKind.STATUS: "Status"}
#: Grouped families a DBC may leave out entirely (an older manager without effort frames).
OPTIONAL_KINDS = frozenset({FrameKind.EFFORT})
#: Families carrying one position signal per axis.
POSITION_KINDS = (FrameKind.TARGET, FrameKind.POSITION)
#: Families carrying one number per axis (``Axis<n>_<Family>``).
AXIS_VALUE_KINDS = (*POSITION_KINDS, FrameKind.EFFORT)
#: Frame families the controller (the driver) sends; the manager sends the others.
CONTROLLER_KINDS = frozenset({FrameKind.CONTROL, FrameKind.TARGET})

#: Status flag attribute of `AxisFlags` -> signal suffix in the DBC (``Axis<n>_<suffix>``).
FLAG_SIGNALS: dict[str, str] = {
    "enabled": "Enabled",
    "tracking": "Tracking",
    "over_current": "OverCurrent",
    "over_temp": "OverTemp",
    "encoder_fault": "EncoderFault",
    "stalled": "Stalled",
    "command_timeout": "CmdTimeout",
}


def sender_of(kind: FrameKind) -> Side:
    """The side that sends frames of a family."""
    return Side.CONTROLLER if kind in CONTROLLER_KINDS else Side.MANAGER


@dataclass(frozen=True)
class GroupPositions:
    """Positions of one frame group: ``positions`` by joint [rad, joint space] and ``axes`` by
    axis index [rad, axis space]."""

    group: int
    counter: int
    positions: dict[str, float]
    axes: dict[int, float]


@dataclass(frozen=True)
class TargetFrame(GroupPositions):
    """One target frame: the commanded positions of one group."""


@dataclass(frozen=True)
class ControlFrame:
    """A manager command: one of ``MotorProtocol.commands``."""

    command: str


@dataclass(frozen=True)
class PositionFeedback(GroupPositions):
    """One position frame: the measured positions of one group."""


@dataclass(frozen=True)
class EffortFeedback:
    """One effort frame: the measured efforts of one group, ``efforts`` by joint [N m, joint
    space: the torque about the joint's axis in its angle's sense] and ``axes`` by axis index
    [N m, axis space: direction * joint torque]."""

    group: int
    counter: int
    efforts: dict[str, float]
    axes: dict[int, float]


@dataclass(frozen=True)
class AxisFlags:
    """Status and fault bits of one axis."""

    enabled: bool = False
    tracking: bool = False
    over_current: bool = False
    over_temp: bool = False
    encoder_fault: bool = False
    stalled: bool = False
    command_timeout: bool = False

    @property
    def fault(self) -> bool:
        """True when any fault bit (over-current, over-temperature, encoder) is set."""
        return self.over_current or self.over_temp or self.encoder_fault


@dataclass(frozen=True)
class AxisStatus:
    """Status bits of the axes of one status frame, by joint name and by axis index."""

    group: int
    counter: int
    flags: dict[str, AxisFlags]
    axes: dict[int, AxisFlags]


@dataclass(frozen=True)
class Heartbeat:
    """Manager heartbeat: ``state`` is one of ``MotorProtocol.states``."""

    state: str
    counter: int


#: What `MotorProtocol.decode` returns.
Decoded = (TargetFrame | ControlFrame | PositionFeedback | EffortFeedback | AxisStatus
           | Heartbeat)
