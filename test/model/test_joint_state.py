"""Tests of crawler_motion.model.joint_state: the one joint-state rule, boundary rows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.model.joint_state import (
    Flaw,
    JointStateError,
    JointStateRule,
    as_float,
    finite_float,
    validate_joint_state,
)

NAMES = ("a", "b", "c", "d", "e", "f")
LOWER = [-1.0] * 6
UPPER = [1.0] * 6
RULE = JointStateRule(NAMES, LOWER, UPPER, subject="joint command")
ZERO = [0.0] * 6


@pytest.mark.parametrize(("value", "expected"), [
    (1, 1.0), (1.5, 1.5), (np.float32(0.5), 0.5), (10**400, math.inf), (-(10**400), -math.inf),
    (True, None), ("1", None), (None, None),
])
def test_as_float(value, expected):
    assert as_float(value) == expected


@pytest.mark.parametrize(("value", "expected"), [
    (1, 1.0), (2.5, 2.5), (math.nan, None), (math.inf, None), (10**400, None), (False, None),
    (np.float64(1.0), 1.0), (np.int64(1), None), ("1", None),
])
def test_finite_float(value, expected):
    assert finite_float(value) == expected


def test_accepts_limits_exactly_and_reorders_by_name():
    q = RULE.validate(list(reversed(NAMES)), [1.0, -1.0, 0.0, 0.0, 0.5, -0.5],
                      velocities=ZERO, efforts=ZERO)
    np.testing.assert_array_equal(q, [-0.5, 0.5, 0.0, 0.0, -1.0, 1.0])
    assert RULE.validate(NAMES, [0, 0, 0, 0, 0, 0]).dtype == float  # ints are numbers


@pytest.mark.parametrize(("names", "positions", "velocities", "efforts", "flaw", "joints",
                          "fragment"), [
    ([1, *NAMES[1:]], ZERO, (), (), Flaw.NAMES_NOT_STRINGS, (), "names must be strings"),
    (NAMES, ZERO[:5], (), (), Flaw.LENGTH, (), "6 names but 5 positions"),
    (NAMES, ZERO, ZERO[:1], (), Flaw.LENGTH, (), "6 names but 1 velocities (0 or 6"),
    (NAMES, ZERO, (), [0.0] * 7, Flaw.LENGTH, (), "6 names but 7 efforts"),
    (NAMES[:5], ZERO[:5], (), (), Flaw.NAMES, ("f",), "missing ['f']"),
    ([*NAMES, "g"], [*ZERO, 0.0], (), (), Flaw.NAMES, ("g",), "unknown ['g']"),
    ([*NAMES[:5], "a"], ZERO, (), (), Flaw.NAMES, ("a", "f"), "appear more than once"),
    (NAMES, ["x", *ZERO[1:]], (), (), Flaw.NOT_A_NUMBER, ("a",), "must be numbers [rad]"),
    (NAMES, [True, *ZERO[1:]], (), (), Flaw.NOT_A_NUMBER, ("a",), "must be numbers"),
    (NAMES, [*ZERO[:5], math.nan], (), (), Flaw.NOT_FINITE, ("f",), "non-finite"),
    (NAMES, [10**400, *ZERO[1:]], (), (), Flaw.NOT_FINITE, ("a",), "NaN or inf"),
    (NAMES, ZERO, [math.inf, *ZERO[1:]], (), Flaw.VELOCITY, ("a",), "velocities must be fin"),
    (NAMES, ZERO, ["0", *ZERO[1:]], (), Flaw.VELOCITY, ("a",), "got '0' for a"),
    (NAMES, [math.nextafter(1.0, 2.0), *ZERO[1:]], (), (), Flaw.LIMITS, ("a",),
     "outside the joint limits (refused, not clipped)"),
    (NAMES, [*ZERO[:5], math.nextafter(-1.0, -2.0)], (), (), Flaw.LIMITS, ("f",), "f=-1"),
])
def test_refused(names, positions, velocities, efforts, flaw, joints, fragment):
    with pytest.raises(JointStateError) as info:
        RULE.validate(names, positions, velocities, efforts)
    error = info.value
    assert isinstance(error, CommandError)
    assert error.flaw is flaw and error.joints == joints and error.subject == "joint command"
    assert str(error).startswith("joint command ") and fragment in str(error)


def test_without_limits_any_finite_angle_is_accepted():
    rule = JointStateRule(NAMES)
    assert rule.validate(NAMES, [100.0, *ZERO[1:]])[0] == 100.0


def test_validate_joint_state_gives_one_row_per_leg():
    q = validate_joint_state(NAMES, np.arange(6.0), [], NAMES)
    assert q.shape == (2, 3)
    np.testing.assert_array_equal(q, [[0, 1, 2], [3, 4, 5]])
    with pytest.raises(JointStateError, match=r"^joint_states "):
        validate_joint_state(NAMES, ZERO[:5], [], NAMES)
