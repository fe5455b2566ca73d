"""The ``evaluate`` subcommand: a planned walk replayed through the seabed physics, per cycle."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from crawler_motion.model.config import Config
from crawler_motion.motion.gait import WalkParams
from crawler_motion.sim.seabed.water import Medium
from crawler_motion.sim.seabed.world import DEFAULT_WORLD, worlds_dir

#: Gait cycles evaluated by default (the issue's timing figure is for a 4-step walk).
DEFAULT_STEPS = 4


def add_evaluate_options(p: argparse.ArgumentParser) -> None:
    """The options ``evaluate`` adds to the walk options: world, medium, output format."""
    shipped = ", ".join(sorted(path.stem for path in worlds_dir().glob("*.xml")))
    p.add_argument("--world", default=None,
                   help=f"a shipped world ({shipped}) or an MJCF file (default: "
                        f"{Path(DEFAULT_WORLD).stem})")
    p.add_argument("--medium", choices=[m.value for m in Medium], default=Medium.WATER.value,
                   help="around the robot (default water: 30 %% net weight, drag)")
    p.add_argument("--json", action="store_true",
                   help="print the whole result as JSON instead of the table")


def cmd_evaluate(args: argparse.Namespace, cfg: Config, params: WalkParams) -> int:
    """Replay the walk ``params`` (``args.steps`` cycles) and print its figures."""
    # MuJoCo is imported here, not with the CLI: the other subcommands do not need it.
    from crawler_motion.sim.seabed.evaluate import evaluate_walk, format_table
    from crawler_motion.sim.seabed.model import SimSettings
    from crawler_motion.sim.seabed.water import WaterSettings

    settings = SimSettings(water=WaterSettings(medium=Medium(args.medium)))
    start = time.perf_counter()
    result = evaluate_walk(cfg, params, args.steps, settings, args.world)
    wall = time.perf_counter() - start
    if args.json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
    else:
        label = f"{params.gait} {args.medium} {Path(args.world or DEFAULT_WORLD).stem}"
        print(format_table([(label, result)]))
    print(f"evaluate: {result.sim_time:.1f} s of walk in {wall:.2f} s, "
          f"{result.sim_time / wall:.1f}x real time (physics replay alone "
          f"{result.speedup:.1f}x)", file=sys.stderr)
    return 0
