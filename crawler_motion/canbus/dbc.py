"""Loading the motor-manager DBC (cantools, strict) and indexing and validating its frames."""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cantools

from crawler_motion.canbus.axes import JointSpace
from crawler_motion.canbus.frames import (
    AXIS_VALUE_KINDS,
    FLAG_SIGNALS,
    GROUPED,
    OPTIONAL_KINDS,
    POSITION_KINDS,
    FrameKind,
)
from crawler_motion.canbus.layout import FrameLayout, compile_layout
from crawler_motion.errors import ProtocolError, ProtocolParseError

#: Heartbeat period when the DBC gives MM_Heartbeat no cycle time [s].
DEFAULT_HEARTBEAT_PERIOD = 0.1
#: Cycle time of each frame family when the DBC gives none [s] (targets and feedback 100 Hz).
DEFAULT_PERIODS: dict[FrameKind, float] = {
    FrameKind.TARGET: 0.01, FrameKind.POSITION: 0.01, FrameKind.EFFORT: 0.01,
    FrameKind.STATUS: 0.01, FrameKind.HEARTBEAT: DEFAULT_HEARTBEAT_PERIOD,
}

_SINGLE: dict[str, tuple[FrameKind, tuple[str, ...]]] = {
    "MM_Control": (FrameKind.CONTROL, ("Command", "CommandInv")),
    "MM_Heartbeat": (FrameKind.HEARTBEAT, ("State", "Counter")),
}
_GROUPED_NAME = re.compile(r"MM_(Target|Position|Effort|Status)_(\d+)")
_AXIS_SIGNAL = re.compile(r"Axis(\d+)_(\w+)")


@dataclass(frozen=True)
class DbcFrame:
    """What the code needs to know about one DBC message."""

    message: Any  # cantools Message
    kind: FrameKind
    group: int
    axis_signals: tuple[tuple[int, str], ...]  # (axis, signal) for target/position/effort
    flag_signals: tuple[tuple[int, tuple[str, ...]], ...]  # status: (axis, signals in FLAG order)
    counter_bits: int
    checksum_byte: int | None
    used_mask: int  # every bit some signal covers; the rest are reserved (zero)
    layout: FrameLayout | None = None  # the compiled packing (None: cantools packs it)

    @property
    def name(self) -> str:
        """The DBC message name, e.g. ``MM_Target_0``."""
        return str(self.message.name)

    @property
    def frame_id(self) -> int:
        """The 11-bit arbitration id."""
        return int(self.message.frame_id)


class DbcIndex:
    """The frames of a motor-manager DBC by id and by family, validated for ``n_axes`` axes."""

    def __init__(self, path: str | Path, n_axes: int) -> None:
        self.path = Path(path)
        try:
            self.database = cantools.database.load_file(str(path), strict=True)
        except FileNotFoundError as exc:
            raise ProtocolParseError(f"cannot read DBC file {path}: {exc.strerror}",
                                     path=path) from exc
        except Exception as exc:
            raise ProtocolParseError(f"DBC file {path} is invalid: {exc}", path=path) from exc
        self.frames: dict[int, DbcFrame] = {}
        self.groups: dict[FrameKind, list[DbcFrame]] = {k: [] for k in GROUPED}
        self._index(n_axes)
        self.resolution = max(float(f.message.get_signal_by_name(name).scale)
                              for kind in POSITION_KINDS for f in self.groups[kind]
                              for _, name in f.axis_signals)

    def _bad(self, what: str) -> ProtocolParseError:
        return ProtocolParseError(f"DBC file {self.path}: {what}", path=self.path)

    def _index(self, n: int) -> None:
        names = {m.name for m in self.database.messages}
        for name in _SINGLE:
            if name not in names:
                raise self._bad(f"missing message {name}")
        for message in self.database.messages:
            used = self._used_bits(message)
            if message.name in _SINGLE:
                kind, required = _SINGLE[message.name]
                self._add(message, kind, 0, used, required)
                continue
            match = _GROUPED_NAME.fullmatch(message.name)
            if match is None:
                raise self._bad(f"unexpected message {message.name}; expected MM_Control, "
                                f"MM_Heartbeat, MM_Target_<g>, MM_Position_<g>, "
                                f"MM_Effort_<g>, MM_Status_<g>")
            self._add(message, FrameKind(match.group(1).lower()), int(match.group(2)), used, ())
        for kind, family in GROUPED.items():
            frames = self.groups[kind]
            axes = sorted(a for f in frames for a, _ in (f.axis_signals or f.flag_signals))
            if axes != list(range(n)) and (axes or kind not in OPTIONAL_KINDS):
                optional = " (or none at all)" if kind in OPTIONAL_KINDS else ""
                raise self._bad(f"the MM_{family}_<g> frames must carry each axis 0..{n - 1} "
                                f"exactly once{optional}, they carry {axes}")
            frames.sort(key=lambda f: f.group)

    def _used_bits(self, message: Any) -> int:
        """The mask of the bits the signals of a (classic, little-endian) message cover."""
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
        return used

    def _add(self, message: Any, kind: FrameKind, group: int, used: int,
             required: tuple[str, ...]) -> None:
        signals = {s.name: s for s in message.signals}
        for name in required:
            if name not in signals:
                raise self._bad(f"{message.name} lacks the signal {name}")
        grouped = kind in GROUPED
        axis_signals: list[tuple[int, str]] = []
        flags: dict[int, dict[str, str]] = {}
        checksum_byte = None
        for name, signal in signals.items():
            if name in required or (grouped and name == "Counter"):
                continue
            if grouped and name == "Checksum":
                if signal.length != 8 or signal.start % 8 or signal.is_signed:
                    raise self._bad(f"{message.name}.Checksum must be one unsigned, "
                                    f"byte-aligned byte")
                checksum_byte = signal.start // 8
                continue
            match = _AXIS_SIGNAL.fullmatch(name)
            if kind in AXIS_VALUE_KINDS and match and match.group(2) == GROUPED[kind]:
                axis_signals.append((int(match.group(1)), name))
            elif kind == FrameKind.STATUS and match and match.group(2) in FLAG_SIGNALS.values():
                flags.setdefault(int(match.group(1)), {})[match.group(2)] = name
            else:
                raise self._bad(f"unexpected signal {name} in {message.name}")
        counter_bits = signals["Counter"].length if "Counter" in signals else 0
        if grouped and not counter_bits:
            raise self._bad(f"{message.name} lacks the signal Counter")
        frame = DbcFrame(message=message, kind=kind, group=group,
                         axis_signals=tuple(sorted(axis_signals)),
                         flag_signals=self._flag_signals(message.name, flags),
                         counter_bits=counter_bits, checksum_byte=checksum_byte, used_mask=used,
                         layout=compile_layout(message))
        self.frames[message.frame_id] = frame
        if grouped:
            self.groups[kind].append(frame)

    def _flag_signals(self, name: str, flags: Mapping[int, Mapping[str, str]]
                      ) -> tuple[tuple[int, tuple[str, ...]], ...]:
        """Per axis, the flag signal names in `FLAG_SIGNALS` order; all flags required."""
        result = []
        for axis, found in sorted(flags.items()):
            missing = [s for s in FLAG_SIGNALS.values() if s not in found]
            if missing:
                raise self._bad(f"{name}: axis {axis} lacks the flags {missing}")
            result.append((axis, tuple(found[s] for s in FLAG_SIGNALS.values())))
        return tuple(result)

    def check_ranges(self, joints: JointSpace) -> None:
        """Fail early when a joint's limit range does not fit its axis signal range."""
        for kind in POSITION_KINDS:
            for frame in self.groups[kind]:
                for axis, name in frame.axis_signals:
                    signal = frame.message.get_signal_by_name(name)
                    m = joints.by_axis[axis]
                    i = joints.joint_index[m.joint]
                    lo, hi = joints.lower[i], joints.upper[i]
                    ends = sorted((m.to_axis(lo), m.to_axis(hi)))
                    if ends[0] < signal.minimum or ends[1] > signal.maximum:
                        raise ProtocolParseError(
                            f"{m.joint} limits [{lo}, {hi}] rad map to axis {axis} positions "
                            f"[{ends[0]:.6g}, {ends[1]:.6g}] rad, beyond {name}'s range "
                            f"[{signal.minimum}, {signal.maximum}] rad in {self.path}; fix "
                            f"zero_offset in the axis map or the DBC range", path=self.path)

    # ---- look-ups --------------------------------------------------------------------------

    def single(self, kind: FrameKind) -> DbcFrame:
        """The one frame of an ungrouped family (control, heartbeat)."""
        name = next(n for n, (k, _) in _SINGLE.items() if k == kind)
        return self.frames[self.database.get_message_by_name(name).frame_id]

    def choices(self, kind: FrameKind, signal: str) -> Mapping[int, Any]:
        """The value table of an enum signal of an ungrouped frame (number -> name)."""
        return self.single(kind).message.get_signal_by_name(signal).choices or {}

    def period(self, kind: str) -> float | None:
        """Cycle time of a frame family from the DBC's GenMsgCycleTime [s], None if unset.

        ``kind`` is one of ``target``, ``position``, ``effort``, ``status``, ``heartbeat``
        (``effort``: None also when the DBC has no effort frames).
        """
        if kind == FrameKind.HEARTBEAT:
            cycle = self.single(FrameKind.HEARTBEAT).message.cycle_time
        elif kind in self.groups:
            frames = self.groups[FrameKind(kind)]
            cycle = frames[0].message.cycle_time if frames else None
        else:
            raise ProtocolError(f"unknown frame family {kind!r}; expected target, position, "
                                f"effort, status or heartbeat")
        return cycle / 1000.0 if cycle else None

    def cycle_period(self, kind: str) -> float:
        """Cycle time of a frame family [s]: the DBC's, else `DEFAULT_PERIODS`."""
        return self.period(kind) or DEFAULT_PERIODS[FrameKind(kind)]
