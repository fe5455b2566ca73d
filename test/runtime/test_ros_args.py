"""Tests of crawler_motion.runtime.ros_args: --ros-args read as rcl reads them, without ROS."""

from __future__ import annotations

from pathlib import Path

import pytest

from crawler_motion.errors import ConfigError
from crawler_motion.runtime.ros_args import parse_ros_args

FILE = """
/**:
  ros__parameters:
    shared: 1
/**/sim:
  ros__parameters:
    rate: 50.0
    group:
      inner: "x"
sim:
  ros__parameters:
    root_only: true
/crawler1/sim:
  ros__parameters:
    rate: 75.0
/*/sim:
  ros__parameters:
    one_level: 2
other:
  ros__parameters:
    rate: 1.0
crawler2:
  sim:
    ros__parameters:
      nested: 3
"""


@pytest.fixture()
def params_file(tmp_path: Path) -> str:
    path = tmp_path / "p.yaml"
    path.write_text(FILE)
    return str(path)


@pytest.mark.parametrize(("args", "expected"), [
    ([], {}),
    (["-p", "rate:=200"], {"rate": 200}),
    (["--param", "rate:=2.5e-3"], {"rate": 0.0025}),
    (["-p", "name:=udp_multicast", "-p", "on:=true", "-p", "empty:="],
     {"name": "udp_multicast", "on": True, "empty": ""}),
    (["-p", "group:=239.1.2.3"], {"group": "239.1.2.3"}),
    (["-p", "sim:rate:=3.0", "-p", "other:rate:=4.0"], {"rate": 3.0}),  # node-specific
    (["-p", "rate:=1.0", "-p", "rate:=2.0"], {"rate": 2.0}),  # the later wins
    (["--log-level", "debug", "--enable-rosout-logs", "-r", "/diagnostics:=/x/diagnostics"],
     {}),
])
def test_parameters_from_the_command_line(args: list[str], expected: dict) -> None:
    ros = parse_ros_args(["--ros-args", *args], "sim")
    assert ros.parameters == expected
    assert ros.explicit == set(expected)


@pytest.mark.parametrize(("remaps", "expected"), [
    ([], {"shared": 1, "rate": 50.0, "group.inner": "x", "root_only": True}),
    (["-r", "__ns:=/crawler1"], {"shared": 1, "rate": 75.0, "group.inner": "x",
                                 "one_level": 2}),
    (["-r", "__ns:=/crawler2"], {"shared": 1, "rate": 50.0, "group.inner": "x",
                                 "one_level": 2, "nested": 3}),
    (["-r", "__ns:=/a/b"], {"shared": 1, "rate": 50.0, "group.inner": "x"}),  # * is one level
    (["-r", "__node:=other"], {"shared": 1, "rate": 1.0}),
    (["-r", "sim:__node:=other"], {"shared": 1, "rate": 1.0}),
    (["-r", "nobody:__node:=other"], {"shared": 1, "rate": 50.0, "group.inner": "x",
                                      "root_only": True}),
])
def test_parameter_file_sections_match_the_node(params_file: str, remaps: list[str],
                                                expected: dict) -> None:
    ros = parse_ros_args(["--ros-args", "--params-file", params_file, *remaps], "sim")
    assert ros.parameters == expected
    assert ros.explicit == set()


def test_the_command_line_after_a_file_wins_and_before_it_loses(params_file: str) -> None:
    after = parse_ros_args(["--ros-args", "--params-file", params_file, "-p", "rate:=9.0"],
                           "sim")
    before = parse_ros_args(["--ros-args", "-p", "rate:=9.0", "--params-file", params_file],
                            "sim")
    assert (after.parameters["rate"], before.parameters["rate"]) == (9.0, 50.0)


@pytest.mark.parametrize(("args", "message"), [
    (["--bogus"], "'--bogus' is not understood"),
    (["-p"], "-p needs a value"),
    (["-p", "rate"], "expected name:=value"),
    (["-r", ":=x"], "expected name:=value"),
    (["--params-file", "/nonexistent/p.yaml"], "--params-file /nonexistent/p.yaml"),
])
def test_bad_ros_args_are_one_clear_error(args: list[str], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_ros_args(["--ros-args", *args], "sim")


def test_a_file_that_is_not_a_parameter_file_is_refused(tmp_path: Path) -> None:
    for text, message in (("- 1\n- 2\n", "not a mapping"), ("sim: 3\n", "must hold a mapping"),
                          ("sim:\n  ros__parameters: 3\n", "must be a mapping")):
        path = tmp_path / "bad.yaml"
        path.write_text(text)
        with pytest.raises(ConfigError, match=message):
            parse_ros_args(["--ros-args", "--params-file", str(path)], "sim")
