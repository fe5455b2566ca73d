"""Parameter declarations (`ParamSpec`) and the one validator contract of the package (no ROS).

A node declares its parameters as a tuple of `ParamSpec`, built by a function when bounds or
choices depend on a loaded configuration. `validate_parameter` says why one value is refused
(None when it is accepted); `validate_parameters` lists every reason for a set of values.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

#: A parameter value as ROS carries it (a tuple: an array of floats).
Value = bool | int | float | str | tuple[float, ...]
#: An extra rule of one parameter: the reason a value is refused, or None.
Check = Callable[[Any], str | None]


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: default, meaning, unit and the rules of its values.

    ``minimum``/``maximum`` bound a number (both or neither, inclusive, in ``unit``);
    ``choices`` close a string; ``check`` adds a rule of its own (e.g. "must not be empty").
    The value type is the type of ``default`` (a float parameter also takes an int).
    """

    name: str
    default: Value
    description: str
    read_only: bool = False
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] = ()
    unit: str = ""
    check: Check | None = field(default=None, compare=False)

    @property
    def kind(self) -> type:
        """The value type: bool, int, float or str."""
        return type(self.default)


def not_empty(value: str) -> str | None:
    """A `Check`: a string parameter must not be empty or blank."""
    return "must not be empty" if not value.strip() else None


def _type_reason(spec: ParamSpec, value: Any) -> str | None:
    kind = spec.kind
    if kind is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    elif kind is tuple:
        ok = isinstance(value, (list, tuple)) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
    else:
        ok = type(value) is kind
    return None if ok else f"{spec.name} must be a {kind.__name__}, got {value!r}"


def _rule_reason(spec: ParamSpec, value: Any) -> str | None:
    if isinstance(value, str):
        if spec.choices and value not in spec.choices:
            return f"{spec.name} must be one of {list(spec.choices)}, got {value!r}"
        return None
    if isinstance(value, bool):
        return None
    if isinstance(value, (list, tuple)):
        finite = all(math.isfinite(v) for v in value)
        return None if finite else f"{spec.name} must be finite numbers, got {list(value)!r}"
    if not math.isfinite(value):
        return f"{spec.name} must be finite, got {value!r}"
    if spec.minimum is not None and spec.maximum is not None and not (
            spec.minimum <= value <= spec.maximum):
        unit = f" {spec.unit}" if spec.unit else ""
        return (f"{spec.name} must be within [{spec.minimum:g}, {spec.maximum:g}]{unit}, "
                f"got {value!r}")
    return None


def validate_parameter(spec: ParamSpec, value: Any) -> str | None:
    """Why ``value`` is not acceptable for the parameter ``spec``; None when it is."""
    reason = _type_reason(spec, value)
    if reason is None and spec.check is not None:
        problem = spec.check(value)
        reason = None if problem is None else (
            problem if problem.startswith(spec.name) else f"{spec.name} {problem}")
    return reason if reason is not None else _rule_reason(spec, value)


def validate_parameters(specs: Iterable[ParamSpec], values: Mapping[str, Any]) -> list[str]:
    """Every reason why ``values`` (name -> value) is not acceptable; empty when all are.

    Names without a spec are refused in one reason naming all of them.
    """
    table = {spec.name: spec for spec in specs}
    unknown = sorted(name for name in values if name not in table)
    reasons = [reason for name, value in values.items() if name in table
               and (reason := validate_parameter(table[name], value)) is not None]
    if unknown:
        reasons.append(f"unknown {unknown}: each unknown parameter is refused; the known "
                       f"ones are {sorted(table)}")
    return reasons


#: The words YAML 1.1 (the ROS command line's ``-p name:=value`` and parameter files) reads as
#: booleans: a choice spelled so arrives as a bool.
YAML_BOOLEANS = {True: ("true", "yes", "on", "y"), False: ("false", "no", "off", "n")}


def choice_from_yaml(spec: ParamSpec, value: Any) -> Any:
    """``value`` of ``spec`` as written: a bool given to a choice parameter is the one choice
    YAML reads as that bool (``-p attitude_mode:=off`` arrives as False and is ``"off"``);
    anything else unchanged (a bool no choice matches is refused by `validate_parameters`)."""
    if not (spec.choices and isinstance(value, bool)):
        return value
    words = [c for c in spec.choices if c.lower() in YAML_BOOLEANS[value]]
    return words[0] if len(words) == 1 else value
