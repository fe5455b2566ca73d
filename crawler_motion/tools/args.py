"""The walk options on the command line: argparse types and flags from the one option table."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from crawler_motion.motion.walk_options import OPTIONS, OptionType, Sign, WalkOption
from crawler_motion.runtime.cli_args import finite_number, positive_int


def option_type(option: WalkOption) -> Callable[[str], Any]:
    """The argparse ``type`` of a walk option: its kind and sign, not yet its config range
    (choices are checked by `check_choice` once the config is loaded, or by the planner)."""
    if option.type is OptionType.COUNT:
        return positive_int
    if option.type is OptionType.CHOICE:
        return str
    return finite_number(option.label, positive=option.sign is Sign.POSITIVE,
                         nonneg=option.sign is Sign.NONNEGATIVE)


def add_walk_options(parser: argparse.ArgumentParser, names: Iterable[str],
                     help_suffix: str = "") -> None:
    """Add the ``--flag`` of each walk option in ``names`` (default None: not set)."""
    for name in names:
        option = OPTIONS[name]
        parser.add_argument(option.flag, type=option_type(option), default=None,
                            help=option.described(option.help) + help_suffix)


def check_choice(prog: str, flag: str, value: str, choices: Sequence[str]) -> None:
    """Exit with status 2 and argparse's one-line message if ``value`` is not a choice."""
    if value not in choices:
        shown = ", ".join(repr(choice) for choice in choices)
        sys.stderr.write(f"{prog}: error: argument {flag}: invalid choice: {value!r} "
                         f"(choose from {shown})\n")
        raise SystemExit(2)


def add_gait_option(parser: argparse.ArgumentParser) -> None:
    """``--gait``: a phase table of the shipped robot.yaml (its choices and its default gait
    come from the config, so a table added there is offered here)."""
    from crawler_motion.model.config import load_config

    gait = load_config().gait
    parser.add_argument("--gait", choices=tuple(gait.gaits), default=gait.gait,
                        help=f"gait (a phase table of the config; default {gait.gait})")
