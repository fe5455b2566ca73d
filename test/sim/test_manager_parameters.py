"""Tests of crawler_motion.sim.manager_parameters: --ros-args of motor_manager_sim as its
options."""

from __future__ import annotations

import pytest

from crawler_motion.errors import ConfigError
from crawler_motion.runtime.ros_args import RosArgs
from crawler_motion.sim.manager_cli import _parser
from crawler_motion.sim.manager_parameters import MANAGER_PARAMETERS, OPTIONS, manager_flags


def _ros(params: dict, explicit: bool = True) -> RosArgs:
    return RosArgs("motor_manager_sim", parameters=dict(params),
                   explicit=set(params) if explicit else set())


@pytest.mark.parametrize(("params", "flags"), [
    ({}, []),
    ({"can_interface": "socketcan", "can_channel": "vcan0"},
     ["--interface", "socketcan", "--channel", "vcan0"]),
    ({"can_port": 4242, "speed_limit": 3, "command_timeout": 0.5},
     ["--port", "4242", "--speed-limit", "3", "--command-timeout", "0.5"]),
    ({"can_port": 0, "rate": 0.0, "heartbeat_period": 0.0, "dbc_file": ""}, []),  # defaults
    ({"rate": 200.0, "heartbeat_period": 0.05}, ["--rate", "200.0", "--heartbeat-period",
                                                 "0.05"]),
    ({"effort": True}, []), ({"effort": False}, ["--no-effort"]),
    ({"initial_pose": "zero", "config_file": "r.yaml"},
     ["--initial-pose", "zero", "--config", "r.yaml"]),
])
def test_parameters_become_the_options(params: dict, flags: list[str]) -> None:
    assert manager_flags(_ros(params)) == flags


@pytest.mark.parametrize(("params", "message"), [
    ({"bogus": 1}, "unknown parameters \\['bogus'\\]"),
    ({"speed_limit": 0.0}, "speed_limit must be within"),
    ({"speed_limit": "fast"}, "speed_limit must be a float"),
    ({"initial_pose": "up"}, "initial_pose must be one of"),
    ({"can_port": 70000}, "can_port must be within"),
])
def test_bad_parameters_are_refused(params: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        manager_flags(_ros(params))


def test_a_parameter_files_names_for_other_nodes_are_left_to_them() -> None:
    assert manager_flags(_ros({"autostart": True, "speed_limit": 1.5}, explicit=False)) == [
        "--speed-limit", "1.5"]


def test_every_parameter_is_one_option_of_the_program() -> None:
    options = {o for action in _parser()._actions for o in action.option_strings}
    assert set(OPTIONS) == {spec.name for spec in MANAGER_PARAMETERS}
    assert set(OPTIONS.values()) <= options
