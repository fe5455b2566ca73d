"""The CAN protocol of the multi-axis motor manager, as data (no ROS here).

The frames are described in ``config/motor_manager.dbc`` (loaded with cantools, strict) and the
joint-to-axis map in ``config/axes.yaml``. Frames carry *axis* positions on the axis output side,

    axis_position = direction * joint_angle + zero_offset        [rad]

while the rest of the package works in joint space (joint order of
`crawler_motion.model.config.joint_names`). `MotorProtocol` converts between the two, encodes and
decodes every frame, and refuses rather than clips: a NaN, an angle outside the joint limits or
a value beyond the DBC scaling raises `ProtocolError` with what was wrong and what is allowed.

The code finds frames and signals by name, so ids, grouping, scaling and ranges can be changed
in the DBC without touching it: ``MM_Control`` (Command, CommandInv), ``MM_Target_<g>``
(``Axis<n>_Target``, Counter, Checksum), ``MM_Position_<g>`` (``Axis<n>_Position``, Counter,
Checksum), ``MM_Status_<g>`` (``Axis<n>_<Flag>``, Counter, Checksum) and ``MM_Heartbeat``
(State, Counter). ``Checksum`` is optional; where present it is one byte-aligned byte holding a
CRC-8/SAE-J1850 over the frame id (2 bytes, little-endian) and every other data byte.
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import cantools
import numpy as np
import yaml

from crawler_motion.errors import ProtocolError
from crawler_motion.model.config import config_path

#: Default tolerance on measured positions beyond the joint limits [rad]: a powered-down or
#: loaded joint may sit slightly outside its commanded range (the zero pose puts the knee 0.1 rad
#: below its lower limit); feedback further out than this is taken as corrupt.
DEFAULT_FEEDBACK_MARGIN = 0.2

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

AXIS_KEYS: tuple[str, ...] = ("axis", "direction", "zero_offset", "gear_ratio")

_FAMILIES = {"target": "Target", "position": "Position", "status": "Status"}
#: Frame families the controller (the driver) sends; the manager sends the others.
CONTROLLER_KINDS = frozenset({"control", "target"})


def _crc8_table(poly: int) -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


_CRC8_J1850 = _crc8_table(0x1D)


def crc8_sae_j1850(data: bytes) -> int:
    """CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, xorout 0xFF); ``b"123456789"`` gives 0x4B."""
    crc = 0xFF
    table = _CRC8_J1850
    for byte in data:
        crc = table[crc ^ byte]
    return crc ^ 0xFF


def frame_bits_worst_case(data_bytes: int, extended: bool = False) -> int:
    """Bits on the wire of one classic CAN data frame with worst-case bit stuffing.

    Includes the 3-bit interframe space (Davis, Burns, Bril, Lukkien 2007):
    ``8n + g + 13 + floor((g + 8n - 1) / 4)`` with g = 34 for an 11-bit id, 54 for a 29-bit id.
    Eight data bytes and an 11-bit id give 135 bits, i.e. 135 us at 1 Mbit/s.
    """
    n = operator.index(data_bytes)
    if not 0 <= n <= 8:
        raise ProtocolError(f"a classic CAN frame carries 0..8 data bytes, got {n}")
    g = 54 if extended else 34
    return 8 * n + g + 13 + (g + 8 * n - 1) // 4


# --------------------------------------------------------------------------------------------
# Axis map
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AxisMapping:
    """Where one joint sits on the manager: ``axis = direction * joint + zero_offset`` [rad]."""

    joint: str
    axis: int  # manager axis index 0..n-1
    direction: int  # +1 or -1
    zero_offset: float  # axis position at joint angle 0 [rad]
    gear_ratio: float  # motor turns per output turn (> 0); not part of the encoding

    def to_axis(self, joint_rad: float) -> float:
        """Axis position [rad] of a joint angle [rad]."""
        return self.direction * joint_rad + self.zero_offset

    def to_joint(self, axis_rad: float) -> float:
        """Joint angle [rad] of an axis position [rad]."""
        return (axis_rad - self.zero_offset) * self.direction + 0.0  # no -0.0


class _UniqueKeyLoader(yaml.SafeLoader):
    """A YAML safe loader that refuses duplicate keys instead of keeping the last one."""


def _construct_unique_mapping(loader: _UniqueKeyLoader, node: yaml.MappingNode) -> dict:
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in seen:
            raise ProtocolError(f"duplicate key {key!r} (line {key_node.start_mark.line + 1}); "
                                f"each joint and each field may appear only once")
        seen.add(key)
    return loader.construct_mapping(node, deep=True)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
                                 _construct_unique_mapping)


def _is_number(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float))


def parse_axis_map(data: Any, joint_names: Sequence[str],
                   where: str = "axes") -> tuple[AxisMapping, ...]:
    """Validate a ``{joint: {axis, direction, zero_offset, gear_ratio}}`` mapping.

    Returns one `AxisMapping` per joint in ``joint_names`` order. Every joint must appear once
    and the axes must be exactly ``0..len(joint_names) - 1``, each used once.
    """
    names = tuple(joint_names)
    n = len(names)
    if not isinstance(data, Mapping):
        raise ProtocolError(f"{where} must be a mapping joint name -> "
                            f"{{axis, direction, zero_offset, gear_ratio}}, got {data!r}")
    missing = [j for j in names if j not in data]
    extra = [str(j) for j in data if j not in names]
    if missing or extra:
        raise ProtocolError(f"{where}: the axis map must name exactly the {n} joints {list(names)}"
                            f"; missing {missing}, unknown {extra}")
    result = []
    owner: dict[int, str] = {}
    for joint in names:
        entry = data[joint]
        here = f"{where}.{joint}"
        if not isinstance(entry, Mapping):
            raise ProtocolError(f"{here} must be a mapping {{axis, direction, zero_offset, "
                                f"gear_ratio}}, got {entry!r}")
        unknown = sorted(str(k) for k in entry if k not in AXIS_KEYS)
        absent = [k for k in AXIS_KEYS if k not in entry]
        if unknown or absent:
            raise ProtocolError(f"{here}: needs exactly the keys {list(AXIS_KEYS)}; "
                                f"missing {absent}, unknown {unknown}")
        axis = entry["axis"]
        if isinstance(axis, bool) or not isinstance(axis, int) or not 0 <= axis < n:
            raise ProtocolError(f"{here}.axis must be an integer 0..{n - 1}, got {axis!r}")
        if axis in owner:
            raise ProtocolError(f"{where}: axis {axis} is used by both {owner[axis]} and {joint}; "
                                f"each axis 0..{n - 1} must be used exactly once")
        owner[axis] = joint
        direction = entry["direction"]
        if not _is_number(direction) or direction not in (1, -1):
            raise ProtocolError(f"{here}.direction must be +1 or -1, got {direction!r}")
        offset = entry["zero_offset"]
        if not _is_number(offset) or not math.isfinite(offset):
            raise ProtocolError(f"{here}.zero_offset must be a finite angle in rad, "
                                f"got {offset!r}")
        gear = entry["gear_ratio"]
        if not _is_number(gear) or not math.isfinite(gear) or gear <= 0:
            raise ProtocolError(f"{here}.gear_ratio must be a finite number > 0, got {gear!r}")
        result.append(AxisMapping(joint=joint, axis=axis, direction=int(direction),
                                  zero_offset=float(offset), gear_ratio=float(gear)))
    return tuple(result)


def load_axis_map(path: str | Path, joint_names: Sequence[str]) -> tuple[AxisMapping, ...]:
    """Load and validate an axes YAML file (a top-level ``axes:`` mapping)."""
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as exc:
        raise ProtocolError(f"cannot read axis map {file}: {exc.strerror}") from exc
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)
    except ProtocolError as exc:
        raise ProtocolError(f"axis map {file}: {exc}") from exc
    except yaml.YAMLError as exc:
        raise ProtocolError(f"axis map {file} is not valid YAML: {exc}") from exc
    if not isinstance(data, Mapping) or "axes" not in data:
        raise ProtocolError(f"axis map {file} must hold a top-level 'axes:' mapping "
                            f"joint name -> {{axis, direction, zero_offset, gear_ratio}}")
    return parse_axis_map(data["axes"], joint_names, where=f"{file}: axes")


# --------------------------------------------------------------------------------------------
# Decoded frames
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TargetFrame:
    """One target frame: joint ``positions`` [rad, joint space] and ``axes`` [rad, axis space]."""

    group: int
    counter: int
    positions: dict[str, float]
    axes: dict[int, float]


@dataclass(frozen=True)
class ControlFrame:
    """A manager command: one of ``MotorProtocol.commands``."""

    command: str


@dataclass(frozen=True)
class PositionFeedback:
    """Measured positions of one group: ``positions`` [rad, joint space], ``axes`` [rad, axis]."""

    group: int
    counter: int
    positions: dict[str, float]
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
Decoded = TargetFrame | ControlFrame | PositionFeedback | AxisStatus | Heartbeat


# --------------------------------------------------------------------------------------------
# Protocol
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Frame:
    """What the code needs to know about one DBC message."""

    message: Any  # cantools Message
    kind: str  # control | target | position | status | heartbeat
    group: int
    axis_signals: tuple[tuple[int, str], ...]  # (axis, signal) for target/position
    flag_signals: tuple[tuple[int, tuple[str, ...]], ...]  # status: (axis, signals in FLAG order)
    counter_bits: int
    checksum_byte: int | None
    used_mask: int


def _as_int(value: Any, what: str) -> int:
    if isinstance(value, bool):
        raise ProtocolError(f"{what} must be an integer, got {value!r}")
    try:
        number = operator.index(value)
    except TypeError:
        raise ProtocolError(f"{what} must be an integer, got {value!r}") from None
    if number < 0:
        raise ProtocolError(f"{what} must be >= 0 (it wraps modulo the field size), got {number}")
    return number


class MotorProtocol:
    """Encoder/decoder of the motor-manager frames for one robot.

    ``joint_names`` fixes the joint order of every position vector; ``lower``/``upper`` are the
    joint limits in that order [rad]. ``feedback_margin`` [rad] is how far beyond the limits a
    measured position may be before the frame is refused as corrupt.
    """

    def __init__(self, dbc_path: str | Path, axes_path: str | Path, joint_names: Sequence[str],
                 lower: Sequence[float], upper: Sequence[float], *,
                 feedback_margin: float = DEFAULT_FEEDBACK_MARGIN) -> None:
        self._joint_names = tuple(joint_names)
        n = len(self._joint_names)
        if n == 0 or len(set(self._joint_names)) != n:
            raise ProtocolError(f"joint names must be distinct and non-empty, "
                                f"got {list(self._joint_names)}")
        self._lower = np.asarray(lower, dtype=float).reshape(-1)
        self._upper = np.asarray(upper, dtype=float).reshape(-1)
        if self._lower.shape != (n,) or self._upper.shape != (n,):
            raise ProtocolError(f"joint limits must hold {n} values each, got "
                                f"{self._lower.size} lower and {self._upper.size} upper")
        if not (np.all(np.isfinite(self._lower)) and np.all(np.isfinite(self._upper))
                and np.all(self._lower < self._upper)):
            raise ProtocolError("joint limits must be finite with lower < upper")
        if not (math.isfinite(feedback_margin) and feedback_margin >= 0):
            raise ProtocolError(f"feedback_margin must be a finite angle >= 0 rad, "
                                f"got {feedback_margin!r}")
        self.feedback_margin = float(feedback_margin)
        self._axis_map = load_axis_map(axes_path, self._joint_names)
        self._by_axis = {m.axis: m for m in self._axis_map}
        self._joint_index = {m.joint: i for i, m in enumerate(self._axis_map)}
        self._axis_order = np.array([m.axis for m in self._axis_map])
        self._direction = np.array([m.direction for m in self._axis_map], dtype=float)
        self._offset = np.array([m.zero_offset for m in self._axis_map])
        self.dbc_path = Path(dbc_path)
        try:
            self._db = cantools.database.load_file(str(dbc_path), strict=True)
        except FileNotFoundError as exc:
            raise ProtocolError(f"cannot read DBC file {dbc_path}: {exc.strerror}") from exc
        except Exception as exc:
            raise ProtocolError(f"DBC file {dbc_path} is invalid: {exc}") from exc
        self._frames: dict[int, _Frame] = {}
        self._groups: dict[str, list[_Frame]] = {k: [] for k in _FAMILIES}
        self._index_dbc(n)
        self._resolution = max(float(f.message.get_signal_by_name(name).scale)
                               for kind in ("target", "position") for f in self._groups[kind]
                               for _, name in f.axis_signals)
        self._check_signal_ranges()

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

    # ---- DBC indexing ----------------------------------------------------------------------

    def _bad(self, what: str) -> ProtocolError:
        return ProtocolError(f"DBC file {self.dbc_path}: {what}")

    def _index_dbc(self, n: int) -> None:
        names = {m.name: m for m in self._db.messages}
        for name in ("MM_Control", "MM_Heartbeat"):
            if name not in names:
                raise self._bad(f"missing message {name}")
        for message in self._db.messages:
            if message.is_extended_frame or message.is_fd or message.is_container:
                raise self._bad(f"{message.name} must be a classic CAN frame with an 11-bit id")
            if message.length > 8:
                raise self._bad(f"{message.name} has {message.length} bytes, at most 8 allowed")
            used = 0
            for signal in message.signals:
                if signal.byte_order != "little_endian" or signal.multiplexer_ids:
                    raise self._bad(f"{message.name}.{signal.name} must be a little-endian, "
                                    f"non-multiplexed signal")
                used |= ((1 << signal.length) - 1) << signal.start
            if message.name == "MM_Control":
                self._add(message, "control", 0, used, ("Command", "CommandInv"))
            elif message.name == "MM_Heartbeat":
                self._add(message, "heartbeat", 0, used, ("State", "Counter"))
            else:
                match = re.fullmatch(r"MM_(Target|Position|Status)_(\d+)", message.name)
                if match is None:
                    raise self._bad(f"unexpected message {message.name}; expected MM_Control, "
                                    f"MM_Heartbeat, MM_Target_<g>, MM_Position_<g>, "
                                    f"MM_Status_<g>")
                kind = match.group(1).lower()
                self._add(message, kind, int(match.group(2)), used, ())
        for kind, suffix in _FAMILIES.items():
            frames = self._groups[kind]
            axes = sorted(a for f in frames for a, _ in (f.axis_signals or f.flag_signals))
            if axes != list(range(n)):
                raise self._bad(f"the MM_{suffix}_<g> frames must carry each axis 0..{n - 1} "
                                f"exactly once, they carry {axes}")
            frames.sort(key=lambda f: f.group)

    def _add(self, message: Any, kind: str, group: int, used: int,
             required: tuple[str, ...]) -> None:
        signals = {s.name: s for s in message.signals}
        for name in required:
            if name not in signals:
                raise self._bad(f"{message.name} lacks the signal {name}")
        axis_signals: list[tuple[int, str]] = []
        flags: dict[int, dict[str, str]] = {}
        suffix = _FAMILIES.get(kind, "")
        counter_bits = signals["Counter"].length if "Counter" in signals else 0
        checksum_byte = None
        for name, signal in signals.items():
            if name in required:
                continue
            if kind in _FAMILIES and name == "Counter":
                continue
            if kind in _FAMILIES and name == "Checksum":
                if signal.length != 8 or signal.start % 8 or signal.is_signed:
                    raise self._bad(f"{message.name}.Checksum must be one unsigned, "
                                    f"byte-aligned byte")
                checksum_byte = signal.start // 8
                continue
            match = re.fullmatch(r"Axis(\d+)_(\w+)", name)
            if kind in ("target", "position") and match and match.group(2) == suffix:
                axis_signals.append((int(match.group(1)), name))
            elif (kind == "status" and match
                    and match.group(2) in FLAG_SIGNALS.values()):
                flags.setdefault(int(match.group(1)), {})[match.group(2)] = name
            else:
                raise self._bad(f"unexpected signal {name} in {message.name}")
        if kind in _FAMILIES and not counter_bits:
            raise self._bad(f"{message.name} lacks the signal Counter")
        flag_signals = []
        for axis, found in sorted(flags.items()):
            missing = [s for s in FLAG_SIGNALS.values() if s not in found]
            if missing:
                raise self._bad(f"{message.name}: axis {axis} lacks the flags {missing}")
            flag_signals.append((axis, tuple(found[s] for s in FLAG_SIGNALS.values())))
        frame = _Frame(message=message, kind=kind, group=group,
                       axis_signals=tuple(sorted(axis_signals)),
                       flag_signals=tuple(flag_signals), counter_bits=counter_bits,
                       checksum_byte=checksum_byte, used_mask=used)
        self._frames[message.frame_id] = frame
        if kind in self._groups:
            self._groups[kind].append(frame)

    def _check_signal_ranges(self) -> None:
        """Fail early when a joint's limit range does not fit its axis signal range."""
        for kind in ("target", "position"):
            for frame in self._groups[kind]:
                for axis, name in frame.axis_signals:
                    signal = frame.message.get_signal_by_name(name)
                    m = self._by_axis[axis]
                    i = self._joint_index[m.joint]
                    ends = sorted((m.to_axis(self._lower[i]), m.to_axis(self._upper[i])))
                    if ends[0] < signal.minimum or ends[1] > signal.maximum:
                        raise ProtocolError(
                            f"{m.joint} limits [{self._lower[i]}, {self._upper[i]}] rad map to "
                            f"axis {axis} positions [{ends[0]:.6g}, {ends[1]:.6g}] rad, beyond "
                            f"{name}'s range [{signal.minimum}, {signal.maximum}] rad in "
                            f"{self.dbc_path}; fix zero_offset in the axis map or the DBC range")

    # ---- properties ------------------------------------------------------------------------

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in the order of every joint-space vector."""
        return self._joint_names

    @property
    def n_axes(self) -> int:
        """Number of axes (= number of joints)."""
        return len(self._joint_names)

    @property
    def axis_map(self) -> tuple[AxisMapping, ...]:
        """The joint-to-axis map, in joint order."""
        return self._axis_map

    @property
    def lower(self) -> np.ndarray:
        """Lower joint limits in joint order [rad] (a copy)."""
        return self._lower.copy()

    @property
    def upper(self) -> np.ndarray:
        """Upper joint limits in joint order [rad] (a copy)."""
        return self._upper.copy()

    @property
    def database(self) -> Any:
        """The loaded cantools database."""
        return self._db

    @property
    def resolution_rad(self) -> float:
        """Coarsest position step of the target/position signals [rad] (0.0001 by default)."""
        return self._resolution

    @property
    def commands(self) -> tuple[str, ...]:
        """Command names accepted by `encode_control` (the DBC's MM_Control.Command choices)."""
        return tuple(str(v) for v in self._choices("MM_Control", "Command").values())

    @property
    def states(self) -> tuple[str, ...]:
        """Manager state names of the heartbeat (the DBC's MM_Heartbeat.State choices)."""
        return tuple(str(v) for v in self._choices("MM_Heartbeat", "State").values())

    def _choices(self, message: str, signal: str) -> Mapping[int, Any]:
        choices = self._db.get_message_by_name(message).get_signal_by_name(signal).choices
        return choices or {}

    def period(self, kind: str) -> float | None:
        """Cycle time of a frame family from the DBC's GenMsgCycleTime [s], None if unset.

        ``kind`` is one of ``target``, ``position``, ``status``, ``heartbeat``.
        """
        if kind == "heartbeat":
            cycle = self._db.get_message_by_name("MM_Heartbeat").cycle_time
        elif kind in self._groups:
            cycle = self._groups[kind][0].message.cycle_time
        else:
            raise ProtocolError(f"unknown frame family {kind!r}; expected target, position, "
                                f"status or heartbeat")
        return cycle / 1000.0 if cycle else None

    def sender(self, msg: Any) -> str | None:
        """Which side sends the (standard 11-bit) id of ``msg``: ``"controller"`` (control and
        target frames), ``"manager"`` (feedback), or None (unknown or extended id, not a
        frame). Lets each side skip its own frames, looped back on udp_multicast, undecoded."""
        if getattr(msg, "is_extended_id", True):
            return None
        frame = self._frames.get(getattr(msg, "arbitration_id", None))
        if frame is None:
            return None
        return "controller" if frame.kind in CONTROLLER_KINDS else "manager"

    def frame_ids(self, kind: str) -> tuple[int, ...]:
        """Arbitration ids of a frame family (``control``, ``target``, ``position``, ...)."""
        return tuple(fid for fid, f in self._frames.items() if f.kind == kind)

    def cycle_bits(self) -> dict[str, int]:
        """Worst-case wire bits of one cycle of each frame family (see `frame_bits_worst_case`)."""
        bits: dict[str, int] = {}
        for frame in self._frames.values():
            bits[frame.kind] = bits.get(frame.kind, 0) + frame_bits_worst_case(
                frame.message.length)
        return bits

    # ---- joint <-> axis --------------------------------------------------------------------

    def _vector(self, values: Any, what: str) -> np.ndarray:
        try:
            arr = np.asarray(values, dtype=float).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise ProtocolError(f"{what} must be {self.n_axes} numbers [rad]: {exc}") from None
        if arr.shape != (self.n_axes,):
            raise ProtocolError(f"{what} must hold {self.n_axes} values [rad], got {arr.size}")
        return arr

    def to_axis(self, joint_positions: Sequence[float]) -> np.ndarray:
        """Axis positions in axis order (index = axis) of joint angles in joint order [rad]."""
        q = self._vector(joint_positions, "joint positions")
        out = np.empty(self.n_axes)
        out[self._axis_order] = self._direction * q + self._offset
        return out

    def to_joint(self, axis_positions: Sequence[float]) -> np.ndarray:
        """Joint angles in joint order of axis positions in axis order [rad]."""
        a = self._vector(axis_positions, "axis positions")
        return (a[self._axis_order] - self._offset) * self._direction + 0.0  # no -0.0

    # ---- encoding --------------------------------------------------------------------------

    def _message(self, frame: _Frame, values: dict[str, Any]) -> can.Message:
        message = frame.message
        if frame.checksum_byte is not None:
            values["Checksum"] = 0
        try:
            data = bytearray(message.encode(values, scaling=True, padding=False, strict=True))
        except Exception as exc:
            raise ProtocolError(self._encode_failure(frame, values, exc)) from exc
        if frame.checksum_byte is not None:
            data[frame.checksum_byte] = self._checksum(message.frame_id, data,
                                                       frame.checksum_byte)
        return can.Message(arbitration_id=message.frame_id, data=bytes(data),
                           is_extended_id=False, dlc=len(data))

    def _encode_failure(self, frame: _Frame, values: dict[str, Any], exc: Exception) -> str:
        for axis, name in frame.axis_signals:
            signal = frame.message.get_signal_by_name(name)
            value = values[name]
            tol = abs(signal.scale) * 1e-6
            if not (signal.minimum - tol <= value <= signal.maximum + tol):
                m = self._by_axis[axis]
                return (f"{m.joint} (axis {axis}): axis position {value:.6g} rad is beyond "
                        f"{name}'s range [{signal.minimum}, {signal.maximum}] rad of "
                        f"{frame.message.name} (direction {m.direction}, zero_offset "
                        f"{m.zero_offset} rad); values are never clipped")
        return f"cannot encode {frame.message.name}: {exc}"

    @staticmethod
    def _checksum(frame_id: int, data: bytes | bytearray, skip: int) -> int:
        body = bytes(data[:skip]) + bytes(data[skip + 1:])
        return crc8_sae_j1850(frame_id.to_bytes(2, "little") + body)

    def _check_joint_range(self, q: np.ndarray, what: str, margin: float) -> None:
        for i, value in enumerate(q):
            lo, hi = self._lower[i], self._upper[i]
            if not math.isfinite(value):
                raise ProtocolError(f"{what} of {self._joint_names[i]} is {value}; it must be a "
                                    f"finite angle within [{lo}, {hi}] rad")
            if not lo - margin <= value <= hi + margin:
                allowed = f"[{lo}, {hi}] rad" + (f" (+- {margin:g} rad)" if margin else "")
                raise ProtocolError(f"{what} of {self._joint_names[i]} is {value:.6g} rad, "
                                    f"outside its limits {allowed}; values are never clipped")

    def encode_targets(self, positions_rad: Sequence[float], counter: int) -> list[can.Message]:
        """Target frames (one per group) of 12 joint angles in joint order [rad].

        ``counter`` is any int >= 0, sent modulo the Counter field (16 by default). Raises
        `ProtocolError` for NaN/inf, an angle outside the joint limits or beyond the DBC range.
        """
        q = self._vector(positions_rad, "target positions")
        self._check_joint_range(q, "target", 0.0)
        return self._encode_axes("target", self.to_axis(q), counter)

    def encode_feedback(self, axis_positions: Sequence[float],
                        counter: int) -> list[can.Message]:
        """Position frames of measured axis positions in axis order and axis space [rad].

        The inverse of decoding `PositionFeedback`, for the simulated manager. Positions more
        than ``feedback_margin`` outside the joint limits raise `ProtocolError`.
        """
        a = self._vector(axis_positions, "measured axis positions")
        self._check_joint_range(self.to_joint(a), "measured position", self.feedback_margin)
        return self._encode_axes("position", a, counter)

    def _encode_axes(self, kind: str, a: np.ndarray, counter: int) -> list[can.Message]:
        count = _as_int(counter, "counter")
        messages = []
        for frame in self._groups[kind]:
            values: dict[str, Any] = {name: float(a[axis]) for axis, name in frame.axis_signals}
            values["Counter"] = count % (1 << frame.counter_bits)
            messages.append(self._message(frame, values))
        return messages

    def encode_status(self, flags: Sequence[AxisFlags], counter: int) -> list[can.Message]:
        """Status frames of one `AxisFlags` per axis, in axis order."""
        if len(flags) != self.n_axes or not all(isinstance(f, AxisFlags) for f in flags):
            raise ProtocolError(f"status needs {self.n_axes} AxisFlags in axis order")
        count = _as_int(counter, "counter")
        messages = []
        for frame in self._groups["status"]:
            values: dict[str, Any] = {"Counter": count % (1 << frame.counter_bits)}
            for axis, names in frame.flag_signals:
                for attr, name in zip(FLAG_SIGNALS, names, strict=True):
                    values[name] = int(getattr(flags[axis], attr))
            messages.append(self._message(frame, values))
        return messages

    def _choice_number(self, message: str, signal: str, name: str, what: str) -> int:
        for number, choice in self._choices(message, signal).items():
            if str(choice) == name:
                return int(number)
        allowed = [str(v) for v in self._choices(message, signal).values()]
        raise ProtocolError(f"unknown {what} {name!r}; expected one of {allowed}")

    def encode_control(self, command: str) -> can.Message:
        """The MM_Control frame of a command (one of `commands`)."""
        number = self._choice_number("MM_Control", "Command", str(command), "command")
        frame = self._frames[self._db.get_message_by_name("MM_Control").frame_id]
        return self._message(frame, {"Command": number, "CommandInv": number ^ 0xFF})

    def encode_heartbeat(self, state: str, counter: int) -> can.Message:
        """The MM_Heartbeat frame of a manager state (one of `states`) and counter (wraps)."""
        number = self._choice_number("MM_Heartbeat", "State", str(state), "manager state")
        message = self._db.get_message_by_name("MM_Heartbeat")
        bits = message.get_signal_by_name("Counter").length
        count = _as_int(counter, "counter") % (1 << bits)
        return self._message(self._frames[message.frame_id], {"State": number, "Counter": count})

    # ---- decoding --------------------------------------------------------------------------

    def decode(self, msg: can.Message) -> Decoded:
        """Decode and validate one received frame; `ProtocolError` if it is not a valid one.

        Refused: error/remote/extended/FD frames, unknown ids, a DLC other than the DBC's, set
        reserved bits, a wrong checksum, values beyond the DBC range, unknown enum values, and
        positions beyond the joint limits (targets: + half a resolution step; measured
        positions: + ``feedback_margin``).
        """
        fid = msg.arbitration_id
        if msg.is_error_frame or msg.is_remote_frame:
            raise ProtocolError(f"frame 0x{fid:X} is an error or remote frame, not a data frame")
        if msg.is_extended_id or msg.is_fd:
            raise ProtocolError(f"frame 0x{fid:X} is an extended-id or CAN FD frame; the "
                                f"protocol uses classic frames with 11-bit ids")
        frame = self._frames.get(fid)
        if frame is None:
            known = ", ".join(f"0x{i:03X}" for i in sorted(self._frames))
            raise ProtocolError(f"unknown frame id 0x{fid:03X}; the protocol knows {known}")
        name = frame.message.name
        data = bytes(msg.data)
        if len(data) != frame.message.length:
            raise ProtocolError(f"{name} (0x{fid:03X}) must carry {frame.message.length} bytes, "
                                f"got {len(data)}")
        if int.from_bytes(data, "little") & ~frame.used_mask:
            raise ProtocolError(f"{name} (0x{fid:03X}) has reserved bits set: {data.hex()}")
        if frame.checksum_byte is not None:
            expected = self._checksum(fid, data, frame.checksum_byte)
            if data[frame.checksum_byte] != expected:
                raise ProtocolError(f"{name} (0x{fid:03X}) checksum 0x"
                                    f"{data[frame.checksum_byte]:02X} != 0x{expected:02X}")
        try:
            values = frame.message.decode(data, decode_choices=False, scaling=True,
                                          allow_truncated=False, allow_excess=False)
        except Exception as exc:
            raise ProtocolError(f"{name} (0x{fid:03X}) cannot be decoded: {exc}") from exc
        for signal in frame.message.signals:
            value = values[signal.name]
            tol = abs(signal.scale) * 1e-6
            if (signal.minimum is not None and value < signal.minimum - tol) or (
                    signal.maximum is not None and value > signal.maximum + tol):
                raise ProtocolError(f"{name}.{signal.name} = {value} is outside its range "
                                    f"[{signal.minimum}, {signal.maximum}] {signal.unit or ''}")
        return getattr(self, f"_decode_{frame.kind}")(frame, values)

    def _decode_control(self, frame: _Frame, values: Mapping[str, Any]) -> ControlFrame:
        number, check = int(values["Command"]), int(values["CommandInv"])
        if check != number ^ 0xFF:
            raise ProtocolError(f"MM_Control: CommandInv 0x{check:02X} is not the complement "
                                f"of Command 0x{number:02X}")
        command = self._choices("MM_Control", "Command").get(number)
        if command is None:
            raise ProtocolError(f"MM_Control: unknown command number {number}")
        return ControlFrame(command=str(command))

    def _decode_heartbeat(self, frame: _Frame, values: Mapping[str, Any]) -> Heartbeat:
        state = self._choices("MM_Heartbeat", "State").get(int(values["State"]))
        if state is None:
            raise ProtocolError(f"MM_Heartbeat: unknown state number {values['State']}")
        return Heartbeat(state=str(state), counter=int(values["Counter"]))

    def _decode_positions(self, frame: _Frame, values: Mapping[str, Any],
                          margin: float) -> tuple[dict[str, float], dict[int, float]]:
        axes: dict[int, float] = {}
        joints: dict[str, float] = {}
        what = "target" if frame.kind == "target" else "measured position"
        for axis, name in frame.axis_signals:
            m = self._by_axis[axis]
            a = float(values[name])
            q = m.to_joint(a)
            i = self._joint_index[m.joint]
            if not self._lower[i] - margin <= q <= self._upper[i] + margin:
                raise ProtocolError(f"{frame.message.name}: {what} of {m.joint} (axis {axis}) is "
                                    f"{q:.6g} rad, outside its limits [{self._lower[i]}, "
                                    f"{self._upper[i]}] rad (+- {margin:g} rad)")
            axes[axis] = a
            joints[m.joint] = q
        return joints, axes

    def _decode_target(self, frame: _Frame, values: Mapping[str, Any]) -> TargetFrame:
        margin = 0.5 * self.resolution_rad * (1.0 + 1e-6)
        joints, axes = self._decode_positions(frame, values, margin)
        return TargetFrame(group=frame.group, counter=int(values["Counter"]), positions=joints,
                           axes=axes)

    def _decode_position(self, frame: _Frame, values: Mapping[str, Any]) -> PositionFeedback:
        joints, axes = self._decode_positions(frame, values, self.feedback_margin)
        return PositionFeedback(group=frame.group, counter=int(values["Counter"]),
                                positions=joints, axes=axes)

    def _decode_status(self, frame: _Frame, values: Mapping[str, Any]) -> AxisStatus:
        axes: dict[int, AxisFlags] = {}
        for axis, names in frame.flag_signals:
            axes[axis] = AxisFlags(**{attr: bool(values[name])
                                      for attr, name in zip(FLAG_SIGNALS, names, strict=True)})
        flags = {self._by_axis[axis].joint: f for axis, f in axes.items()}
        return AxisStatus(group=frame.group, counter=int(values["Counter"]), flags=flags,
                          axes=axes)
