"""``crawler-motion zmp-plot``: two steady cycles of a walk seen from above, in the world: the
support lines, the planned and the measured zero-moment point and the body's path.

The walk is replayed through the seabed physics in lock-step (`sim.seabed.replay`, the
evaluator's run). The planned ZMP is the plan's own: the body pose from the planned contact
points held on the ground (`metrics.no_slip_path`, aligned with the measured start), plus the
ZMP in the body frame from the stance feet's planned acceleration. The measured one comes from
the measured body motion (`metrics.measured_zmp`, as the evaluator's).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from crawler_motion.runtime.cli_args import OneLineParser, positive_int
from crawler_motion.tools.args import add_gait_option, add_walk_options

PROG = "crawler-motion zmp-plot"
#: Steady gait cycles drawn.
CYCLES = 2
#: Support lines drawn per slot (evenly in its swing).
LINES_PER_SLOT = 3


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit status."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    add_gait_option(parser)
    add_walk_options(parser, ("heading", "stride"))
    parser.add_argument("--medium", choices=("water", "land"), default="water")
    parser.add_argument("--steps", type=positive_int, default=4, help="gait cycles walked")
    parser.add_argument("--out", type=Path, default=Path("plots") / "zmp_walk.png")
    args = parser.parse_args(argv)
    print(f"wrote {draw(args)}")
    return 0


def draw(args: argparse.Namespace) -> Path:
    """Replay the walk of ``args`` and draw its picture; the PNG's path."""
    import matplotlib

    matplotlib.use("Agg")
    from crawler_motion.model.config import load_config
    from crawler_motion.motion.gait import WalkParams, plan_walk
    from crawler_motion.sim.seabed.evaluate import medium_of
    from crawler_motion.sim.seabed.metrics import (
        measured_zmp,
        no_slip_path,
        plan_phases,
        steady_cycles,
    )
    from crawler_motion.sim.seabed.model import SeabedModel, SimSettings
    from crawler_motion.sim.seabed.replay import replay
    from crawler_motion.sim.seabed.water import Medium, WaterSettings

    settings = SimSettings(water=WaterSettings(medium=Medium(args.medium)))
    cfg = load_config()
    cfg = replace(cfg, medium=medium_of(cfg, settings))
    chosen = {k: getattr(args, k) for k in ("heading", "stride") if getattr(args, k) is not None}
    params = WalkParams.defaults(cfg.gait, gait=args.gait, **chosen)
    plan = plan_walk(cfg, params, args.steps)
    rec = replay(SeabedModel(cfg.robot, settings, None), plan)
    t = rec.time
    phases = plan_phases(plan, t)
    path = no_slip_path(plan, t, phases.stance)  # planned body pose, from the first sample
    omega2 = cfg.medium.omega2(float(plan.slots[0].params.body_height))
    # planned ZMP in the body frame: minus the stance feet's mean acceleration / w²
    acc = np.stack([leg.evaluate(t)[2][:, :2] for leg in plan.contacts], axis=1)
    two = phases.stance.sum(axis=1) == 2
    mean_acc = np.where(two[:, None], (acc * phases.stance[..., None]).sum(axis=1)
                        / np.maximum(phases.stance.sum(axis=1), 1)[:, None], 0.0)
    z_body = mean_acc / omega2 + cfg.medium.zmp_shift
    start = rec.base[0, :2]
    c, s = np.cos(path[:, 2]), np.sin(path[:, 2])
    planned_body = start + path[:, :2]
    planned_zmp = planned_body + np.stack((c * z_body[:, 0] - s * z_body[:, 1],
                                           s * z_body[:, 0] + c * z_body[:, 1]), axis=-1)
    body = rec.base[:, :2]
    measured = measured_zmp(rec, omega2, cfg.medium.zmp_shift)
    cycles = steady_cycles(plan, t)
    k0, k1 = cycles[0][0], cycles[min(CYCLES, len(cycles)) - 1][1]
    lines = [rec.feet[k][phases.stance[k], :2] for k in np.linspace(
        k0, k1 - 1, CYCLES * len(cfg.gait.gaits[params.gait]) * LINES_PER_SLOT).astype(int)
        if two[k]]
    title = f"{params.gait}, {args.medium}: {CYCLES} steady cycles from above"
    return _picture(args.out, title, lines, slice(k0, k1), two,
                    {"planned body": planned_body, "body": body, "planned zmp": planned_zmp,
                     "zmp": measured})


def _picture(out: Path, title: str, lines: list[np.ndarray], part: slice, two: np.ndarray,
             paths: dict[str, np.ndarray]) -> Path:
    """Draw the support ``lines`` and the ``paths`` (world xy [m], samples ``part``; the
    ZMPs where ``two`` feet are down) into ``out``."""
    import matplotlib.pyplot as plt

    planned_body, body = paths["planned body"], paths["body"]
    planned_zmp, measured_zmp = paths["planned zmp"], paths["zmp"]
    fig, ax = plt.subplots(figsize=(8, 4.2))
    for feet in lines:
        ax.plot(feet[:, 0], feet[:, 1], color="0.75", lw=1.0, zorder=1)
    ax.plot([], [], color="0.75", lw=1.0, label="support lines (measured feet)")
    mask = two[part]
    ax.plot(*planned_body[part].T, color="tab:blue", lw=1.5, label="body path, planned")
    ax.plot(*body[part].T, color="tab:blue", lw=1.0, ls="--", label="body path, measured")
    ax.plot(*np.where(mask[:, None], planned_zmp[part], np.nan).T, color="tab:green", lw=1.5,
            label="ZMP, planned")
    ax.plot(*np.where(mask[:, None], measured_zmp[part], np.nan).T, color="tab:red", lw=0.8,
            alpha=0.8, label="ZMP, measured (smoothed 20 ms)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (world)")
    ax.set_ylabel("y [m]")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=7, ncol=2)
    lo, hi = body[part].min(axis=0), body[part].max(axis=0)
    ax.set_ylim(lo[1] - 0.25, hi[1] + 0.25)
    ax.set_xlim(lo[0] - 0.15, hi[0] + 0.15)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
