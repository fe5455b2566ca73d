"""The report's pictures (matplotlib, headless): each returns its PNG path, None without data."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.recording import series
from crawler_motion.recording.reader import Recording

DPI = 80


def figure(rows: int = 1, cols: int = 1, size: tuple[float, float] = (8.0, 4.0)) -> Any:
    """A headless matplotlib figure and its ``(rows, cols)`` axes; ``size`` in inches."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(rows, cols, figsize=size, squeeze=False)


def save(fig: Any, path: Path) -> Path:
    """Write ``fig`` as a small PNG at ``path``, close it and return ``path``."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def draw_joints(cmd: series.Joints, meas: series.Joints, legs: list[str], path: Path
                ) -> Path | None:
    """Commanded (dashed) against measured joint angles, one panel per leg [rad]."""
    if not len(cmd.t) and not len(meas.t):
        return None
    fig, axes = figure(len(legs), 1, (8.0, 1.8 * len(legs)))
    for row, leg in enumerate(legs):
        ax = axes[row][0]
        for j, name in enumerate(meas.names):
            if not name.startswith(f"{leg}_"):
                continue
            line = ax.plot(meas.t, meas.q[:, j], lw=1.0, label=name.split("_")[1])[0]
            ax.plot(cmd.t, cmd.q[:, j], "--", lw=0.8, color=line.get_color())
        ax.set_ylabel(f"{leg} [rad]")
        ax.legend(loc="upper right", fontsize=7, ncol=3)
    axes[-1][0].set_xlabel("time [s] (dashed: commanded)")
    return save(fig, path)


def draw_feet(t: np.ndarray, feet: np.ndarray, legs: list[str], path: Path) -> Path | None:
    """Foot paths in ``base_link``: x-y seen from above (hips' side up) and z over time, one
    colour per leg [m]."""
    if not len(t):
        return None
    fig, axes = figure(1, 2, (10.0, 4.2))
    top, height = axes[0][0], axes[0][1]
    for leg, name in enumerate(legs):
        xy = feet[:, leg, :2]
        line = top.plot(xy[:, 0], xy[:, 1], lw=1.0, label=name)[0]
        top.plot(*xy[0], "o", ms=4, color=line.get_color())
        height.plot(t, feet[:, leg, 2], lw=1.0, label=name, color=line.get_color())
    top.plot(0.0, 0.0, "k+", ms=10)
    top.set_aspect("equal", adjustable="datalim")
    top.set_xlabel("x [m] (base_link, o: first sample)")
    top.set_ylabel("y [m]")
    top.legend(loc="center", fontsize=8)
    height.set_xlabel("time [s]")
    height.set_ylabel("foot z in base_link [m]")
    height.legend(loc="upper right", fontsize=8, ncol=len(legs))
    return save(fig, path)


def draw_tracking(err: series.Joints, path: Path) -> Path | None:
    """Tracking error of every joint and the largest over time [rad]."""
    if not len(err.t):
        return None
    fig, axes = figure()
    ax = axes[0][0]
    ax.plot(err.t, err.q, lw=0.6, alpha=0.6)
    ax.plot(err.t, np.nanmax(np.abs(err.q), axis=1), "k", lw=1.2, label="largest |error|")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("measured - commanded [rad]")
    ax.legend(loc="upper right", fontsize=8)
    return save(fig, path)


def draw_path(rec: Recording, path: Path) -> Path | None:
    """The body's path from ``odom`` over the terrain map (obstacles dark) and the goals."""
    _, xyz = series.body_path(rec)
    if not len(xyz):
        return None
    fig, axes = figure(size=(5.5, 5.0))
    ax = axes[0][0]
    grid = series.terrain(rec)
    if grid is not None:
        cells, extent = grid
        ax.imshow(np.ma.masked_less(cells, 0), origin="lower", extent=extent, cmap="Greys",
                  vmin=0, vmax=100, alpha=0.8)
    ax.plot(xyz[:, 0], xyz[:, 1], "C0", lw=1.5, label="body (odom)")
    ax.plot(*xyz[0, :2], "go", label="start")
    ax.plot(*xyz[-1, :2], "rs", label="end")
    goals = series.goals(rec)
    if len(goals):
        ax.plot(goals[:, 0], goals[:, 1], "m*", ms=12, label="goal")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize=8)
    return save(fig, path)


def draw_states(rec: Recording, path: Path) -> Path | None:
    """Planner (and driver) states over time."""
    fig, axes = figure(size=(8.0, 2.6))
    ax = axes[0][0]
    names: list[str] = []
    drawn = False
    for topic in ("planner_status", "driver_status"):
        t, states = series.status_states(rec, topic)
        if not states:
            continue
        labels = [f"{topic.split('_')[0]}: {s}" for s in states]
        names += [n for n in dict.fromkeys(labels) if n not in names]
        ax.step(t, [names.index(n) for n in labels], where="post", label=topic)
        drawn = True
    if not drawn:
        import matplotlib.pyplot as plt

        plt.close(fig)
        return None
    ax.set_yticks(range(len(names)), names, fontsize=7)
    ax.set_xlabel("time [s]")
    return save(fig, path)


def draw_faults(found: list[tuple[float, str, str, str]], path: Path) -> Path | None:
    """Non-OK ``/diagnostics`` statuses over time, one row per status name."""
    if not found:
        return None
    names = list(dict.fromkeys(name for _, name, _, _ in found))
    colors = {"WARN": "orange", "ERROR": "red", "STALE": "grey"}
    fig, axes = figure(size=(8.0, 1.0 + 0.35 * len(names)))
    ax = axes[0][0]
    for t, name, level, _ in found:
        ax.plot(t, names.index(name), "|", ms=12, color=colors.get(level, "black"))
    ax.set_yticks(range(len(names)), names, fontsize=7)
    ax.set_xlabel("time [s] (orange WARN, red ERROR, grey STALE)")
    return save(fig, path)
