"""The joint-to-axis map (``config/axes.yaml``) and the conversion between joint and axis space."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from crawler_motion.errors import ProtocolError, ProtocolParseError

#: The fields of one joint's entry in the axis map, all required.
AXIS_KEYS: tuple[str, ...] = ("axis", "direction", "zero_offset", "gear_ratio")


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
            line = key_node.start_mark.line + 1
            raise ProtocolParseError(f"duplicate key {key!r} (line {line}); each joint and each "
                                     f"field may appear only once", key=str(key), line=line)
        seen.add(key)
    return loader.construct_mapping(node, deep=True)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
                                 _construct_unique_mapping)


def _is_number(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float))


def joint_tuple(joint_names: Sequence[str]) -> tuple[str, ...]:
    """The joint names as a tuple; `ProtocolError` unless they are distinct and non-empty."""
    names = tuple(joint_names)
    if not names or len(set(names)) != len(names):
        raise ProtocolError(f"joint names must be distinct and non-empty, got {list(names)}")
    return names


def _parse_entry(entry: Any, joint: str, here: str, n: int) -> AxisMapping:
    """One joint's entry ``{axis, direction, zero_offset, gear_ratio}``, validated."""
    def bad(message: str, field: str | None = None) -> ProtocolParseError:
        return ProtocolParseError(message, key=here if field is None else f"{here}.{field}")

    if not isinstance(entry, Mapping):
        raise bad(f"{here} must be a mapping {{axis, direction, zero_offset, gear_ratio}}, "
                  f"got {entry!r}")
    unknown = sorted(str(k) for k in entry if k not in AXIS_KEYS)
    absent = [k for k in AXIS_KEYS if k not in entry]
    if unknown or absent:
        raise bad(f"{here}: needs exactly the keys {list(AXIS_KEYS)}; missing {absent}, "
                  f"unknown {unknown}")
    axis = entry["axis"]
    if isinstance(axis, bool) or not isinstance(axis, int) or not 0 <= axis < n:
        raise bad(f"{here}.axis must be an integer 0..{n - 1}, got {axis!r}", "axis")
    direction = entry["direction"]
    if not _is_number(direction) or direction not in (1, -1):
        raise bad(f"{here}.direction must be +1 or -1, got {direction!r}", "direction")
    offset = entry["zero_offset"]
    if not _is_number(offset) or not math.isfinite(offset):
        raise bad(f"{here}.zero_offset must be a finite angle in rad, got {offset!r}",
                  "zero_offset")
    gear = entry["gear_ratio"]
    if not _is_number(gear) or not math.isfinite(gear) or gear <= 0:
        raise bad(f"{here}.gear_ratio must be a finite number > 0, got {gear!r}", "gear_ratio")
    return AxisMapping(joint=joint, axis=axis, direction=int(direction),
                       zero_offset=float(offset), gear_ratio=float(gear))


def parse_axis_map(data: Any, joint_names: Sequence[str],
                   where: str = "axes") -> tuple[AxisMapping, ...]:
    """Validate a ``{joint: {axis, direction, zero_offset, gear_ratio}}`` mapping.

    Returns one `AxisMapping` per joint in ``joint_names`` order. Every joint must appear once
    and the axes must be exactly ``0..len(joint_names) - 1``, each used once.
    """
    names = joint_tuple(joint_names)
    n = len(names)
    if not isinstance(data, Mapping):
        raise ProtocolParseError(f"{where} must be a mapping joint name -> "
                                 f"{{axis, direction, zero_offset, gear_ratio}}, got {data!r}",
                                 key=where)
    missing = [j for j in names if j not in data]
    extra = [str(j) for j in data if j not in names]
    if missing or extra:
        raise ProtocolParseError(f"{where}: the axis map must name exactly the {n} joints "
                                 f"{list(names)}; missing {missing}, unknown {extra}", key=where)
    result = []
    owner: dict[int, str] = {}
    for joint in names:
        mapping = _parse_entry(data[joint], joint, f"{where}.{joint}", n)
        if mapping.axis in owner:
            raise ProtocolParseError(
                f"{where}: axis {mapping.axis} is used by both {owner[mapping.axis]} and "
                f"{joint}; each axis 0..{n - 1} must be used exactly once",
                key=f"{where}.{joint}.axis")
        owner[mapping.axis] = joint
        result.append(mapping)
    return tuple(result)


def load_axis_map(path: str | Path, joint_names: Sequence[str]) -> tuple[AxisMapping, ...]:
    """Load and validate an axes YAML file (a top-level ``axes:`` mapping)."""
    file = Path(path)
    joint_tuple(joint_names)
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as exc:
        raise ProtocolParseError(f"cannot read axis map {file}: {exc.strerror}",
                                 path=file) from exc
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)
    except ProtocolParseError as exc:
        raise ProtocolParseError(f"axis map {file}: {exc}", path=file, key=exc.key,
                                 line=exc.line) from exc
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise ProtocolParseError(f"axis map {file} is not valid YAML: {exc}", path=file,
                                 line=None if mark is None else mark.line + 1) from exc
    if not isinstance(data, Mapping) or "axes" not in data:
        raise ProtocolParseError(f"axis map {file} must hold a top-level 'axes:' mapping "
                                 f"joint name -> {{axis, direction, zero_offset, gear_ratio}}",
                                 path=file)
    try:
        return parse_axis_map(data["axes"], joint_names, where=f"{file}: axes")
    except ProtocolParseError as exc:
        raise ProtocolParseError(str(exc), path=file, key=exc.key) from None


class JointSpace:
    """Joint order, joint limits [rad] and the axis map: converts and checks position vectors.

    ``lower``/``upper`` are the joint limits in ``joint_names`` order [rad].
    """

    def __init__(self, joint_names: Sequence[str], lower: Sequence[float],
                 upper: Sequence[float], axis_map: Sequence[AxisMapping]) -> None:
        self.joint_names = joint_tuple(joint_names)
        n = len(self.joint_names)
        self.lower = np.asarray(lower, dtype=float).reshape(-1)
        self.upper = np.asarray(upper, dtype=float).reshape(-1)
        if self.lower.shape != (n,) or self.upper.shape != (n,):
            raise ProtocolError(f"joint limits must hold {n} values each, got "
                                f"{self.lower.size} lower and {self.upper.size} upper")
        if not (np.all(np.isfinite(self.lower)) and np.all(np.isfinite(self.upper))
                and np.all(self.lower < self.upper)):
            raise ProtocolError("joint limits must be finite with lower < upper")
        self.axis_map = tuple(axis_map)
        self.by_axis = {m.axis: m for m in self.axis_map}
        self.joint_index = {m.joint: i for i, m in enumerate(self.axis_map)}
        self._axis_order = np.array([m.axis for m in self.axis_map])
        self._direction = np.array([m.direction for m in self.axis_map], dtype=float)
        self._offset = np.array([m.zero_offset for m in self.axis_map])

    @property
    def n(self) -> int:
        """Number of joints (= number of axes)."""
        return len(self.joint_names)

    def vector(self, values: Any, what: str,
               error: type[ProtocolError] = ProtocolError, unit: str = "rad") -> np.ndarray:
        """``values`` as a float vector of one value per joint/axis; ``error`` otherwise."""
        try:
            arr = np.asarray(values, dtype=float).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise error(f"{what} must be {self.n} numbers [{unit}]: {exc}") from None
        if arr.shape != (self.n,):
            raise error(f"{what} must hold {self.n} values [{unit}], got {arr.size}")
        return arr

    def to_axis(self, q: np.ndarray) -> np.ndarray:
        """Axis positions in axis order (index = axis) of joint angles in joint order [rad]."""
        out = np.empty(self.n)
        out[self._axis_order] = self._direction * q + self._offset
        return out

    def to_joint(self, a: np.ndarray) -> np.ndarray:
        """Joint angles in joint order of axis positions in axis order [rad]."""
        return (a[self._axis_order] - self._offset) * self._direction + 0.0  # no -0.0

    def effort_to_axis(self, tau: np.ndarray) -> np.ndarray:
        """Axis efforts in axis order of joint torques in joint order [N m] (direction only:
        a zero offset does not shift a torque)."""
        out = np.empty(self.n)
        out[self._axis_order] = self._direction * tau
        return out

    def effort_to_joint(self, e: np.ndarray) -> np.ndarray:
        """Joint torques in joint order of axis efforts in axis order [N m]."""
        return e[self._axis_order] * self._direction + 0.0  # no -0.0

    def within(self, i: int, value: float, margin: float) -> bool:
        """True when joint ``i`` at ``value`` [rad] is finite and within its limits widened by
        ``margin`` [rad]."""
        return bool(self.lower[i] - margin <= value <= self.upper[i] + margin)
