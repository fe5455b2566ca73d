"""``crawler-motion path --map MAP.yaml --start X Y --goal X Y [--method apf|apf-virtual]
[--standoff R] [--step S]``: plan a path on a map_server map with the improved potential field.

Prints the path as CSV ``x,y`` (metres, map frame) on stdout and one line on stderr: reached or
trapped (with the reason), length, virtual goals used, minimum clearance of the disc. Exit 0:
reached; 2: trapped; 1: bad input (a missing or malformed map, a start or goal off the map or in
an obstacle, a non-finite number, a bad option), with a one-line error and no path. Unknown
cells of the map count as obstacles. The robot is a disc of the envelope radius of
``robot.yaml`` (``--radius`` to override). ``--plot PNG`` draws the paths of both methods.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from typing import NoReturn

import numpy as np

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.mapping.map_file import FREE, MapData, read_map
from crawler_motion.model.config import load_config
from crawler_motion.navigation.apf.field import FieldSettings, Grid, ObstacleField
from crawler_motion.navigation.apf.planner import (
    ApfMethod,
    PlanResult,
    PlanSettings,
    min_clearance,
    plan,
)
from crawler_motion.navigation.body import envelope_radius
from crawler_motion.runtime.cli_args import OneLineParser

PROG = "crawler-motion path"
#: Exit status of a plan that ends trapped (bad input: 1).
TRAPPED = 2


class Parser(OneLineParser):
    """Usage errors exit 1: status 2 means trapped."""

    def error(self, message: str) -> NoReturn:
        """Print ``<prog>: error: <message>`` and exit with status 1."""
        self.exit(1, f"{self.prog}: error: {message}\n")


def grid_of(data: MapData) -> Grid:
    """The planner's grid of a map: every cell that is not free is an obstacle."""
    return Grid(data.cells != FREE, np.array(data.origin, dtype=float), data.resolution)


def add_field_options(parser: argparse.ArgumentParser) -> None:
    """``--map``, ``--standoff``, ``--step``, ``--radius``, ``--config`` (shared with
    ``coverage``)."""
    parser.add_argument("--map", required=True, help="map_server YAML")
    parser.add_argument("--standoff", type=float, default=FieldSettings.standoff,
                        help="ρ_o: repulsion range and stand-off distance [m]")
    parser.add_argument("--step", type=float, default=PlanSettings.step,
                        help="fixed step s [m]")
    parser.add_argument("--radius", type=float, default=None,
                        help="disc radius [m] (default: the envelope radius of robot.yaml)")
    parser.add_argument("--config", default=None, help="robot.yaml (default: the shipped one)")


def field_of(args: argparse.Namespace) -> ObstacleField:
    """The field of the options (`CrawlerMotionError` for bad values or a bad map)."""
    radius = args.radius if args.radius is not None else envelope_radius(
        load_config(args.config).robot)
    return ObstacleField(grid_of(read_map(args.map)), radius,
                         FieldSettings(standoff=args.standoff))


def summary(res: PlanResult, fld: ObstacleField, seconds: float) -> str:
    """The one stderr line of a plan."""
    outcome = "reached" if res.reached else f"trapped ({res.reason})"
    return (f"{outcome}; length {res.length:.3f} m; virtual goals {len(res.virtual_goals)}; "
            f"min clearance {min_clearance(fld, res.path):.3f} m; planned in {seconds:.3f} s")


def write_csv(points: np.ndarray) -> None:
    """``x,y`` rows [m] on stdout."""
    sys.stdout.write("x,y\n" + "".join(f"{x:.4f},{y:.4f}\n" for x, y in points))


def draw(fld: ObstacleField, start: np.ndarray, goal: np.ndarray, out: str,
         settings: PlanSettings) -> None:
    """A PNG of the map with the paths of both methods, their virtual goals and the disc."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x0, x1, y0, y1 = fld.grid.extent
    fig, ax = plt.subplots(figsize=(4.6, 4.0), dpi=80)
    ax.imshow(fld.grid.obstacle, origin="lower", extent=(x0, x1, y0, y1), cmap="Greys",
              vmax=1.6)
    for method, colour in zip(ApfMethod, ("tab:red", "tab:blue"), strict=True):
        res = plan(fld, start, goal, method, settings)
        label = f"{method.value}: {'reached' if res.reached else 'trapped'}, {res.length:.2f} m"
        ax.plot(*res.path.T, color=colour, lw=1.5, label=label)
        ax.add_patch(plt.Circle(tuple(res.path[-1]), fld.radius, fill=False, color=colour,
                                ls="--", lw=0.8))
        for v in res.virtual_goals:
            ax.plot(*v, "x", color=colour, ms=6)
    ax.plot(*start, "ko", ms=4)
    ax.plot(*goal, "k*", ms=9)
    ax.set(xlabel="x [m]", ylabel="y [m]", aspect="equal")
    ax.legend(loc="lower left", fontsize=7)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = Parser(prog=PROG, description=__doc__.splitlines()[0])
    add_field_options(parser)
    parser.add_argument("--start", type=float, nargs=2, required=True, metavar=("X", "Y"))
    parser.add_argument("--goal", type=float, nargs=2, required=True, metavar=("X", "Y"))
    parser.add_argument("--method", default=ApfMethod.APF_VIRTUAL.value,
                        choices=[m.value for m in ApfMethod])
    parser.add_argument("--plot", default=None, metavar="PNG",
                        help="also draw the paths of both methods (virtual goals: x)")
    args = parser.parse_args(argv)
    try:
        fld = field_of(args)
        begin = time.perf_counter()
        res = plan(fld, np.array(args.start), np.array(args.goal), ApfMethod(args.method),
                   PlanSettings(step=args.step))
        seconds = time.perf_counter() - begin
        if args.plot:
            draw(fld, np.array(args.start), np.array(args.goal), args.plot,
                 PlanSettings(step=args.step))
    except (CrawlerMotionError, OSError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    try:
        write_csv(res.path)
    except BrokenPipeError:
        return 0 if res.reached else TRAPPED
    print(summary(res, fld, seconds), file=sys.stderr)
    return 0 if res.reached else TRAPPED
