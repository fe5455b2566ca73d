"""Mission files: a list of tasks (go to, follow a structure, cover an area, come home), checked.

A mission is YAML (or JSON) text with one key ``tasks``: a list of one-key mappings, in the
frame ``odom``, each with an optional ``timeout`` [s] (default `DEFAULT_TIMEOUT`) and an
optional ``id`` at the top level::

    tasks:
      - goto: {x: 1.0, y: 0.0}
      - follow: {side: left, length: 1.5, standoff: 0.15}   # the structure on that side
      - cover: {area: [0.5, -1.0, 2.5, 1.0], spacing: 0.25}  # or polygon: [[x, y], ...]
      - home: {}                                           # back to where the mission started

`parse_mission` refuses anything else with a `CommandError` naming the task (1-based) and the
key, and what would be right. Numbers are finite floats; coordinates within
`MAX_COORDINATE` of the origin; the text at most `MAX_TEXT` characters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import yaml

from crawler_motion.errors import CommandError

#: Longest mission text [characters] and most tasks.
MAX_TEXT = 65536
MAX_TASKS = 100
#: Largest |x|, |y| of a coordinate [m] and the default task timeout [s].
MAX_COORDINATE = 1000.0
DEFAULT_TIMEOUT = 600.0


class TaskKind(Enum):
    """The kinds of task."""

    GOTO = "goto"
    FOLLOW = "follow"
    COVER = "cover"
    HOME = "home"


#: Keys of each kind (required, optional) besides ``timeout``.
KEYS: dict[TaskKind, tuple[tuple[str, ...], tuple[str, ...]]] = {
    TaskKind.GOTO: (("x", "y"), ()),
    TaskKind.FOLLOW: (("length",), ("side", "standoff")),
    TaskKind.COVER: (("spacing",), ("area", "polygon")),
    TaskKind.HOME: ((), ()),
}


@dataclass(frozen=True)
class Task:
    """One task: its kind, its checked values and its timeout [s]."""

    kind: TaskKind
    values: dict[str, Any] = field(default_factory=dict)
    timeout: float = DEFAULT_TIMEOUT

    @property
    def polygon(self) -> list[tuple[float, float]]:
        """A cover task's area as a polygon (an ``area`` rectangle as its four corners)."""
        if "polygon" in self.values:
            return list(self.values["polygon"])
        x0, y0, x1, y1 = self.values["area"]
        return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


@dataclass(frozen=True)
class Mission:
    """The checked tasks of a mission and its id."""

    id: str
    tasks: tuple[Task, ...]


def _number(value: Any, where: str, low: float = -math.inf, high: float = math.inf) -> float:
    if isinstance(value, str) and len(value) < 40:  # YAML 1.1 reads 1e9 (no dot) as text
        try:
            value = float(value)
        except ValueError:
            pass
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CommandError(f"{where} must be a number, got {str(value)[:40]!r}")
    number = float(value)
    if not (math.isfinite(number) and low <= number <= high):
        raise CommandError(f"{where} must be a finite number in [{low:g}, {high:g}], got "
                           f"{str(value)[:40]}")
    return number


def _point(value: Any, where: str) -> tuple[float, float]:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise CommandError(f"{where} must be a point [x, y], got {str(value)[:60]}")
    return (_number(value[0], f"{where} x", -MAX_COORDINATE, MAX_COORDINATE),
            _number(value[1], f"{where} y", -MAX_COORDINATE, MAX_COORDINATE))


def _cover(values: dict[str, Any], where: str) -> dict[str, Any]:
    out: dict[str, Any] = {"spacing": _number(values["spacing"], f"{where} spacing", 0.01,
                                              10.0)}
    if ("area" in values) == ("polygon" in values):
        raise CommandError(f"{where} needs exactly one of area: [x0, y0, x1, y1] or polygon: "
                           "[[x, y], ...]")
    if "area" in values:
        area = values["area"]
        if not isinstance(area, list | tuple) or len(area) != 4:
            raise CommandError(f"{where} area must be [x0, y0, x1, y1], got {str(area)[:60]}")
        x0, y0, x1, y1 = (_number(v, f"{where} area", -MAX_COORDINATE, MAX_COORDINATE)
                          for v in area)
        if not (x1 > x0 and y1 > y0):
            raise CommandError(f"{where} area needs x1 > x0 and y1 > y0, got {list(area)}")
        out["area"] = (x0, y0, x1, y1)
    else:
        poly = values["polygon"]
        if not isinstance(poly, list) or not 3 <= len(poly) <= 100:
            raise CommandError(f"{where} polygon must be 3 to 100 points [[x, y], ...]")
        out["polygon"] = tuple(_point(p, f"{where} polygon point {i + 1}")
                               for i, p in enumerate(poly))
    return out


def _task(item: Any, index: int) -> Task:
    where = f"task {index}"
    if not isinstance(item, dict) or len(item) != 1:
        raise CommandError(f"{where} must be a one-key mapping such as goto: {{x: 1, y: 0}}, "
                           f"got {str(item)[:60]}")
    (name, values), = item.items()
    try:
        kind = TaskKind(name)
    except ValueError:
        raise CommandError(f"{where}: unknown task {str(name)[:30]!r}; one of "
                           f"{[k.value for k in TaskKind]}") from None
    where = f"task {index} ({kind.value})"
    values = {} if values is None else values
    if not isinstance(values, dict):
        raise CommandError(f"{where} takes a mapping of its keys, got {str(values)[:60]}")
    required, optional = KEYS[kind]
    unknown = set(values) - set(required) - set(optional) - {"timeout"}
    missing = set(required) - set(values)
    if unknown or missing:
        raise CommandError(f"{where}: {'unknown keys ' + str(sorted(unknown)) if unknown else ''}"
                           f"{'missing keys ' + str(sorted(missing)) if missing else ''}; "
                           f"it takes {list(required)} and optionally "
                           f"{[*optional, 'timeout']}")
    timeout = _number(values.get("timeout", DEFAULT_TIMEOUT), f"{where} timeout", 1.0, 86400.0)
    checked: dict[str, Any] = {}
    if kind is TaskKind.GOTO:
        checked = {"x": _number(values["x"], f"{where} x", -MAX_COORDINATE, MAX_COORDINATE),
                   "y": _number(values["y"], f"{where} y", -MAX_COORDINATE, MAX_COORDINATE)}
    elif kind is TaskKind.FOLLOW:
        side = values.get("side", "right")
        if side not in ("left", "right"):
            raise CommandError(f"{where} side must be left or right, got {str(side)[:20]!r}")
        checked = {"length": _number(values["length"], f"{where} length", 0.01, 100.0),
                   "side": side}
        if "standoff" in values:
            checked["standoff"] = _number(values["standoff"], f"{where} standoff", 0.01, 1.0)
    elif kind is TaskKind.COVER:
        checked = _cover(values, where)
    return Task(kind, checked, timeout)


def parse_mission(text: str, mission_id: str = "") -> Mission:
    """The checked mission of a YAML/JSON text; `CommandError` naming what is wrong."""
    if not isinstance(text, str) or len(text) > MAX_TEXT:
        raise CommandError(f"a mission must be YAML text of at most {MAX_TEXT} characters")
    try:
        data = yaml.safe_load(text)
    except (yaml.YAMLError, RecursionError) as exc:
        raise CommandError(f"the mission is not valid YAML ({str(exc)[:120]})") from None
    if not isinstance(data, dict) or "tasks" not in data or set(data) - {"tasks", "id"}:
        raise CommandError("a mission is a mapping with the key tasks (a list) and optionally "
                           "id")
    tasks = data["tasks"]
    if not isinstance(tasks, list) or not 1 <= len(tasks) <= MAX_TASKS:
        raise CommandError(f"tasks must be a list of 1 to {MAX_TASKS} tasks")
    return Mission(str(data.get("id", mission_id))[:64],
                   tuple(_task(item, i + 1) for i, item in enumerate(tasks)))
