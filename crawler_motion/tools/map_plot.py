"""``crawler-motion map-plot``: walk to a goal in the seabed simulator and draw the map and the
path. By default on the real-time stack (every process of ``crawler-motion sim`` in real
time: the published ``terrain_map``, `map_plot_live`); with ``--lockstep`` in the lock-step
closed loop (one process, simulated time: the elevation map with the robot, its virtual circle
and its path, and the heading over time, the study's Fig. 8 for the crawler, with timings)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from crawler_motion.model.config import load_config
from crawler_motion.navigation.navigator import NavigatorSettings
from crawler_motion.navigation.steering import Steering
from crawler_motion.runtime.cli_args import OneLineParser, finite_number
from crawler_motion.testing.avoidance_loop import AvoidanceLoop, LoopResult

PROG = "crawler-motion map-plot"


def summary(res: LoopResult) -> str:
    """The figures of a run, one per line."""
    m, n = np.array(res.map_ms), np.array(res.nav_ms)
    return "\n".join([
        f"outcome: {res.state} ({res.reason})",
        f"final distance to the goal: {res.final_error:.3f} m; walk: {res.walk_time:.1f} s "
        "simulated",
        f"virtual circle to the nearest obstacle cell: min {min(res.clearance):.3f} m",
        f"hull or leg contact: {res.contact_samples} of the control ticks",
        f"map update per scan (fuse + obstacle cells): median {np.median(m):.2f} ms, "
        f"p95 {np.percentile(m, 95):.2f} ms, max {m.max():.2f} ms over {len(m)} scans",
        f"navigator cycle: median {np.median(n):.2f} ms, p95 {np.percentile(n, 95):.2f} ms, "
        f"max {n.max():.2f} ms",
        f"planner refusals: {len(res.refusals)}"])


def draw_map(res: LoopResult, out: Path) -> None:
    """Elevation map, obstacle cells, path, virtual circles and goal."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mapper = res.mapper
    assert mapper is not None
    g = mapper.grid
    heights = np.where(g.known, g.height, np.nan) * 100
    extent = (g.origin[0], g.origin[0] + g.size, g.origin[1], g.origin[1] + g.size)
    fig, ax = plt.subplots(figsize=(5.5, 4.5), dpi=80)
    im = ax.imshow(heights, origin="lower", extent=extent, cmap="viridis")
    fig.colorbar(im, ax=ax, label="fused height [cm] (white: unknown)")
    obst = np.where(mapper.obstacles(), 1.0, np.nan)
    ax.imshow(obst, origin="lower", extent=extent, cmap="Reds", vmin=0, vmax=1, alpha=0.8)
    path = np.array(res.path)
    ax.plot(path[:, 0], path[:, 1], "w-", lw=1.5, label="body path")
    for k in range(0, len(path), max(1, len(path) // 8)):
        ax.add_patch(plt.Circle(path[k, :2], res.radius[k], fill=False, color="w", lw=0.6))
    ax.plot(*res.goal, "r*", ms=12, label="goal")
    ax.set(xlabel="x [m] (odom)", ylabel="y [m]", title="terrain map, obstacle cells (red)")
    lo, hi = path[:, :2].min(axis=0) - 0.5, path[:, :2].max(axis=0) + 0.5
    ax.set_xlim(lo[0], max(hi[0], res.goal[0] + 0.3))
    ax.set_ylim(lo[1], hi[1])
    ax.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def draw_heading(res: LoopResult, out: Path) -> None:
    """Heading and body yaw [deg] over time, the rule shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.array(res.time) - res.time[0]
    heading = np.degrees(np.array(res.heading))
    yaw = np.degrees([p[2] for p in res.path])
    fig, ax = plt.subplots(figsize=(6, 3), dpi=80)
    ax.plot(t, heading, label="computed heading (odom)")
    ax.plot(t, yaw, label="body yaw")
    goal_dir = [math.degrees(math.atan2(res.goal[1] - p[1], res.goal[0] - p[0]))
                for p in res.path]
    ax.plot(t, goal_dir, "k:", lw=1, label="goal direction")
    ax.set(xlabel="time [s]", ylabel="angle [deg]",
           title="heading around the wall and back to the goal")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    """Run, print the figures, write the pictures."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="low_wall", help="world name or file")
    parser.add_argument("--goal", nargs=2, type=finite_number("goal"), default=(1.6, 0.0),
                        metavar=("X", "Y"), help="goal in odom [m] (default 1.6 0)")
    parser.add_argument("--steering", choices=[s.value for s in Steering], default="crab")
    parser.add_argument("--limit", type=finite_number("limit", positive=True), default=120.0,
                        help="time limit [s]")
    parser.add_argument("--out", type=Path, default=Path("terrain_map.png"))
    parser.add_argument("--heading-out", type=Path, default=None,
                        help="also draw the heading over time here (--lockstep)")
    parser.add_argument("--lockstep", action="store_true", help="the one-process lock-step "
                        "loop in simulated time (a design aid) instead of the real-time stack")
    parser.add_argument("--method", choices=("virtual_body", "apf"), default="virtual_body",
                        help="navigator method (real-time stack)")
    parser.add_argument("--start", nargs=3, type=finite_number("start"), default=(0, 0, 0),
                        metavar=("X", "Y", "YAW"), help="start pose (real-time stack)")
    args = parser.parse_args(argv)
    if not args.lockstep:
        from crawler_motion.tools.map_plot_live import run_live

        return run_live(args)
    loop = AvoidanceLoop(load_config(), args.world,
                         NavigatorSettings(steering=Steering(args.steering)))
    res = loop.run(tuple(args.goal), limit=args.limit)
    print(summary(res))
    draw_map(res, args.out)
    print(f"map: {args.out}")
    if args.heading_out is not None:
        draw_heading(res, args.heading_out)
        print(f"heading: {args.heading_out}")
    return 0 if res.state == "ARRIVED" else 1
