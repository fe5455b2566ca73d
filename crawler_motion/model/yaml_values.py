"""Checked values of a YAML configuration: numbers, numbers in a range, positive numbers and
sections.

Each check raises `ConfigError` naming the place (``what`` / ``where``) and the value found.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from crawler_motion.errors import ConfigError


def number(value: Any, what: str) -> float:
    """``value`` as a finite float; `ConfigError` if it is not a finite number (bool is not)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{what} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"{what} must be finite, got {value!r}")
    return float(value)


def number_in(value: Any, what: str, lo: float, hi: float, unit: str, *,
              above: bool = False) -> float:
    """``value`` as a finite float in [lo, hi] ((lo, hi] if ``above``); `ConfigError` naming
    ``what``, the range with its ``unit`` and the value otherwise (bool is not a number)."""
    x = float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        else math.nan
    if not (math.isfinite(x) and (x > lo if above else x >= lo) and x <= hi):
        raise ConfigError(f"{what} must be a number in {'(' if above else '['}{lo:g}, {hi:g}] "
                          f"{unit}, got {value!r}")
    return x


def positive(value: Any, what: str) -> float:
    """``value`` as a finite float > 0; `ConfigError` otherwise."""
    result = number(value, what)
    if result <= 0.0:
        raise ConfigError(f"{what} must be > 0, got {result}")
    return result


def section(data: Mapping[str, Any], key: str, where: str) -> Mapping[str, Any]:
    """The mapping ``data[key]``; `ConfigError` if it is missing or not a mapping."""
    value = data.get(key)
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where}: missing section '{key}' (a mapping)")
    return value
