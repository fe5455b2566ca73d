"""`MotorProtocol`: the motor manager's CAN protocol for one robot, as data (no ROS here).

The frames are described in ``config/motor_manager.dbc`` (loaded with cantools, strict; see
`crawler_motion.canbus.dbc`) and the joint-to-axis map in ``config/axes.yaml`` (see
`crawler_motion.canbus.axes`). Frames carry *axis* positions on the axis output side,

    axis_position = direction * joint_angle + zero_offset        [rad]

while the rest of the package works in joint space (joint order of
`crawler_motion.model.config.joint_names`). `MotorProtocol` converts between the two, encodes and
decodes every frame (`crawler_motion.canbus.codec`), and refuses rather than clips: a NaN, an
angle outside the joint limits or a value beyond the DBC scaling raises `ProtocolEncodeError`
(a `ProtocolError`) with what was wrong and what is allowed.

The code finds frames and signals by name, so ids, grouping, scaling and ranges can be changed
in the DBC without touching it: ``MM_Control`` (Command, CommandInv), ``MM_Target_<g>``
(``Axis<n>_Target``, Counter, Checksum), ``MM_Position_<g>`` (``Axis<n>_Position``, Counter,
Checksum), ``MM_Effort_<g>`` (optional: ``Axis<n>_Effort`` [N m], Counter, Checksum; axis
effort = direction * joint torque), ``MM_Status_<g>`` (``Axis<n>_<Flag>``, Counter, Checksum)
and ``MM_Heartbeat`` (State, Counter). ``Checksum`` is optional; where present it is one
byte-aligned byte holding a CRC-8/SAE-J1850 over the frame id (2 bytes, little-endian) and
every other data byte.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import can
import numpy as np

from crawler_motion.canbus.axes import AxisMapping, JointSpace, load_axis_map
from crawler_motion.canbus.busload import DEFAULT_BITRATE, cycle_bits, load_percent
from crawler_motion.canbus.codec import FrameCodec
from crawler_motion.canbus.dbc import DbcIndex
from crawler_motion.canbus.frames import (
    AxisFlags,
    AxisStatus,
    ControlFrame,
    Decoded,
    EffortFeedback,
    FrameKind,
    Heartbeat,
    PositionFeedback,
    Side,
    TargetFrame,
    sender_of,
)
from crawler_motion.errors import ProtocolEncodeError, ProtocolError
from crawler_motion.model.config import config_path

#: The frame types are part of this module's API (``protocol.TargetFrame`` ...).
__all__ = [
    "DEFAULT_FEEDBACK_MARGIN", "AxisFlags", "AxisMapping", "AxisStatus", "ControlFrame",
    "Decoded", "EffortFeedback", "FrameKind", "Heartbeat", "MotorProtocol", "PositionFeedback",
    "Side", "TargetFrame",
]

#: Default tolerance on measured positions beyond the joint limits [rad]: a powered-down or
#: loaded joint may sit slightly outside its commanded range (the zero pose puts the knee 0.1 rad
#: below its lower limit); feedback further out than this is taken as corrupt.
DEFAULT_FEEDBACK_MARGIN = 0.2


class MotorProtocol:
    """Encoder/decoder of the motor-manager frames for one robot.

    ``joint_names`` fixes the joint order of every position vector; ``lower``/``upper`` are the
    joint limits in that order [rad]. ``feedback_margin`` [rad] is how far beyond the limits a
    measured position may be before the frame is refused as corrupt.
    """

    def __init__(self, dbc_path: str | Path, axes_path: str | Path, joint_names: Sequence[str],
                 lower: Sequence[float], upper: Sequence[float], *,
                 feedback_margin: float = DEFAULT_FEEDBACK_MARGIN) -> None:
        if not (math.isfinite(feedback_margin) and feedback_margin >= 0):
            raise ProtocolError(f"feedback_margin must be a finite angle >= 0 rad, "
                                f"got {feedback_margin!r}")
        axis_map = load_axis_map(axes_path, joint_names)
        self._joints = JointSpace(joint_names, lower, upper, axis_map)
        self.dbc_path = Path(dbc_path)
        self._index = DbcIndex(dbc_path, self._joints.n)
        self._index.check_ranges(self._joints)
        self._codec = FrameCodec(self._index, self._joints, float(feedback_margin))

    @classmethod
    def from_config(cls, robot_config: Any, dbc_path: str | Path | None = None,
                    axes_path: str | Path | None = None, *,
                    feedback_margin: float = DEFAULT_FEEDBACK_MARGIN) -> MotorProtocol:
        """Build from a `RobotConfig` (or a `Config`) and the shipped DBC / axes defaults."""
        robot = getattr(robot_config, "robot", robot_config)
        return cls(config_path("motor_manager.dbc") if dbc_path is None else dbc_path,
                   config_path("axes.yaml") if axes_path is None else axes_path,
                   robot.joint_names, np.asarray(robot.lower_limits()).reshape(-1),
                   np.asarray(robot.upper_limits()).reshape(-1), feedback_margin=feedback_margin)

    # ---- properties ------------------------------------------------------------------------

    @property
    def feedback_margin(self) -> float:
        """Tolerance on measured positions beyond the joint limits [rad]."""
        return self._codec.feedback_margin

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in the order of every joint-space vector."""
        return self._joints.joint_names

    @property
    def n_axes(self) -> int:
        """Number of axes (= number of joints)."""
        return self._joints.n

    @property
    def axis_map(self) -> tuple[AxisMapping, ...]:
        """The joint-to-axis map, in joint order."""
        return self._joints.axis_map

    @property
    def lower(self) -> np.ndarray:
        """Lower joint limits in joint order [rad] (a copy)."""
        return self._joints.lower.copy()

    @property
    def upper(self) -> np.ndarray:
        """Upper joint limits in joint order [rad] (a copy)."""
        return self._joints.upper.copy()

    @property
    def database(self) -> Any:
        """The loaded cantools database."""
        return self._index.database

    @property
    def resolution_rad(self) -> float:
        """Coarsest position step of the target/position signals [rad] (0.0001 by default)."""
        return self._index.resolution

    @property
    def commands(self) -> tuple[str, ...]:
        """Command names accepted by `encode_control` (the DBC's MM_Control.Command choices)."""
        return tuple(str(v) for v in self._index.choices(FrameKind.CONTROL, "Command").values())

    @property
    def states(self) -> tuple[str, ...]:
        """Manager state names of the heartbeat (the DBC's MM_Heartbeat.State choices)."""
        return tuple(str(v) for v in self._index.choices(FrameKind.HEARTBEAT, "State").values())

    def period(self, kind: str) -> float | None:
        """Cycle time of a frame family from the DBC's GenMsgCycleTime [s], None if unset.

        ``kind`` is one of ``target``, ``position``, ``effort``, ``status``, ``heartbeat``.
        """
        return self._index.period(kind)

    def cycle_period(self, kind: str) -> float:
        """Cycle time of a frame family [s]: the DBC's, else the package default."""
        return self._index.cycle_period(kind)

    def sender(self, msg: Any) -> Side | None:
        """Which side sends the (standard 11-bit) id of ``msg``: ``"controller"`` (control and
        target frames), ``"manager"`` (feedback), or None (unknown or extended id, not a
        frame). Lets each side skip its own frames, looped back on udp_multicast, undecoded."""
        if getattr(msg, "is_extended_id", True):
            return None
        frame = self._index.frames.get(getattr(msg, "arbitration_id", None))
        return None if frame is None else sender_of(frame.kind)

    def frame_ids(self, kind: str) -> tuple[int, ...]:
        """Arbitration ids of a frame family (``control``, ``target``, ``position``, ...)."""
        return tuple(fid for fid, f in self._index.frames.items() if f.kind == kind)

    @property
    def has_effort(self) -> bool:
        """True when the DBC has effort frames (``MM_Effort_<g>``)."""
        return bool(self._index.groups[FrameKind.EFFORT])

    def cycle_bits(self) -> dict[str, int]:
        """Worst-case wire bits of one cycle of each frame family (see `frame_bits_worst_case`)."""
        return cycle_bits((f.kind, f.message.length) for f in self._index.frames.values())

    def bus_load(self, command_rate: float, bitrate: float = DEFAULT_BITRATE) -> float:
        """Worst-case bus load [%]: target frames at ``command_rate`` [Hz], the manager's
        frames at their cycle times (`cycle_period`); sporadic control frames not counted."""
        bits = self.cycle_bits()
        rates = {k: 1.0 / self.cycle_period(k) for k in bits if k not in ("control", "target")}
        return load_percent(bits, {**rates, "target": float(command_rate)}, bitrate)

    # ---- joint <-> axis --------------------------------------------------------------------

    def to_axis(self, joint_positions: Sequence[float]) -> np.ndarray:
        """Axis positions in axis order (index = axis) of joint angles in joint order [rad]."""
        return self._joints.to_axis(self._joints.vector(joint_positions, "joint positions"))

    def to_joint(self, axis_positions: Sequence[float]) -> np.ndarray:
        """Joint angles in joint order of axis positions in axis order [rad]."""
        return self._joints.to_joint(self._joints.vector(axis_positions, "axis positions"))

    def effort_to_axis(self, joint_efforts: Sequence[float]) -> np.ndarray:
        """Axis efforts in axis order of joint torques in joint order [N m]."""
        return self._joints.effort_to_axis(self._joints.vector(joint_efforts, "joint efforts",
                                                               unit="N m"))

    def effort_to_joint(self, axis_efforts: Sequence[float]) -> np.ndarray:
        """Joint torques in joint order of axis efforts in axis order [N m]."""
        return self._joints.effort_to_joint(self._joints.vector(axis_efforts, "axis efforts",
                                                                unit="N m"))

    # ---- frames ----------------------------------------------------------------------------

    def encode_targets(self, positions_rad: Sequence[float], counter: int) -> list[can.Message]:
        """Target frames (one per group) of 12 joint angles in joint order [rad].

        ``counter`` is any int >= 0, sent modulo the Counter field (16 by default). Raises
        `ProtocolEncodeError` for NaN/inf, an angle outside the joint limits or beyond the DBC
        range.
        """
        q = self._joints.vector(positions_rad, "target positions", ProtocolEncodeError)
        return self._codec.encode_targets(q, counter)

    def encode_feedback(self, axis_positions: Sequence[float],
                        counter: int) -> list[can.Message]:
        """Position frames of measured axis positions in axis order and axis space [rad].

        The inverse of decoding `PositionFeedback`, for the simulated manager. Positions more
        than ``feedback_margin`` outside the joint limits raise `ProtocolEncodeError`.
        """
        a = self._joints.vector(axis_positions, "measured axis positions", ProtocolEncodeError)
        return self._codec.encode_feedback(a, counter)

    def encode_efforts(self, axis_efforts: Sequence[float], counter: int) -> list[can.Message]:
        """Effort frames of measured axis efforts in axis order and axis space [N m], for the
        simulated manager; an empty list when the DBC has no effort frames. NaN/inf or a value
        beyond the DBC range raises `ProtocolEncodeError` (never clipped)."""
        e = self._joints.vector(axis_efforts, "measured axis efforts", ProtocolEncodeError,
                                unit="N m")
        return self._codec.encode_efforts(e, counter)

    def encode_status(self, flags: Sequence[AxisFlags], counter: int) -> list[can.Message]:
        """Status frames of one `AxisFlags` per axis, in axis order."""
        return self._codec.encode_status(flags, counter)

    def encode_control(self, command: str) -> can.Message:
        """The MM_Control frame of a command (one of `commands`)."""
        return self._codec.encode_control(command)

    def encode_heartbeat(self, state: str, counter: int) -> can.Message:
        """The MM_Heartbeat frame of a manager state (one of `states`) and counter (wraps)."""
        return self._codec.encode_heartbeat(state, counter)

    def decode(self, msg: can.Message) -> Decoded:
        """Decode and validate one received frame; `ProtocolDecodeError` if it is not valid.

        Refused: error/remote/extended/FD frames, unknown ids, a DLC other than the DBC's, set
        reserved bits, a wrong checksum, values beyond the DBC range, unknown enum values, and
        positions beyond the joint limits (targets: + half a resolution step; measured
        positions: + ``feedback_margin``).
        """
        return self._codec.decode(msg)
