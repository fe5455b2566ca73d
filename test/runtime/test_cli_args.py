"""Tests of crawler_motion.runtime.cli_args.split_ros_args."""

from __future__ import annotations

import pytest

from crawler_motion.runtime.cli_args import split_ros_args


@pytest.mark.parametrize(("argv", "own", "ros"), [
    ([], [], []),
    (["stand", "--timeout", "5"], ["stand", "--timeout", "5"], []),
    (["stand", "--ros-args", "-r", "__ns:=/c1"], ["stand"], ["--ros-args", "-r", "__ns:=/c1"]),
    (["--ros-args", "-p", "a:=1", "--", "walk", "--steps", "2"], ["walk", "--steps", "2"],
     ["--ros-args", "-p", "a:=1"]),
    (["x", "--ros-args", "-p", "a:=1", "--", "y", "--ros-args", "-p", "b:=2"], ["x", "y"],
     ["--ros-args", "-p", "a:=1", "--ros-args", "-p", "b:=2"]),
    (["--", "x"], ["--", "x"], []),  # a -- outside --ros-args is the program's
])
def test_split_ros_args(argv: list[str], own: list[str], ros: list[str]) -> None:
    assert split_ros_args(argv) == (own, ros)
