"""``crawler-motion fk --leg L [--calibration FILE]``: the planner's forward kinematics of one
leg, CSV ``q_root,q_shoulder,q_knee`` [rad] on stdin to ``x,y,z`` [m, base_link] on stdout."""

from __future__ import annotations

import sys
from collections.abc import Sequence

import numpy as np

from crawler_motion.calibration import csvio, study
from crawler_motion.errors import CrawlerMotionError
from crawler_motion.model.calibration_file import with_calibration
from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.runtime.cli_args import OneLineParser

PROG = "crawler-motion fk"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--leg", required=True)
    parser.add_argument("--calibration", default=None, help="leg calibration YAML")
    parser.add_argument("--config", default=None, help="robot.yaml (default: the shipped one)")
    args = parser.parse_args(argv)
    try:
        robot = with_calibration(load_config(args.config).robot, args.calibration)
        leg = study.leg_index(robot, args.leg)
        poses = csvio.parse_rows(sys.stdin, csvio.POSE_HEADER, "stdin")
        study.check_poses(robot, poses, "stdin")
        angles = np.broadcast_to(0.5 * (robot.lower + robot.upper),
                                 (len(poses), robot.n_legs, 3)).copy()
        angles[:, leg] = poses
        feet = forward_kinematics(robot, angles)[:, leg]
    except (CrawlerMotionError, OSError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    sys.stdout.write(csvio.format_rows(feet, csvio.FOOT_HEADER))
    return 0
