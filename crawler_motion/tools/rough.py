"""``crawler-motion rough``: a walk over a seabed world in the closed loop (lock-step physics, the
planner core with its foot contacts), blind or with the rough-ground features, and its figures.

Unlike ``evaluate`` (the plan replayed open loop), the planner reacts to the simulated efforts
here: the terrain-adaptive touch-down, the stumble retry and the body attitude act as on the
robot (`testing.foothold_loop`). Deterministic: simulated time, no ROS.
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Sequence

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.model.config import load_config
from crawler_motion.motion.attitude import AttitudeMode, AttitudeSettings
from crawler_motion.motion.foothold import FootholdSettings
from crawler_motion.motion.stumble import StumbleSettings
from crawler_motion.runtime.cli_args import OneLineParser, positive_int
from crawler_motion.tools.args import add_walk_options

PROG = "crawler-motion rough"
#: Steps walked by default: enough for the rear feet to cross the step world's step.
DEFAULT_STEPS = 6


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    from crawler_motion.tools.cli import WALK_FIELDS, walk_params

    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    add_walk_options(parser, WALK_FIELDS)
    parser.add_argument("--steps", type=positive_int, default=DEFAULT_STEPS,
                        help=f"gait cycles (default {DEFAULT_STEPS})")
    parser.add_argument("--world", default="step", help="a shipped world or an MJCF file "
                        "(default step)")
    parser.add_argument("--foothold-adapt", action="store_true",
                        help="the terrain-adaptive touch-down (planner foothold_adapt); "
                             "without it: blind, and the options below do nothing")
    parser.add_argument("--stumble-retry", choices=("on", "off"), default="on",
                        help="the stumble retry (planner stumble_retry; default on)")
    parser.add_argument("--attitude", choices=[m.value for m in AttitudeMode],
                        default=AttitudeSettings().mode.value,
                        help="body attitude (planner attitude_mode; imu: the simulated IMU)")
    parser.add_argument("--config", default=None, help="robot.yaml (default: the shipped one)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args(argv)
    try:
        # MuJoCo is imported here, not with the CLI: the other subcommands do not need it.
        from crawler_motion.testing.foothold_loop import FootholdLoop

        cfg = load_config(args.config)
        params = walk_params(args, cfg)
        loop = FootholdLoop(cfg, args.world, FootholdSettings(enabled=args.foothold_adapt),
                            stumble=StumbleSettings(enabled=args.stumble_retry == "on"),
                            attitude=AttitudeSettings(mode=AttitudeMode(args.attitude)))
        start = time.perf_counter()
        rec = loop.walk(params, args.steps)
        wall = time.perf_counter() - start
    except CrawlerMotionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    figures = {
        "advance_ratio": round(rec.advance_ratio, 3),
        "roll_max": round(math.degrees(rec.max_roll), 2),
        "pitch_max": round(math.degrees(rec.max_pitch), 2),
        "yaw_per_cycle": round(math.degrees(rec.yaw_change) / args.steps, 2),
        "torque_max": round(rec.max_torque, 3),
        "state": rec.state,
        "events": [e for e in rec.events if not e.startswith("info")],
    }
    if args.json:
        print(json.dumps(figures, indent=2))
    else:
        mode = (f"adapt, stumble {args.stumble_retry}, attitude {args.attitude}"
                if args.foothold_adapt else "blind")
        print(f"{params.gait} {args.world} ({mode}): advance {figures['advance_ratio']:.2f}, "
              f"roll {figures['roll_max']:.1f}°, pitch {figures['pitch_max']:.1f}°, yaw "
              f"{figures['yaw_per_cycle']:+.2f}°/cycle, torque max "
              f"{rec.max_torque * 100:.0f} % of the limit, {rec.state}")
        for event in figures["events"]:
            print(f"  {event}")
    print(f"{PROG}: {rec.time[-1] - rec.time[0]:.1f} s of walk in {wall:.1f} s",
          file=sys.stderr)
    return 0
