"""``crawler-motion calibrate poses|identify|simulate|report``: leg kinematic calibration.

Every failure is one line on stderr and exit status 1; nothing is written then.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

from crawler_motion.calibration import csvio, report, session, session_report, study, synthetic
from crawler_motion.calibration.identify import RLS_MAX_PASSES, Method
from crawler_motion.calibration.jacobian import leg_feet
from crawler_motion.calibration.readings import Readings, format_readings, read_readings
from crawler_motion.errors import CrawlerMotionError
from crawler_motion.model.calibration_file import (
    LegCalibration,
    load_calibration,
    nominal_calibration,
    with_calibration,
    write_calibration,
)
from crawler_motion.model.config import RobotConfig, load_config
from crawler_motion.model.rotations import rpy_matrix
from crawler_motion.runtime.cli_args import OneLineParser, finite_number, positive_int

PROG = "crawler-motion calibrate"


def build_parser() -> argparse.ArgumentParser:
    """The ``calibrate`` argument parser and its three subcommands."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=None, help="robot.yaml (default: the shipped one)")
    sub = parser.add_subparsers(dest="action", required=True)
    poses = sub.add_parser("poses", help="optimised excitation poses, CSV on stdout")
    poses.add_argument("--leg", required=True)
    poses.add_argument("--candidates", type=positive_int, default=200)
    poses.add_argument("--count", type=positive_int, default=50)
    poses.add_argument("--seed", type=int, default=0)
    poses.add_argument("--harmonics", type=positive_int, default=5)
    poses.add_argument("--calibration", default=None,
                       help="the leg's current calibration YAML (default: robot.yaml's)")
    ident = sub.add_parser("identify", help="identify legs from measured feet")
    ident.add_argument("--measurements", default=None, help="CSV leg,q_root,q_shoulder,q_knee,"
                       "x,y,z [rad, m]: every leg of a session (instead of --leg, --poses, "
                       "--measured)")
    ident.add_argument("--frame", choices=("body", "tracker"), default="body",
                       help="frame of the readings; tracker: its pose is identified too")
    ident.add_argument("--target-offset", nargs=3, type=finite_number("--target-offset"),
                       default=(0.0, 0.0, 0.0), metavar=("X", "Y", "Z"),
                       help="the target's offset from the foot tip [m]: x from the knee axis "
                       "to the foot tip, y along the knee axis, z completing")
    ident.add_argument("--max-noise", type=finite_number("--max-noise", positive=True),
                       default=1e-4, help="largest robust tracker noise sigma per axis [m] a "
                       "session may show (default 1e-4)")
    ident.add_argument("--leg", default=None)
    ident.add_argument("--poses", default=None, help="CSV q_root,q_shoulder,q_knee [rad]")
    ident.add_argument("--measured", default=None, help="CSV x,y,z [m] in base_link")
    ident.add_argument("--method", choices=[m.value for m in Method], default=None,
                       help="--leg form: rls, de or rls-de (default); --measurements: rls")
    ident.add_argument("--out", required=True, help="calibration YAML (merged if it exists)")
    ident.add_argument("--seed", type=int, default=0)
    ident.add_argument("--calibration", default=None, help="the current calibration YAML: "
                       "the starting geometry and the 'before' column (default: robot.yaml's)")
    sim = sub.add_parser("simulate", help="tracker readings of a 'true' robot, CSV on stdout")
    sim.add_argument("--leg", required=True, help="a leg, or legs separated by commas, or "
                     "'all'; more than one (or --tracker): a --measurements CSV")
    sim.add_argument("--tracker", nargs=6, type=finite_number("--tracker"), default=None,
                     metavar=("X", "Y", "Z", "ROLL", "PITCH", "YAW"),
                     help="readings in a tracker's frame at this pose in base_link [m, rad]")
    sim.add_argument("--poses", required=True, help="CSV q_root,q_shoulder,q_knee [rad]")
    sim.add_argument("--true", default=None, help="the true robot's calibration YAML")
    sim.add_argument("--perturb-seed", type=int, default=None,
                     help="instead of --true: random assembly errors with this seed")
    sim.add_argument("--write-true", default=None, help="write the perturbed robot's YAML")
    sim.add_argument("--noise", type=finite_number("--noise", nonneg=True), default=0.0,
                     help="tracker noise per axis [m] (default 0)")
    sim.add_argument("--seed", type=int, default=0)
    rep = sub.add_parser("report", help="the study's comparison on simulated legs, per leg")
    rep.add_argument("--perturb-seed", type=int, default=1, help="the true legs' errors")
    rep.add_argument("--noise", type=finite_number("--noise", nonneg=True), action="append",
                     help="tracker noise per axis [m]; repeat (default: 0 and 2e-5)")
    rep.add_argument("--seed", type=int, default=0)
    rep.add_argument("--rls-passes", type=positive_int, default=RLS_MAX_PASSES,
                     help=f"most RLS re-linearisations (default {RLS_MAX_PASSES}; 1: one pass "
                          f"over the poses, as the study's RLS)")
    return parser


def _poses(robot: RobotConfig, path: str) -> np.ndarray:
    poses = csvio.read_rows(path, csvio.POSE_HEADER)
    study.check_poses(robot, poses, path)
    return poses


def cmd_poses(args: argparse.Namespace, robot: RobotConfig) -> int:
    """Print the selected poses; the condition numbers on stderr."""
    leg = study.leg_index(robot, args.leg)
    if args.count > args.candidates:
        raise CrawlerMotionError(f"--count {args.count} exceeds --candidates {args.candidates}")
    sel = study.select_poses(robot, leg, args.candidates, args.count, args.seed, args.harmonics)
    sys.stdout.write(csvio.format_rows(sel.poses, csvio.POSE_HEADER))
    print(f"{PROG} poses: condition number {sel.condition:.2f} of the {args.count} selected "
          f"poses; median of 101 random {args.count}-of-{args.candidates} selections "
          f"{sel.random_median:.2f}", file=sys.stderr)
    return 0


def cmd_identify(args: argparse.Namespace, robot: RobotConfig) -> int:
    """Identify, print the report, write the legs' parameters into ``--out``."""
    if args.measurements is not None:
        if any(v is not None for v in (args.leg, args.poses, args.measured)):
            raise CrawlerMotionError("give --measurements or --leg/--poses/--measured, not both")
        return _identify_session(args, robot)
    if None in (args.leg, args.poses, args.measured):
        raise CrawlerMotionError("give --measurements FILE, or --leg, --poses and --measured")
    if args.frame == "tracker" or any(args.target_offset):
        raise CrawlerMotionError("--frame tracker and --target-offset need --measurements FILE "
                                 "(leg,q_root,q_shoulder,q_knee,x,y,z)")
    leg = study.leg_index(robot, args.leg)
    poses = _poses(robot, args.poses)
    measured = csvio.read_rows(args.measured, csvio.FOOT_HEADER)
    if len(poses) != len(measured):
        raise CrawlerMotionError(f"{len(poses)} poses but {len(measured)} measured feet: one "
                                 f"measurement per pose")
    existing = _existing(args.out, robot)
    rows = Readings(np.full(len(poses), leg), poses, measured, np.arange(1, len(poses) + 1))
    screen = session.robust_fit(robot, rows, _start(robot), np.zeros(3), tracker=False)
    session.check_fit(screen, rows, args.max_noise, args.measured, "pose")
    keep = ~screen.outliers
    comp = study.compare(robot, leg, poses[keep], measured[keep], args.seed)
    method = args.method or Method.RLS_DE.value
    calib = existing.with_leg(args.leg, comp.fits[method].params)
    print(comp.identifiability.describe())
    print(session_report.outlier_line(rows, screen, "pose"))
    print(study.format_table(comp))
    write_calibration(args.out, calib)
    print(f"{PROG} identify: leg {args.leg} ({method}) written to {args.out}",
          file=sys.stderr)
    return 0


def _start(robot: RobotConfig) -> np.ndarray:
    """Every leg's current parameters ``(n_legs, N_PARAMS)`` (robot.yaml's or --calibration)."""
    geometry = robot.geometry or nominal_calibration(robot.legs, (robot.l1, robot.l2, robot.l3))
    return geometry.params


def _identify_session(args: argparse.Namespace, robot: RobotConfig) -> int:
    """Every measured leg (and the tracker's pose) from one measurement file."""
    if args.method not in (None, Method.RLS.value):
        raise CrawlerMotionError("--measurements identifies the legs together by least "
                                 "squares (rls); --method de / rls-de need the --leg form")
    readings = read_readings(args.measurements, robot)
    tracker, offset = args.frame == "tracker", np.array(args.target_offset, dtype=float)
    start = _start(robot)
    fit = session.robust_fit(robot, readings, start, offset, tracker)
    session.check_fit(fit, readings, args.max_noise, args.measurements)
    calib = _existing(args.out, robot)
    for leg in fit.layout.columns:
        calib = calib.with_leg(robot.legs[leg], fit.state.params[leg])
    before = session.start_state(robot, readings.subset(~fit.outliers), start, offset, tracker)
    print(session_report.describe(robot, readings, fit, before, offset))
    write_calibration(args.out, calib)
    legs = ", ".join(robot.legs[leg] for leg in fit.layout.columns)
    print(f"{PROG} identify: legs {legs} ({args.frame} frame, least squares) written to "
          f"{args.out}", file=sys.stderr)
    return 0


def _existing(path: str, robot: RobotConfig) -> LegCalibration:
    from pathlib import Path

    links = (robot.l1, robot.l2, robot.l3)
    if Path(path).exists():
        return load_calibration(path, robot.legs, links)
    return robot.geometry or nominal_calibration(robot.legs, links)


def cmd_simulate(args: argparse.Namespace, robot: RobotConfig) -> int:
    """Print the true robot's feet at the poses, with tracker noise: x,y,z of one leg, or a
    --measurements CSV of several legs (every leg at every pose) or in a tracker's frame."""
    names = list(robot.legs) if args.leg == "all" else args.leg.split(",")
    legs = [study.leg_index(robot, name) for name in names]
    if (args.true is None) == (args.perturb_seed is None):
        raise CrawlerMotionError("give exactly one of --true FILE and --perturb-seed N")
    poses = _poses(robot, args.poses)
    true = (with_calibration(robot, args.true) if args.true is not None
            else synthetic.perturbed_robot(robot, args.perturb_seed))
    assert true.geometry is not None
    feet = np.concatenate([leg_feet(robot, leg, true.geometry.params[leg], poses)
                           for leg in legs])
    if args.tracker is not None:
        rotation = rpy_matrix(np.array(args.tracker[3:]))
        feet = (feet - np.array(args.tracker[:3])) @ rotation
    feet = synthetic.measure(feet, args.noise, np.random.default_rng(args.seed))
    if args.write_true is not None:
        write_calibration(args.write_true, true.geometry)
    if len(legs) == 1 and args.tracker is None:
        sys.stdout.write(csvio.format_rows(feet, csvio.FOOT_HEADER))
    else:
        index = np.repeat(np.array(legs), len(poses))
        rows = Readings(index, np.tile(poses, (len(legs), 1)), feet, np.arange(len(feet)))
        sys.stdout.write(format_readings(robot, rows))
    return 0


def cmd_report(args: argparse.Namespace, robot: RobotConfig) -> int:
    """Print the comparison tables of every leg at every tracker noise."""
    true = synthetic.perturbed_robot(robot, args.perturb_seed)
    assert true.geometry is not None
    for leg in range(robot.n_legs):
        sel = None
        for noise in args.noise or (0.0, 2e-5):
            rep = report.leg_report(robot, leg, true.geometry.params[leg], noise, args.seed, sel,
                                    args.rls_passes)
            sel = rep.selection
            print(report.format_report(rep) + "\n")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        robot = with_calibration(load_config(args.config).robot,
                                 getattr(args, "calibration", None))
        if robot.geometry is not None and robot.geometry.note:
            print(f"{PROG}: note: {robot.geometry.note}", file=sys.stderr)
        return {"poses": cmd_poses, "identify": cmd_identify,
                "simulate": cmd_simulate, "report": cmd_report}[args.action](args, robot)
    except (CrawlerMotionError, OSError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
