"""The one validation rule of a joint-state vector (names, positions, velocities, efforts)."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from enum import Enum
from typing import Any

import numpy as np

from crawler_motion.errors import CommandError


def as_float(value: Any) -> float | None:
    """``value`` as a float if it is a real number (int, float, numpy scalar; not bool), an
    int beyond the float range as +-inf; None for anything else (str, None, ...)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        return None
    try:
        return float(value)
    except OverflowError:  # an int of more than ~308 digits
        return math.inf if value > 0 else -math.inf


def finite_float(value: Any) -> float | None:
    """``value`` as a finite float if it is a Python int or float (not bool) that is one; else
    None (NaN, inf, an int beyond the float range, anything else)."""
    if not isinstance(value, (int, float)):
        return None
    number = as_float(value)
    return number if number is not None and math.isfinite(number) else None


class Flaw(str, Enum):
    """What is wrong with a joint-state vector."""

    NAMES_NOT_STRINGS = "names_not_strings"
    LENGTH = "length"
    NAMES = "names"
    NOT_A_NUMBER = "not_a_number"
    NOT_FINITE = "not_finite"
    VELOCITY = "velocity"
    LIMITS = "limits"


class JointStateError(CommandError):
    """A joint-state vector is refused; ``flaw`` says why, ``joints`` names the joints at fault.

    ``subject`` is what was validated ("joint_states", "joint command").
    """

    def __init__(self, subject: str, flaw: Flaw, joints: Sequence[str], detail: str) -> None:
        super().__init__(f"{subject} {detail}")
        self.subject = subject
        self.flaw = flaw
        self.joints = tuple(joints)
        self.detail = detail


class JointStateRule:
    """Validates joint-state vectors against the joint names and (optionally) their limits.

    Every expected joint exactly once and no other; positions one per name, velocities and
    efforts one per name or none; positions and velocities finite real numbers (not bool, not
    strings); positions within ``[lower, upper]`` [rad] when limits are given (refused, never
    clipped).
    """

    def __init__(self, joint_names: Sequence[str], lower: Sequence[float] | None = None,
                 upper: Sequence[float] | None = None, subject: str = "joint_states") -> None:
        self.joint_names = tuple(joint_names)
        self.subject = subject
        self._index = {name: i for i, name in enumerate(self.joint_names)}
        self._lower = None if lower is None else np.asarray(lower, dtype=float)
        self._upper = None if upper is None else np.asarray(upper, dtype=float)

    def _error(self, flaw: Flaw, joints: Sequence[str], detail: str) -> JointStateError:
        return JointStateError(self.subject, flaw, joints, detail)

    def validate(self, names: Sequence[Any], positions: Sequence[Any],
                 velocities: Sequence[Any] = (), efforts: Sequence[Any] = ()) -> np.ndarray:
        """Positions [rad] in joint-name order; `JointStateError` for anything wrong."""
        q = self._plain(names, positions, velocities, efforts)
        if q is not None:
            return q
        names = list(names)
        if not all(isinstance(name, str) for name in names):
            raise self._error(Flaw.NAMES_NOT_STRINGS, (), "names must be strings")
        self._check_lengths(names, positions, velocities, efforts)
        self._check_names(names)
        q = np.empty(len(self.joint_names))
        for name, value in zip(names, positions, strict=True):
            number = as_float(value)
            if number is None:
                raise self._error(Flaw.NOT_A_NUMBER, (name,), (
                    f"positions must be numbers [rad], got {value!r:.40} for {name}"))
            q[self._index[name]] = number
        bad = np.flatnonzero(~np.isfinite(q))
        if len(bad):
            joints = [self.joint_names[i] for i in bad]
            listed = ", ".join(f"{self.joint_names[i]}={q[i]}" for i in bad)
            raise self._error(Flaw.NOT_FINITE, joints, (
                f"has non-finite positions (NaN or inf): {listed}; send finite values"))
        for name, value in zip(names, velocities, strict=False):  # 0 or n of them
            number = as_float(value)
            if number is None or not math.isfinite(number):
                raise self._error(Flaw.VELOCITY, (name,), (
                    f"velocities must be finite numbers [rad/s] (no NaN or inf), got "
                    f"{value!r:.40} for {name}"))
        self._check_limits(q)
        return q

    def _plain(self, names: Sequence[Any], positions: Sequence[Any], velocities: Sequence[Any],
               efforts: Sequence[Any]) -> np.ndarray | None:
        """The common case in one pass: every joint in order, floats only, all finite, within
        the limits; its positions [rad], or None for the full check (which finds the flaw)."""
        n = len(self.joint_names)
        if (len(positions) != n or len(velocities) not in (0, n) or len(efforts) not in (0, n)
                or tuple(names) != self.joint_names
                or not all(type(v) is float for v in positions)
                or not all(type(v) is float for v in velocities)
                or not math.isfinite(sum(positions, 0.0) + sum(velocities, 0.0))):
            return None
        q = np.array(positions, dtype=float)
        if self._lower is not None and self._upper is not None and not (
                (q >= self._lower).all() and (q <= self._upper).all()):
            return None
        return q

    def _check_lengths(self, names: list[str], positions: Sequence[Any],
                       velocities: Sequence[Any], efforts: Sequence[Any]) -> None:
        n = len(names)
        if len(positions) != n:
            raise self._error(Flaw.LENGTH, (), (
                f"has {n} names but {len(positions)} positions; send one position per name"))
        for values, what in ((velocities, "velocities"), (efforts, "efforts")):
            if len(values) not in (0, n):
                raise self._error(Flaw.LENGTH, (), (
                    f"has {n} names but {len(values)} {what} (0 or {n} allowed)"))

    def _check_names(self, names: list[str]) -> None:
        counts = Counter(names)
        duplicate = sorted(name for name, count in counts.items() if count > 1)
        missing = [name for name in self.joint_names if name not in counts]
        extra = sorted(name for name in counts if name not in self._index)
        if duplicate or missing or extra:
            again = " (names that appear more than once)" if duplicate else ""
            raise self._error(Flaw.NAMES, [*duplicate, *missing, *extra], (
                f"must name each of the {len(self.joint_names)} joints once; duplicate "
                f"{duplicate}{again}, missing {missing}, unknown {extra}"))

    def _check_limits(self, q: np.ndarray) -> None:
        if self._lower is None or self._upper is None:
            return
        out = np.flatnonzero((q < self._lower) | (q > self._upper))
        if len(out):
            listed = ", ".join(f"{self.joint_names[i]}={q[i]:.6g} not in [{self._lower[i]:g}, "
                               f"{self._upper[i]:g}]" for i in out)
            raise self._error(Flaw.LIMITS, [self.joint_names[i] for i in out], (
                f"outside the joint limits (refused, not clipped): {listed} rad"))


def validate_joint_state(names: Sequence[Any], positions: Sequence[Any],
                         velocities: Sequence[Any], expected_names: Sequence[str]
                         ) -> np.ndarray:
    """Measured joint angles ``(len(expected_names) // 3, 3)`` [rad] in ``expected_names``
    order (one row per leg), by `JointStateRule`; `JointStateError` if refused."""
    return JointStateRule(expected_names).validate(names, positions, velocities).reshape(-1, 3)
