"""The ``crawler-motion`` command line: trajectories, walks, URDF, plots (and the ROS tools).

Every failure is one line on stderr and a non-zero exit status, never a traceback.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.model.config import JOINT_KINDS, Config, load_config
from crawler_motion.model.kinematics import inverse_kinematics
from crawler_motion.motion.gait import WalkParams, plan_walk
from crawler_motion.motion.trajectory import Piecewise, SwingShape, step_cycle
from crawler_motion.tools.args import OneLineParser, finite_number, positive_int

PROG = "crawler-motion"
TRAJECTORY_HEADER = ("t,phase,x,y,z,vx,vy,vz,ax,ay,az,q_root,q_shoulder,q_knee").split(",")


def sample_times(duration: float, rate: float) -> np.ndarray:
    """Times from 0 to ``duration`` [s] at ``rate`` [Hz], both ends included."""
    n = math.floor(duration * rate + 1e-9)
    times = np.arange(n + 1) / rate
    if duration - times[-1] > 1e-9:
        times = np.append(times, duration)
    return times


def leg_cycle(cfg: Config, leg: str, profile: str, stride: float, heading: float, lift: float,
              arc: float, swing_time: float, stance_time: float, degree: int = 6) -> Piecewise:
    """One steady-state cycle of ``leg`` starting at lift-off (see trajectory.step_cycle)."""
    if leg not in cfg.robot.legs:
        raise CrawlerMotionError(f"leg '{leg}' unknown; choose one of {list(cfg.robot.legs)}")
    if profile not in cfg.gait.profiles:
        raise CrawlerMotionError(f"profile '{profile}' unknown; choose one of "
                                 f"{sorted(cfg.gait.profiles)}")
    center = cfg.robot.standing_feet()[cfg.robot.legs.index(leg)]
    vec = stride * np.array([math.cos(heading), math.sin(heading)])
    shape = SwingShape(lift, arc, swing_time, cfg.gait.profiles[profile], degree)
    return step_cycle(center, vec, shape, stance_time)


def cmd_trajectory(args: argparse.Namespace, cfg: Config) -> int:
    """Print one cycle of one leg as CSV."""
    pw = leg_cycle(cfg, args.leg, args.profile, args.stride, args.heading, args.lift, args.arc,
                   args.swing_time, args.stance_time)
    t = sample_times(pw.duration, args.rate)
    pos, vel, acc = pw.evaluate(t)
    leg = cfg.robot.legs.index(args.leg)
    feet = np.broadcast_to(cfg.robot.standing_feet(), (len(t), cfg.robot.n_legs, 3)).copy()
    feet[:, leg] = pos
    q = inverse_kinematics(cfg.robot, feet)[:, leg]
    phases = pw.phase_at(t)
    out = csv.writer(sys.stdout, lineterminator="\n")
    out.writerow(TRAJECTORY_HEADER)
    for i, ti in enumerate(t):
        out.writerow([f"{ti:.6f}", phases[i]] + [f"{v:.9g}" for v in (
            *pos[i], *vel[i], *acc[i], *q[i])])
    return 0


def cmd_walk(args: argparse.Namespace, cfg: Config) -> int:
    """Plan a walk and print joint angles and foot positions over time as CSV."""
    params = WalkParams.defaults(
        cfg.gait, **{k: v for k, v in dict(
            gait=args.gait, profile=args.profile, stride=args.stride, heading=args.heading,
            turn=args.turn, lift=args.lift, arc=args.arc, swing_time=args.swing_time,
            stance_time=args.stance_time, body_height=args.body_height).items()
            if v is not None})
    plan = plan_walk(cfg, params, args.steps)
    t = sample_times(plan.duration, args.rate)
    pos, _, _ = plan.evaluate(t)
    q = inverse_kinematics(cfg.robot, pos)
    legs = cfg.robot.legs
    header = ["t", "slot", "kind"] + list(cfg.robot.joint_names) + [
        f"{leg}_foot_{c}" for leg in legs for c in "xyz"]
    out = csv.writer(sys.stdout, lineterminator="\n")
    out.writerow(header)
    for i, ti in enumerate(t):
        k = plan.slot_index(float(ti))
        out.writerow([f"{ti:.6f}", k, plan.slots[k].kind]
                     + [f"{v:.9g}" for v in q[i].ravel()]
                     + [f"{v:.9g}" for v in pos[i].ravel()])
    return 0


def cmd_urdf(args: argparse.Namespace, cfg: Config) -> int:
    """Write the URDF generated from the config."""
    from crawler_motion.model.urdf import generate_urdf

    text = generate_urdf(cfg.robot)
    if args.output:
        Path(args.output).write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)
    return 0


def cmd_plot(args: argparse.Namespace, cfg: Config) -> int:
    """Write the comparison and walk plots as PNG files."""
    from crawler_motion.tools.plots import write_plots

    for path in write_plots(cfg, Path(args.out)):
        print(path)
    return 0


def _add_step_options(p: argparse.ArgumentParser, cfg_defaults: bool = True) -> None:
    p.add_argument("--profile", choices=("rest", "smooth"), default=None if not cfg_defaults
                   else "smooth", help="trajectory profile (default: smooth)")
    p.add_argument("--stride", type=finite_number("stride", nonneg=True), default=None,
                   help="stride length [m] (default from config)")
    p.add_argument("--heading", type=finite_number("heading"), default=None,
                   help="direction of the stride in the body frame [rad] (default 0: forward)")
    p.add_argument("--lift", type=finite_number("lift", positive=True), default=None,
                   help="A->B rise [m]")
    p.add_argument("--arc", type=finite_number("arc", nonneg=True), default=None,
                   help="apex C above B [m]")
    p.add_argument("--swing-time", type=finite_number("swing time", positive=True), default=None,
                   help="swing time [s]")
    p.add_argument("--stance-time", type=finite_number("stance time", positive=True), default=None,
                   help="stance time [s]")
    p.add_argument("--rate", type=finite_number("rate", positive=True), default=100.0,
                   help="sample rate [Hz] (default 100)")
    p.add_argument("--config", default=None, help="robot YAML (default: the shipped one)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``crawler-motion``."""
    parser = OneLineParser(prog=PROG, description="Motion controller of a four-legged crawler.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    p = sub.add_parser("trajectory", help="one cycle of one leg as CSV (t = 0 at lift-off)")
    p.add_argument("--leg", choices=("lf", "lb", "rb", "rf"), default="lf")
    _add_step_options(p)
    p.set_defaults(func=cmd_trajectory)
    p = sub.add_parser("walk", help="a whole walk (half steps in and out) as CSV")
    p.add_argument("--steps", type=positive_int, default=2, help="gait cycles (default 2)")
    p.add_argument("--gait", default=None, help="diagonal | wave (default from config)")
    p.add_argument("--turn", type=finite_number("turn"), default=None, help="yaw per step [rad]")
    p.add_argument("--body-height", type=finite_number("body height", positive=True), default=None,
                   help="hip height above the ground [m]")
    _add_step_options(p, cfg_defaults=False)
    p.set_defaults(func=cmd_walk)
    p = sub.add_parser("urdf", help="the URDF generated from the robot config")
    p.add_argument("--output", "-o", default=None, help="file to write (default: stdout)")
    p.add_argument("--config", default=None, help="robot YAML (default: the shipped one)")
    p.set_defaults(func=cmd_urdf)
    p = sub.add_parser("plot", help="PNG plots: rest vs smooth vs quartic, joints over a walk")
    p.add_argument("--out", default="plots", help="output directory (default ./plots)")
    p.add_argument("--config", default=None, help="robot YAML (default: the shipped one)")
    p.set_defaults(func=cmd_plot)
    for name, module, text in _EXTRA_COMMANDS:
        p = sub.add_parser(name, help=text, add_help=False)
        p.set_defaults(func=None, module=module)
    return parser


#: Subcommands implemented in their own modules (they parse their own arguments).
_EXTRA_COMMANDS: tuple[tuple[str, str, str], ...] = (
    ("console", "crawler_motion.tools.console", "send gait commands/twists, follow the planner"),
    ("demo", "crawler_motion.tools.demo", "the whole stack on a virtual CAN bus, walking"),
)


def _fill_defaults(args: argparse.Namespace, cfg: Config) -> None:
    g = cfg.gait
    defaults = {"stride": g.stride, "heading": 0.0, "lift": g.lift, "arc": g.arc,
                "swing_time": g.swing_time, "stance_time": g.stance_time}
    for key, value in defaults.items():
        if getattr(args, key, "absent") is None:
            setattr(args, key, value)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = {name: module for name, module, _ in _EXTRA_COMMANDS}
    if argv and argv[0] in extra:
        import importlib

        return int(importlib.import_module(extra[argv[0]]).main(argv[1:]) or 0)
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        cfg = load_config(args.config)
        if args.command == "trajectory":
            _fill_defaults(args, cfg)
        return int(args.func(args, cfg))
    except CrawlerMotionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # e.g. piped into `head`
        return 0
    except OSError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())

__all__ = ["JOINT_KINDS", "main"]
