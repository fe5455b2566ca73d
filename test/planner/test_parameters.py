"""The planner node's parameters: declarations from the walk option table, one validator."""

from __future__ import annotations

import math

import pytest

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.motion.attitude import AttitudeMode, AttitudeSettings
from crawler_motion.motion.foothold import FootholdSettings
from crawler_motion.motion.gait import WalkParams, validate_params
from crawler_motion.motion.stumble import StumbleSettings
from crawler_motion.planner.parameters import (
    default_values,
    planner_parameters,
    planner_settings,
)

CFG = load_config()
G = CFG.gait
SPECS = planner_parameters(CFG, "robot.yaml")
BY_NAME = {spec.name: spec for spec in SPECS}


def settings(values):
    return planner_settings(SPECS, values, CFG)


def test_parameter_names_defaults_and_flags():
    assert [spec.name for spec in SPECS] == [
        "config_file", "calibration_file", "rate", "cmd_vel_timeout", "fault_hardware_id",
        "tick_priority", "contact_threshold", "contact_hysteresis", "contact_drive_inertia",
        "contact_period", "foothold_adapt", "foothold_tolerance", "foothold_stop_time",
        "foothold_search_depth", "foothold_search_speed", "foothold_touch_force",
        "stumble_retry", "stumble_force", "stumble_lift", "stumble_retreat",
        "stumble_lift_time", "stumble_stop_time", "attitude_mode", "attitude_max_tilt",
        "attitude_max_lift", "gait", "profile", "stride", "lift", "arc", "swing_time",
        "stance_profile", "margin", "body_height"]
    assert {name for name, spec in BY_NAME.items() if spec.read_only} == {
        "config_file", "calibration_file", "tick_priority"}
    assert default_values(SPECS) == {
        "config_file": "robot.yaml", "calibration_file": "", "rate": 100.0, "cmd_vel_timeout": 0.5,
        "fault_hardware_id": "motor_manager", "tick_priority": 0, "contact_threshold": 0.75,
        "contact_hysteresis": 0.5, "contact_drive_inertia": 0.005, "contact_period": 0.01,
        "foothold_adapt": False, "foothold_tolerance": 0.006, "foothold_stop_time": 0.04,
        "foothold_search_depth": 0.02, "foothold_search_speed": 0.02,
        "foothold_touch_force": 2.0, "stumble_retry": True, "stumble_force": 10.0,
        "stumble_lift": 0.015, "stumble_retreat": 0.0, "stumble_lift_time": 0.12,
        "stumble_stop_time": 0.04, "attitude_mode": "off", "attitude_max_tilt": 0.15,
        "attitude_max_lift": 0.02, "gait": G.gait,
        "profile": G.profile, "stride": G.stride_of(G.gait), "lift": G.lift, "arc": G.arc,
        "swing_time": G.swing_time_of(G.gait), "stance_profile": G.stance_profile_of(G.gait),
        "margin": G.stability_margin,
        "body_height": CFG.robot.body_height}
    assert BY_NAME["stride"].description == "default stride of a new walk [m]"
    assert BY_NAME["body_height"].description == (
        "default standing body height (stand without body_height) [m]")
    assert BY_NAME["gait"].choices == ("diagonal", "diagonal_sway", "diagonal_zmp", "wave")
    assert BY_NAME["profile"].choices == ("rest", "smooth")
    assert BY_NAME["attitude_mode"].choices == ("stance_plane", "imu", "off")


@pytest.mark.parametrize(("name", "lo", "hi"), [
    ("rate", 1.0, 1000.0),
    ("cmd_vel_timeout", 0.05, 10.0),
    ("tick_priority", 0, 99),
    ("stride", 0.0, G.max_stride),
    ("lift", 0.001, G.max_clearance),
    ("arc", 0.0, G.max_clearance),
    ("swing_time", *G.swing_time_range),
    ("body_height", *CFG.robot.body_height_range),
])
def test_parameter_ranges(name, lo, hi):
    assert (BY_NAME[name].minimum, BY_NAME[name].maximum) == (lo, hi)


def test_parameters_defaults_valid():
    s = settings(default_values(SPECS))
    assert s.rate == 100.0 and s.cmd_vel_timeout == 0.5 and s.fault_hardware_id == "motor_manager"
    assert s.tick_priority == 0 and s.config_file == "robot.yaml"
    assert s.foothold == FootholdSettings()
    assert s.defaults == validate_params(WalkParams.defaults(G, body_height=0.07), CFG)


@pytest.mark.parametrize(("change", "fragment"), [
    ({"rate": 0.5}, "rate must be within [1, 1000] Hz, got 0.5"),
    ({"rate": 1000.5}, "rate must be within [1, 1000] Hz, got 1000.5"),
    ({"rate": math.nan}, "rate must be finite, got nan"),
    ({"cmd_vel_timeout": 0.0}, "cmd_vel_timeout must be within [0.05, 10] s, got 0.0"),
    ({"stride": 0.09}, "stride must be within [0, 0.08] m, got 0.09"),
    ({"lift": 0.03, "arc": 0.02}, "gait defaults refused: arc"),
    ({"arc": 0.0}, "gait defaults refused: arc"),  # the smooth profile needs some arc
    ({"gait": "trot"},
     "gait must be one of ['diagonal', 'diagonal_sway', 'diagonal_zmp', 'wave'], got 'trot'"),
    ({"profile": ""}, "profile must be one of ['rest', 'smooth'], got ''"),
    ({"body_height": 0.1}, "body_height must be within [0.05, 0.09] m, got 0.1"),
    ({"fault_hardware_id": " "}, "fault_hardware_id must be a non-empty string"),
    ({"config_file": ""}, "config_file must be"),
    ({"speed": 1.0}, "unknown ['speed']"),
    ({"stride": True}, "stride must be a float, got True"),
    ({"tick_priority": 100}, "tick_priority must be within [0, 99], got 100"),
    ({"foothold_tolerance": -0.001}, "foothold_tolerance must be within [0, 0.05] m"),
    ({"foothold_search_depth": 0.11}, "foothold_search_depth must be within [0, 0.1] m"),
    ({"foothold_adapt": 1}, "foothold_adapt must be a bool, got 1"),
    ({"stumble_force": 100.5}, "stumble_force must be within [0, 100] N"),
    ({"stumble_lift_time": 0.049}, "stumble_lift_time must be within [0.05, 1] s"),
    ({"attitude_mode": "level"}, "attitude_mode must be one of ['stance_plane', 'imu', 'off']"),
    ({"attitude_max_tilt": 0.51}, "attitude_max_tilt must be within [0, 0.5] rad"),
])
def test_parameters_refused(change, fragment):
    values = default_values(SPECS) | change
    with pytest.raises(CommandError) as info:
        settings(values)
    assert fragment in str(info.value)


def test_missing_parameter_refused():
    values = default_values(SPECS)
    del values["rate"]
    with pytest.raises(CommandError, match=r"missing \['rate'\]"):
        settings(values)


def test_parameters_boundaries_accepted():
    lo = default_values(SPECS) | {"rate": 1.0, "cmd_vel_timeout": 0.05, "stride": 0.0,
                                  "lift": 0.001, "arc": 0.0, "swing_time": 0.1,
                                  "body_height": 0.05, "profile": "rest", "tick_priority": 0}
    hi = default_values(SPECS) | {"rate": 1000.0, "cmd_vel_timeout": 10.0,
                                  "stride": 0.08, "lift": 0.03, "arc": 0.01,
                                  "swing_time": 5.0, "body_height": 0.09, "tick_priority": 99}
    assert settings(lo).defaults.body_height == 0.05
    assert settings(hi).rate == 1000.0 and settings(hi).tick_priority == 99
    assert settings(default_values(SPECS) | {"stride": 0}).defaults.stride == 0.0
    edge = settings(default_values(SPECS) | {"foothold_adapt": True, "foothold_search_depth": 0.1,
                                             "foothold_stop_time": 0.005})
    assert edge.foothold == FootholdSettings(enabled=True, search_depth=0.1, stop_time=0.005)
    rough = settings(default_values(SPECS) | {
        "stumble_retry": False, "stumble_force": 0.0, "stumble_lift": 0.05,
        "stumble_retreat": 0.03, "stumble_lift_time": 1.0, "stumble_stop_time": 0.005,
        "attitude_mode": "imu", "attitude_max_tilt": 0.5, "attitude_max_lift": 0.0})
    assert rough.stumble == StumbleSettings(False, 0.0, 0.05, 0.03, 1.0, 0.005)
    assert rough.attitude == AttitudeSettings(AttitudeMode.IMU, 0.5, 0.0)
    assert settings(default_values(SPECS)).stumble == StumbleSettings()
    assert settings(default_values(SPECS)).attitude == AttitudeSettings()


@pytest.mark.parametrize(("change", "expected"), [
    # another gait: its own swing time, stride and stance profile (the walk command's rule)
    ({"gait": "diagonal"}, (G.swing_time, G.stride, G.stance_profile)),
    ({"gait": "diagonal_sway"}, (G.swings["diagonal_sway"], G.stride, G.stance_profile)),
    # a value set with it is kept (one equal to the default gait's own reads as not set)
    ({"gait": "diagonal", "swing_time": 0.55}, (0.55, G.stride, G.stance_profile)),
    ({"gait": "diagonal", "stride": 0.045}, (G.swing_time, 0.045, G.stance_profile)),
    # the default gait: its own
    ({}, (G.swing_time_of(G.gait), G.stride_of(G.gait), G.stance_profile_of(G.gait))),
])
def test_a_gait_parameter_takes_its_tables_own_defaults(change, expected):
    d = settings(default_values(SPECS) | change).defaults
    assert (d.swing_time, d.stride, d.stance_profile) == expected
