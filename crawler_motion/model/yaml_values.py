"""Checked values of a YAML configuration: numbers, positive numbers and sections.

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
