"""Encoding and decoding of the motor-manager frames in joint space (refuses, never clips)."""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import can
import numpy as np

from crawler_motion.canbus.axes import JointSpace
from crawler_motion.canbus.crc import frame_checksum
from crawler_motion.canbus.dbc import DbcFrame, DbcIndex
from crawler_motion.canbus.frames import (
    FLAG_SIGNALS,
    AxisFlags,
    AxisStatus,
    ControlFrame,
    Decoded,
    EffortFeedback,
    FrameKind,
    Heartbeat,
    PositionFeedback,
    TargetFrame,
)
from crawler_motion.errors import ProtocolDecodeError, ProtocolEncodeError

#: Relative slack on a signal's range, in units of its scale: absorbs float rounding only.
RANGE_SLACK = 1e-6


def _counter(value: Any) -> int:
    """A frame counter: any int >= 0 (it wraps modulo the field size)."""
    if isinstance(value, bool):
        raise ProtocolEncodeError(f"counter must be an integer, got {value!r}",
                                  signal="Counter", value=value)
    try:
        number = operator.index(value)
    except TypeError:
        raise ProtocolEncodeError(f"counter must be an integer, got {value!r}",
                                  signal="Counter", value=value) from None
    if number < 0:
        raise ProtocolEncodeError(f"counter must be >= 0 (it wraps modulo the field size), "
                                  f"got {number}", signal="Counter", value=number)
    return number


def _bounds(signal: Any) -> tuple[float, float]:
    """The signal's DBC range widened by `RANGE_SLACK` (infinite where it is open)."""
    tol = abs(signal.scale) * RANGE_SLACK
    return (-math.inf if signal.minimum is None else signal.minimum - tol,
            math.inf if signal.maximum is None else signal.maximum + tol)


def _may_exceed(signal: Any) -> bool:
    """False when no value the signal's bits can hold lies beyond its (widened) DBC range,
    e.g. a 1-bit flag of range [0, 1]: decoded values of it need no range check."""
    if signal.conversion.is_float:
        return True
    bits = signal.length - (1 if signal.is_signed else 0)
    ends = [signal.conversion.raw_to_scaled(raw, False)
            for raw in ((-(1 << bits) if signal.is_signed else 0), (1 << bits) - 1)]
    low, high = _bounds(signal)
    return not all(low <= end <= high for end in ends)


def _range_checks(index: DbcIndex) -> dict[int, tuple[tuple[Any, float, float], ...]]:
    """Per frame id: (signal, lowest, highest value accepted) of each signal whose decoded
    values need a range check (`_may_exceed`)."""
    return {fid: tuple((signal, *_bounds(signal)) for signal in f.message.signals
                       if _may_exceed(signal))
            for fid, f in index.frames.items()}


def _in_range(signal: Any, value: float) -> bool:
    """True when ``value`` lies within the signal's DBC range (open ends allowed)."""
    low, high = _bounds(signal)
    return low <= value <= high


def _pack(frame: DbcFrame, values: dict[str, Any]) -> bytes:
    """The payload of signal ``values``: by the frame's compiled layout, else by cantools
    (strict: the same result, see `layout`)."""
    if frame.layout is not None:
        return frame.layout.pack(values)
    return frame.message.encode(values, scaling=True, padding=False, strict=True)


def _unpack_payload(frame: DbcFrame, data: bytes) -> dict[str, Any]:
    """The scaled signal values of a payload (no choices decoded), as `_pack` packs them."""
    if frame.layout is not None:
        return frame.layout.unpack(data)
    return frame.message.decode(data, decode_choices=False, scaling=True,
                                allow_truncated=False, allow_excess=False)


class FrameCodec:
    """Encoder/decoder of the frames of ``index`` for the joints of ``joints``.

    ``feedback_margin`` [rad] is how far beyond the joint limits a measured position may be
    before the frame is refused as corrupt.
    """

    def __init__(self, index: DbcIndex, joints: JointSpace, feedback_margin: float) -> None:
        self._index = index
        self._joints = joints
        self.feedback_margin = feedback_margin
        self._ranges = _range_checks(index)
        self._decoders: dict[FrameKind, Callable[[DbcFrame, Mapping[str, Any]], Decoded]] = {
            FrameKind.CONTROL: self._decode_control,
            FrameKind.HEARTBEAT: self._decode_heartbeat,
            FrameKind.TARGET: self._decode_target,
            FrameKind.POSITION: self._decode_position,
            FrameKind.EFFORT: self._decode_effort,
            FrameKind.STATUS: self._decode_status,
        }

    # ---- encoding --------------------------------------------------------------------------

    def _message(self, frame: DbcFrame, values: dict[str, Any]) -> can.Message:
        if frame.checksum_byte is not None:
            values["Checksum"] = 0
        try:
            data = bytearray(_pack(frame, values))
        except Exception as exc:
            raise self._encode_failure(frame, values, exc) from exc
        if frame.checksum_byte is not None:
            data[frame.checksum_byte] = frame_checksum(frame.frame_id, data, frame.checksum_byte)
        return can.Message(arbitration_id=frame.frame_id, data=bytes(data),
                           is_extended_id=False, dlc=len(data))

    def _encode_failure(self, frame: DbcFrame, values: dict[str, Any],
                        exc: Exception) -> ProtocolEncodeError:
        for axis, name in frame.axis_signals:
            signal = frame.message.get_signal_by_name(name)
            value = values[name]
            if not _in_range(signal, value):
                m = self._joints.by_axis[axis]
                what, unit, mapping = ("effort", "N m", "") if frame.kind == FrameKind.EFFORT \
                    else ("axis position", "rad", f" (direction {m.direction}, zero_offset "
                                                  f"{m.zero_offset} rad)")
                return ProtocolEncodeError(
                    f"{m.joint} (axis {axis}): {what} {value:.6g} {unit} is beyond {name}'s "
                    f"range [{signal.minimum}, {signal.maximum}] {unit} of {frame.name}"
                    f"{mapping}; values are never clipped", frame_id=frame.frame_id,
                    signal=name, joint=m.joint, value=value)
        return ProtocolEncodeError(f"cannot encode {frame.name}: {exc}", frame_id=frame.frame_id)

    def _check_joint_range(self, q: np.ndarray, what: str, margin: float) -> None:
        joints = self._joints
        ok = (q >= joints.lower - margin) & (q <= joints.upper + margin)  # NaN: not ok
        for i in np.flatnonzero(~ok)[:1]:  # the first joint out of its range
            value = float(q[i])
            joint, lo, hi = joints.joint_names[i], joints.lower[i], joints.upper[i]
            if not math.isfinite(value):
                message = (f"{what} of {joint} is {value}; it must be a finite angle within "
                           f"[{lo}, {hi}] rad")
            else:
                allowed = f"[{lo}, {hi}] rad" + (f" (+- {margin:g} rad)" if margin else "")
                message = (f"{what} of {joint} is {value:.6g} rad, outside its limits "
                           f"{allowed}; values are never clipped")
            raise ProtocolEncodeError(message, joint=joint, value=float(value))

    def encode_targets(self, q: np.ndarray, counter: int) -> list[can.Message]:
        """Target frames (one per group) of joint angles in joint order [rad]."""
        self._check_joint_range(q, "target", 0.0)
        return self._encode_axes(FrameKind.TARGET, self._joints.to_axis(q), counter)

    def encode_feedback(self, a: np.ndarray, counter: int) -> list[can.Message]:
        """Position frames of measured axis positions in axis order [rad]."""
        self._check_joint_range(self._joints.to_joint(a), "measured position",
                                self.feedback_margin)
        return self._encode_axes(FrameKind.POSITION, a, counter)

    def encode_efforts(self, e: np.ndarray, counter: int) -> list[can.Message]:
        """Effort frames of measured axis efforts in axis order [N m] (none when the DBC has
        no effort frames)."""
        bad = np.flatnonzero(~np.isfinite(e))
        if bad.size:
            m = self._joints.by_axis[int(bad[0])]
            raise ProtocolEncodeError(f"{m.joint} (axis {m.axis}): effort {e[bad[0]]} is not "
                                      f"finite; efforts must be finite torques [N m]",
                                      joint=m.joint, value=float(e[bad[0]]))
        return self._encode_axes(FrameKind.EFFORT, e, counter)

    def _encode_axes(self, kind: FrameKind, a: np.ndarray, counter: int) -> list[can.Message]:
        count = _counter(counter)
        messages = []
        for frame in self._index.groups[kind]:
            values: dict[str, Any] = {name: float(a[axis]) for axis, name in frame.axis_signals}
            values["Counter"] = count % (1 << frame.counter_bits)
            messages.append(self._message(frame, values))
        return messages

    def encode_status(self, flags: Sequence[AxisFlags], counter: int) -> list[can.Message]:
        """Status frames of one `AxisFlags` per axis, in axis order."""
        n = self._joints.n
        if len(flags) != n or not all(isinstance(f, AxisFlags) for f in flags):
            raise ProtocolEncodeError(f"status needs {n} AxisFlags in axis order")
        count = _counter(counter)
        messages = []
        for frame in self._index.groups[FrameKind.STATUS]:
            values: dict[str, Any] = {"Counter": count % (1 << frame.counter_bits)}
            for axis, names in frame.flag_signals:
                for attr, name in zip(FLAG_SIGNALS, names, strict=True):
                    values[name] = int(getattr(flags[axis], attr))
            messages.append(self._message(frame, values))
        return messages

    def _choice_number(self, kind: FrameKind, signal: str, name: str, what: str) -> int:
        choices = self._index.choices(kind, signal)
        for number, choice in choices.items():
            if str(choice) == name:
                return int(number)
        allowed = [str(v) for v in choices.values()]
        raise ProtocolEncodeError(f"unknown {what} {name!r}; expected one of {allowed}",
                                  frame_id=self._index.single(kind).frame_id, signal=signal,
                                  value=name)

    def encode_control(self, command: str) -> can.Message:
        """The MM_Control frame of a command name."""
        number = self._choice_number(FrameKind.CONTROL, "Command", str(command), "command")
        return self._message(self._index.single(FrameKind.CONTROL),
                             {"Command": number, "CommandInv": number ^ 0xFF})

    def encode_heartbeat(self, state: str, counter: int) -> can.Message:
        """The MM_Heartbeat frame of a manager state name and counter (wraps)."""
        number = self._choice_number(FrameKind.HEARTBEAT, "State", str(state), "manager state")
        frame = self._index.single(FrameKind.HEARTBEAT)
        count = _counter(counter) % (1 << frame.counter_bits)
        return self._message(frame, {"State": number, "Counter": count})

    # ---- decoding --------------------------------------------------------------------------

    def decode(self, msg: can.Message) -> Decoded:
        """Decode and validate one received frame; `ProtocolDecodeError` if it is not valid."""
        frame, values = self._unpack(msg)
        return self._decoders[frame.kind](frame, values)

    def _unpack(self, msg: can.Message) -> tuple[DbcFrame, dict[str, Any]]:
        """The DBC frame and signal values of a raw frame, with every frame-level check."""
        fid = msg.arbitration_id

        def bad(message: str, **data: Any) -> ProtocolDecodeError:
            return ProtocolDecodeError(message, frame_id=fid, **data)

        if msg.is_error_frame or msg.is_remote_frame:
            raise bad(f"frame 0x{fid:X} is an error or remote frame, not a data frame")
        if msg.is_extended_id or msg.is_fd:
            raise bad(f"frame 0x{fid:X} is an extended-id or CAN FD frame; the protocol uses "
                      f"classic frames with 11-bit ids")
        frame = self._index.frames.get(fid)
        if frame is None:
            known = ", ".join(f"0x{i:03X}" for i in sorted(self._index.frames))
            raise bad(f"unknown frame id 0x{fid:03X}; the protocol knows {known}")
        where = f"{frame.name} (0x{fid:03X})"
        data = bytes(msg.data)
        if len(data) != frame.message.length:
            raise bad(f"{where} must carry {frame.message.length} bytes, got {len(data)}")
        if int.from_bytes(data, "little") & ~frame.used_mask:
            raise bad(f"{where} has reserved bits set: {data.hex()}")
        if frame.checksum_byte is not None:
            expected = frame_checksum(fid, data, frame.checksum_byte)
            got = data[frame.checksum_byte]
            if got != expected:
                raise bad(f"{where} checksum 0x{got:02X} != 0x{expected:02X}",
                          signal="Checksum", value=got)
        try:
            values = _unpack_payload(frame, data)
        except Exception as exc:
            raise bad(f"{where} cannot be decoded: {exc}") from exc
        for signal, low, high in self._ranges[fid]:
            value = values[signal.name]
            if not low <= value <= high:
                raise bad(f"{frame.name}.{signal.name} = {value} is outside its range "
                          f"[{signal.minimum}, {signal.maximum}] {signal.unit or ''}",
                          signal=signal.name, value=value)
        return frame, values

    def _decode_choice(self, frame: DbcFrame, signal: str, number: int, what: str) -> str:
        name = self._index.choices(frame.kind, signal).get(number)
        if name is None:
            raise ProtocolDecodeError(f"{frame.name}: unknown {what} number {number}",
                                      frame_id=frame.frame_id, signal=signal, value=number)
        return str(name)

    def _decode_control(self, frame: DbcFrame, values: Mapping[str, Any]) -> ControlFrame:
        number, check = int(values["Command"]), int(values["CommandInv"])
        if check != number ^ 0xFF:
            raise ProtocolDecodeError(f"MM_Control: CommandInv 0x{check:02X} is not the "
                                      f"complement of Command 0x{number:02X}",
                                      frame_id=frame.frame_id, signal="CommandInv", value=check)
        return ControlFrame(command=self._decode_choice(frame, "Command", number, "command"))

    def _decode_heartbeat(self, frame: DbcFrame, values: Mapping[str, Any]) -> Heartbeat:
        state = self._decode_choice(frame, "State", int(values["State"]), "state")
        return Heartbeat(state=state, counter=int(values["Counter"]))

    def _decode_positions(self, frame: DbcFrame, values: Mapping[str, Any],
                          margin: float) -> tuple[dict[str, float], dict[int, float]]:
        axes: dict[int, float] = {}
        joints: dict[str, float] = {}
        what = "target" if frame.kind == FrameKind.TARGET else "measured position"
        space = self._joints
        for axis, name in frame.axis_signals:
            m = space.by_axis[axis]
            a = float(values[name])
            q = m.to_joint(a)
            i = space.joint_index[m.joint]
            if not space.within(i, q, margin):
                raise ProtocolDecodeError(
                    f"{frame.name}: {what} of {m.joint} (axis {axis}) is {q:.6g} rad, outside "
                    f"its limits [{space.lower[i]}, {space.upper[i]}] rad (+- {margin:g} rad)",
                    frame_id=frame.frame_id, signal=name, joint=m.joint, value=q)
            axes[axis] = a
            joints[m.joint] = q
        return joints, axes

    def _decode_target(self, frame: DbcFrame, values: Mapping[str, Any]) -> TargetFrame:
        margin = 0.5 * self._index.resolution * (1.0 + RANGE_SLACK)
        joints, axes = self._decode_positions(frame, values, margin)
        return TargetFrame(group=frame.group, counter=int(values["Counter"]), positions=joints,
                           axes=axes)

    def _decode_position(self, frame: DbcFrame, values: Mapping[str, Any]) -> PositionFeedback:
        joints, axes = self._decode_positions(frame, values, self.feedback_margin)
        return PositionFeedback(group=frame.group, counter=int(values["Counter"]),
                                positions=joints, axes=axes)

    def _decode_effort(self, frame: DbcFrame, values: Mapping[str, Any]) -> EffortFeedback:
        axes = {axis: float(values[name]) for axis, name in frame.axis_signals}
        space = self._joints
        efforts = {space.by_axis[a].joint: space.by_axis[a].direction * v + 0.0  # no -0.0
                   for a, v in axes.items()}
        return EffortFeedback(group=frame.group, counter=int(values["Counter"]),
                              efforts=efforts, axes=axes)

    def _decode_status(self, frame: DbcFrame, values: Mapping[str, Any]) -> AxisStatus:
        axes: dict[int, AxisFlags] = {}
        for axis, names in frame.flag_signals:
            axes[axis] = AxisFlags(**{attr: bool(values[name])
                                      for attr, name in zip(FLAG_SIGNALS, names, strict=True)})
        flags = {self._joints.by_axis[axis].joint: f for axis, f in axes.items()}
        return AxisStatus(group=frame.group, counter=int(values["Counter"]), flags=flags,
                          axes=axes)
