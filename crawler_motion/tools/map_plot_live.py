"""``crawler-motion map-plot`` on the real-time stack (its default): the simulated robot's
processes in real time walk to the goal; the published ``terrain_map`` (obstacle, free,
unknown), the walked path (``odom``) and the goal are drawn, the run's figures printed."""

from __future__ import annotations

import argparse
import random
import tempfile
from pathlib import Path

import numpy as np

from crawler_motion.tools.live_cases import BOXES, Case, run_case
from crawler_motion.tools.live_nav import LiveResult


def draw_live_map(res: LiveResult, goal: tuple[float, float], world: str, out: Path) -> None:
    """The published occupancy (red obstacle, light free, grey unknown), the real obstacles'
    outlines, the body path and the goal."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Rectangle

    grid = res.map
    assert grid is not None
    rows, cols = grid.data.shape
    r = grid.resolution
    extent = (grid.origin[0], grid.origin[0] + cols * r, grid.origin[1],
              grid.origin[1] + rows * r)
    shown = np.select([grid.data == 100, grid.data == 0], [2, 1], 0)
    fig, ax = plt.subplots(figsize=(5.5, 4.5), dpi=80)
    ax.imshow(shown, origin="lower", extent=extent, vmin=0, vmax=2,
              cmap=ListedColormap(["#9a9a9a", "#f2efe6", "#d62728"]))
    for x0, x1, y0, y1 in BOXES.get(world, ()):
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="k", lw=1.2))
    ax.plot(res.path[:, 1], res.path[:, 2], "b-", lw=1.5, label="body path (odom)")
    ax.plot(*goal, "g*", ms=12, label="goal")
    lo = res.path[:, 1:3].min(axis=0) - 0.5
    hi = np.maximum(res.path[:, 1:3].max(axis=0), goal) + 0.5
    ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), xlabel="x [m] (odom)", ylabel="y [m]",
           title="terrain_map as published (red obstacle, grey unknown); real-time stack")
    ax.title.set_fontsize(8)
    ax.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def run_live(args: argparse.Namespace) -> int:
    """Walk the goal on the real-time stack, print the figures, draw the map; exit 0 when
    arrived."""
    import rclpy

    domain = random.randint(102, 200)
    navigator = {"steering": args.steering, "method": args.method}
    case = Case("map-plot", args.world, start=tuple(args.start), navigator=navigator,
                goal=tuple(args.goal), timeout=args.limit)
    rclpy.init(domain_id=domain)
    try:
        with tempfile.TemporaryDirectory(prefix="map-plot-") as logs:
            res, fig = run_case(case, Path(logs), domain)
    finally:
        rclpy.try_shutdown()
    for key, value in fig.items():
        print(f"{key}: {value:.3f}" if isinstance(value, float) else f"{key}: {value}")
    if res.map is not None and len(res.path):
        draw_live_map(res, case.goal, args.world, args.out)  # type: ignore[arg-type]
        print(f"map: {args.out}")
    return 0 if res.state == "ARRIVED" else 1
