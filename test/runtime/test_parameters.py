"""Tests of crawler_motion.runtime.parameters: the one validator contract, boundary rows."""

from __future__ import annotations

import math

import pytest

from crawler_motion.runtime.parameters import (
    ParamSpec,
    not_empty,
    validate_parameter,
    validate_parameters,
)

RATE = ParamSpec("rate", 100.0, "tick rate", minimum=1.0, maximum=1000.0, unit="Hz")
RETRIES = ParamSpec("retries", 2, "retries", minimum=0, maximum=10)
MODE = ParamSpec("mode", "hold", "what to do", choices=("hold", "disable"))
FLAG = ParamSpec("flag", False, "a switch")
PATH = ParamSpec("path", "x", "a file", check=not_empty)
EVEN = ParamSpec("even", 2, "an even number",
                 check=lambda v: None if v % 2 == 0 else "must be even")
SPECS = (RATE, RETRIES, MODE, FLAG, PATH, EVEN)


@pytest.mark.parametrize(("spec", "value"), [
    (RATE, 1.0), (RATE, 1000.0), (RATE, 1), (RETRIES, 0), (RETRIES, 10), (MODE, "hold"),
    (MODE, "disable"), (FLAG, True), (PATH, "a"), (EVEN, 0),
])
def test_accepted(spec, value):
    assert validate_parameter(spec, value) is None


@pytest.mark.parametrize(("spec", "value", "reason"), [
    (RATE, math.nextafter(1.0, 0.0), "rate must be within [1, 1000] Hz, got 0.9999"),
    (RATE, math.nextafter(1000.0, 2000.0), "within [1, 1000] Hz"),
    (RATE, math.nan, "rate must be finite, got nan"),
    (RATE, math.inf, "must be finite"),
    (RATE, True, "rate must be a float, got True"),
    (RATE, "1", "must be a float"),
    (RETRIES, -1, "retries must be within [0, 10], got -1"),
    (RETRIES, 11, "within [0, 10]"),
    (RETRIES, 1.0, "retries must be a int"),
    (RETRIES, False, "must be a int"),
    (MODE, "stop", "mode must be one of ['hold', 'disable'], got 'stop'"),
    (MODE, "", "must be one of"),
    (FLAG, 1, "flag must be a bool"),
    (PATH, "", "path must not be empty"),
    (PATH, " ", "path must not be empty"),
    (EVEN, 3, "even must be even"),
])
def test_refused_with_a_reason(spec, value, reason):
    got = validate_parameter(spec, value)
    assert got is not None and reason in got


def test_validate_parameters_lists_every_reason():
    assert validate_parameters(SPECS, {s.name: s.default for s in SPECS}) == []
    assert validate_parameters(SPECS, {}) == []
    reasons = validate_parameters(SPECS, {"rate": 0.0, "mode": "x", "speed": 1, "alpha": 2})
    assert len(reasons) == 3
    assert "rate" in reasons[0] and "mode" in reasons[1]
    assert "unknown ['alpha', 'speed']" in reasons[2] and "unknown parameter" in reasons[2]
    assert "'rate'" in reasons[2]  # the known ones are named


def test_specs_built_at_run_time_compare_by_value():
    def table(high: float) -> tuple[ParamSpec, ...]:
        return (ParamSpec("stride", 0.05, "stride", minimum=0.0, maximum=high, unit="m"),)

    assert table(0.08) == table(0.08) and table(0.08) != table(0.1)
    assert validate_parameters(table(0.1), {"stride": 0.09}) == []
    assert validate_parameters(table(0.08), {"stride": 0.09}) != []
    assert ParamSpec("a", 1.5, "").kind is float


def test_ros_descriptor():
    from crawler_motion.runtime.ros_parameters import descriptor

    d = descriptor(RATE)
    assert d.name == "rate" and d.description == "tick rate" and not d.read_only
    assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) == (
        1.0, 1000.0) and not d.integer_range
    d = descriptor(RETRIES)
    assert (d.integer_range[0].from_value, d.integer_range[0].to_value) == (0, 10)
    assert d.integer_range[0].step == 1 and not d.floating_point_range
    d = descriptor(ParamSpec("mode", "hold", "m", read_only=True, choices=("hold", "disable")))
    assert d.read_only and d.additional_constraints == "one of ['hold', 'disable']"
    assert not descriptor(FLAG).integer_range and not descriptor(FLAG).floating_point_range


def test_a_choice_yaml_reads_as_a_bool_is_given_back_as_written() -> None:
    from crawler_motion.runtime.parameters import ParamSpec, choice_from_yaml

    spec = ParamSpec("attitude_mode", "stance_plane", "where", choices=("stance_plane", "imu",
                                                                        "off"))
    assert choice_from_yaml(spec, False) == "off" and choice_from_yaml(spec, "imu") == "imu"
    assert choice_from_yaml(spec, True) is True  # no choice reads as true: refused later
    plain = ParamSpec("flag", False, "a bool")
    assert choice_from_yaml(plain, False) is False
