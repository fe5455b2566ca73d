"""``crawler-motion pose``: the body-pose move from the neutral standing pose, as CSV.

The same move the planner makes for ``{"command": "pose", ...}`` from STANDING (options left
out are 0; the flags come from the one option table): time, the pose, the joint angles and the
foot targets in base_link (every foot fixed on the ground). A pose beyond its limits or a
foot's workspace is one line on stderr and exit status 1.

    crawler-motion pose --x 0.01 --roll 0.05 --rate 50
"""

from __future__ import annotations

import csv
import sys
from collections.abc import Sequence

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.model.config import load_config
from crawler_motion.motion.body_pose import NEUTRAL, POSE_FIELDS, BodyPose, plan_pose_move
from crawler_motion.runtime.cli_args import OneLineParser, finite_number
from crawler_motion.tools.args import add_walk_options
from crawler_motion.tools.cli import sample_times

PROG = "crawler-motion pose"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    add_walk_options(parser, POSE_FIELDS, " (default 0)")
    add_walk_options(parser, ("body_height",), " (default from config)")
    parser.add_argument("--rate", type=finite_number("rate", positive=True), default=100.0,
                        help="sample rate [Hz] (default 100)")
    parser.add_argument("--config", default=None, help="robot YAML (default: the shipped one)")
    args = parser.parse_args(argv)
    try:
        cfg = load_config(args.config)
        body_height = cfg.robot.body_height if args.body_height is None else args.body_height
        pose = BodyPose(**{name: getattr(args, name) or 0.0 for name in POSE_FIELDS})
        path = plan_pose_move(cfg, body_height, NEUTRAL, pose)
    except CrawlerMotionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    t = sample_times(path.duration, args.rate)
    poses = path.pose(t)[0]
    feet = path.feet(t)[0]
    q, _ = path.joints(t)
    robot = cfg.robot
    out = csv.writer(sys.stdout, lineterminator="\n")
    try:
        out.writerow(["t", *POSE_FIELDS, *robot.joint_names,
                      *(f"{leg}_foot_{c}" for leg in robot.legs for c in "xyz")])
        for i, ti in enumerate(t):
            out.writerow([f"{ti:.6f}"] + [f"{v:.9g}" for v in (*poses[i], *q[i].ravel(),
                                                              *feet[i].ravel())])
    except BrokenPipeError:  # e.g. piped into `head`
        return 0
    return 0
