"""Argument parsing of the console scripts: one-line errors and checked number types."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Sequence
from typing import NoReturn


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are a single line (no usage block, no traceback)."""

    def error(self, message: str) -> NoReturn:
        """Print ``<prog>: error: <message>`` and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message}\n")


def finite_number(kind: str, positive: bool = False, nonneg: bool = False
                  ) -> Callable[[str], float]:
    """An argparse ``type`` accepting a finite float (optionally > 0 or >= 0)."""

    def convert(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{kind} must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{kind} must be finite, got {text!r}")
        if positive and value <= 0:
            raise argparse.ArgumentTypeError(f"{kind} must be > 0, got {text}")
        if nonneg and value < 0:
            raise argparse.ArgumentTypeError(f"{kind} must be >= 0, got {text}")
        return value

    return convert


def positive_int(text: str) -> int:
    """An argparse ``type`` accepting an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def split_ros_args(argv: Sequence[str]) -> tuple[list[str], list[str]]:
    """``argv`` as (the program's own arguments, the ROS arguments): every ``--ros-args``
    section up to its ``--`` (or the end) is ROS's, as rclpy reads it (e.g. ``--ros-args -r
    __ns:=/crawler1``); the ``--`` itself is dropped."""
    own: list[str] = []
    ros: list[str] = []
    inside = False
    for arg in argv:
        if arg == "--ros-args":
            inside = True
            ros.append(arg)
        elif inside and arg == "--":
            inside = False
        else:
            (ros if inside else own).append(arg)
    return own, ros
