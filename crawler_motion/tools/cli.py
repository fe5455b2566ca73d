"""The ``crawler-motion`` command line: trajectories, walks, URDF, plots, evaluation, tools.

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
from crawler_motion.motion.walk_options import OPTIONS, WALK_OPTIONS
from crawler_motion.runtime.cli_args import OneLineParser, finite_number
from crawler_motion.tools.args import add_walk_options, check_choice, option_type
from crawler_motion.tools.evaluate import DEFAULT_STEPS, add_evaluate_options, cmd_evaluate

PROG = "crawler-motion"
TRAJECTORY_HEADER = ("t,phase,x,y,z,vx,vy,vz,ax,ay,az,q_root,q_shoulder,q_knee").split(",")
#: The walk options of one leg's cycle (``trajectory``); ``walk`` takes them all.
STEP_OPTIONS = ("profile", "stride", "heading", "lift", "arc", "swing_time", "stance_time")
#: The walk options of ``walk`` (every `WalkParams` field).
WALK_FIELDS = tuple(option.name for option in WALK_OPTIONS if option.name != "steps")


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


def walk_params(args: argparse.Namespace, cfg: Config) -> WalkParams:
    """The walk set by the walk options of ``args`` (the config's defaults for the others)."""
    return WalkParams.defaults(cfg.gait, **{
        name: getattr(args, name) for name in WALK_FIELDS if getattr(args, name) is not None})


def cmd_walk(args: argparse.Namespace, cfg: Config) -> int:
    """Plan a walk and print joint angles and foot positions over time as CSV."""
    plan = plan_walk(cfg, walk_params(args, cfg), args.steps)
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
    """Write the URDF generated from the config (and the leg calibration, if given)."""
    from crawler_motion.model.calibration_file import with_calibration
    from crawler_motion.model.urdf import generate_urdf

    text = generate_urdf(with_calibration(cfg.robot, args.calibration))
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


def _add_common_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rate", type=finite_number("rate", positive=True), default=100.0,
                   help="sample rate [Hz] (default 100)")
    p.add_argument("--config", default=None, help="robot YAML (default: the shipped one)")


def _add_walk_command(p: argparse.ArgumentParser, steps_default: int) -> None:
    """``--steps`` and every walk option of ``walk`` (all from the one option table)."""
    steps = OPTIONS["steps"]
    p.add_argument(steps.flag, type=option_type(steps), default=steps_default,
                   help=f"{steps.help} (default {steps_default})")
    add_walk_options(p, WALK_FIELDS, " (default from config)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``crawler-motion``."""
    parser = OneLineParser(prog=PROG, description="Motion controller of a four-legged crawler.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    p = sub.add_parser("trajectory", help="one cycle of one leg as CSV (t = 0 at lift-off)")
    p.add_argument("--leg", default=None, help="a leg of the config (default: the first)")
    add_walk_options(p, STEP_OPTIONS, " (default from config)")
    _add_common_options(p)
    p.set_defaults(func=cmd_trajectory)
    p = sub.add_parser("walk", help="a whole walk (half steps in and out) as CSV")
    _add_walk_command(p, 2)
    _add_common_options(p)
    p.set_defaults(func=cmd_walk)
    p = sub.add_parser("evaluate", help="a walk replayed through the seabed physics: figures "
                       "per gait cycle (timing on stderr)")
    _add_walk_command(p, DEFAULT_STEPS)
    add_evaluate_options(p)
    p.add_argument("--config", default=None, help="robot YAML (default: the shipped one)")
    p.set_defaults(func=lambda args, cfg: cmd_evaluate(args, cfg, walk_params(args, cfg)))
    p = sub.add_parser("urdf", help="the URDF generated from the robot config")
    p.add_argument("--output", "-o", default=None, help="file to write (default: stdout)")
    p.add_argument("--calibration", default=None, help="leg calibration YAML: per-leg joint "
                   "origins (default: robot.yaml's calibration_file, else nominal)")
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


#: Subcommands implemented in their own modules (they parse their own arguments): the module's
#: ``main``, or ``module:function``.
_EXTRA_COMMANDS: tuple[tuple[str, str, str], ...] = (
    ("console", "crawler_motion.tools.console", "send gait commands/twists, follow the planner"),
    ("demo", "crawler_motion.tools.demo", "the whole stack on a virtual CAN bus, walking"),
    ("bench", "crawler_motion.tools.bench", "benchmarks: timing, bus load (--e2e: whole stack)"),
    ("soak", "crawler_motion.tools.soak", "the whole stack walking for a long time, checked"),
    ("smoothness", "crawler_motion.tools.smoothness",
     "foot-cycle smoothness against other controllers"),
    ("tune-smooth", "crawler_motion.tools.tune_smooth",
     "optimise the smooth profile (needs the [tune] extra)"),
    ("zmp-plot", "crawler_motion.tools.zmp_plot",
     "two steady cycles from above: support lines, planned and measured ZMP, body path"),
    ("rough", "crawler_motion.tools.rough",
     "a walk over a seabed world in the closed loop, blind or with the rough-ground features"),
    ("param-docs", "crawler_motion.tools.param_docs",
     "write docs/parameters.md from the nodes' parameter declarations"),
    ("calibrate", "crawler_motion.tools.calibrate",
     "leg calibration: excitation poses, identification, simulated tracker"),
    ("fk", "crawler_motion.tools.fk", "forward kinematics of one leg: CSV joints in, feet out"),
    ("pose", "crawler_motion.tools.pose",
     "a standing body-pose move (shift and tilt, feet fixed) as CSV"),
    ("map-plot", "crawler_motion.tools.map_plot",
     "walk around obstacles in the simulator: elevation map, path and heading plots"),
    ("path", "crawler_motion.tools.apf_path",
     "plan a path on a map_server map with the improved potential field"),
    ("coverage", "crawler_motion.tools.apf_coverage",
     "plan a coverage route of an area of a map_server map, slice by slice"),
    ("record", "crawler_motion.recording.recorder",
     "record the running stack to a ROS 2 MCAP file (and the CAN bus to a log)"),
    ("report", "crawler_motion.recording.report",
     "a recording as PNG plots and an index.html"),
    ("view", "crawler_motion.recording.view",
     "serve the running stack live to Foxglove (WebSocket)"),
    ("bench-mission", "crawler_motion.tools.bench_mission",
     "the navigator's mission overhead: cycle time and a cover slice's re-plan"),
    ("mission", "crawler_motion.tools.mission",
     "send a mission file (goto, follow, cover, home) to the navigator and follow it"),
    ("sim", "crawler_motion.tools.bringup",
     "bring the simulated robot up: simulator, controller, mapper, navigator; Ctrl-C stops"),
    ("up", "crawler_motion.tools.bringup:main_up",
     "bring the real robot up on its CAN bus: controller, mapper, navigator; Ctrl-C stops"),
)


def _fill_defaults(args: argparse.Namespace, cfg: Config) -> None:
    """The leg and step options ``trajectory`` leaves unset, from the config."""
    if args.leg is None:
        args.leg = cfg.robot.legs[0]
    for name in STEP_OPTIONS:
        default = OPTIONS[name].default
        if getattr(args, name) is None and default is not None:
            setattr(args, name, default(cfg))


def _check_choices(args: argparse.Namespace, cfg: Config) -> None:
    """The options whose choices the config defines (argparse runs before it is loaded)."""
    prog = f"{PROG} {args.command}"
    if getattr(args, "leg", None) is not None:
        check_choice(prog, "--leg", args.leg, cfg.robot.legs)
    if getattr(args, "profile", None) is not None:
        check_choice(prog, "--profile", args.profile, OPTIONS["profile"].allowed(cfg))


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = {name: module for name, module, _ in _EXTRA_COMMANDS}
    if argv and argv[0] in extra:
        import importlib

        module, _, function = extra[argv[0]].partition(":")
        entry = getattr(importlib.import_module(module), function or "main")
        return int(entry(argv[1:]) or 0)
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        cfg = load_config(args.config)
        _check_choices(args, cfg)
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
