"""PNG plots: the study's comparison (rest vs smooth vs quartic) and joints over a walk."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.model.config import Config
from crawler_motion.model.kinematics import inverse_kinematics
from crawler_motion.motion.gait import WalkParams, plan_walk
from crawler_motion.motion.trajectory import Piecewise, SwingShape, step_cycle

CURVES: tuple[tuple[str, str, int, str], ...] = (
    ("rest sextic", "rest", 6, "tab:blue"),
    ("smooth sextic", "smooth", 6, "tab:green"),
    ("quartic (study)", "rest", 4, "tab:red"),
)


def comparison_cycles(cfg: Config) -> dict[str, Piecewise]:
    """One LF cycle along +x per compared curve, config default step."""
    g = cfg.gait
    center = cfg.robot.standing_feet()[0]
    return {label: step_cycle(center, [g.stride, 0.0],
                              SwingShape(g.lift, g.arc, g.swing_time, g.profiles[prof], degree),
                              g.stance_time)
            for label, prof, degree, _ in CURVES}


def _pyplot() -> Any:
    """matplotlib's pyplot on the file-only Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: Path, dpi: int) -> Path:
    """Lay out, write and close ``fig``; returns ``path``."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    _pyplot().close(fig)
    return path


def plot_foot_path(cfg: Config, cycles: dict[str, Piecewise], out: Path) -> Path:
    """``foot_path.png``: the swing of every compared curve in the x-z plane [mm]."""
    center = cfg.robot.standing_feet()[0]
    fig, ax = _pyplot().subplots(figsize=(7, 3.5))
    for (label, _, _, color), pw in zip(CURVES, cycles.values(), strict=True):
        t = np.linspace(pw.t0, pw.breaks[3], 600)
        pos = pw.evaluate(t)[0]
        ax.plot((pos[:, 0] - center[0]) * 1e3, (pos[:, 2] - center[2]) * 1e3, color=color,
                label=label)
    ax.set_xlabel("x along the stride [mm]")
    ax.set_ylabel("z above the ground [mm]")
    ax.set_title("Foot path of one swing (LF, config default step)")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.legend()
    return _save(fig, out / "foot_path.png", 120)


def plot_foot_profiles(cfg: Config, cycles: dict[str, Piecewise], out: Path) -> Path:
    """``foot_profiles.png``: x and z position, velocity and acceleration over one cycle."""
    center = cfg.robot.standing_feet()[0]
    fig, axes = _pyplot().subplots(3, 2, figsize=(11, 8), sharex=True)
    for (label, _, _, color), pw in zip(CURVES, cycles.values(), strict=True):
        t = np.linspace(pw.t0, pw.t_end, 2400)
        pos, vel, acc = pw.evaluate(t)
        for col, (axis, name) in enumerate(((0, "x"), (2, "z"))):
            axes[0, col].plot(t, (pos[:, axis] - center[axis]) * 1e3, color=color, label=label)
            axes[1, col].plot(t, vel[:, axis], color=color)
            axes[2, col].plot(t, acc[:, axis], color=color)
            axes[0, col].set_title(f"{name}")
    for col in range(2):
        axes[0, col].set_ylabel("position [mm]")
        axes[1, col].set_ylabel("velocity [m/s]")
        axes[2, col].set_ylabel("acceleration [m/s²]")
        axes[2, col].set_xlabel("time from lift-off [s]")
        for row in range(3):
            for b in cycles["smooth sextic"].breaks[1:-1]:
                axes[row, col].axvline(b, color="tab:green", alpha=0.15)
            axes[row, col].grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("One step cycle: rest vs smooth sextic vs the study's quartic")
    return _save(fig, out / "foot_profiles.png", 110)


def plot_walk_joints(cfg: Config, out: Path) -> Path:
    """``walk_joints.png``: the joint angles [rad] over a default 3-step walk."""
    plan = plan_walk(cfg, WalkParams.defaults(cfg.gait), 3)
    t = np.linspace(0.0, plan.duration, 1500)
    q = inverse_kinematics(cfg.robot, plan.evaluate(t)[0])
    fig, axes = _pyplot().subplots(3, 1, figsize=(10, 8), sharex=True)
    for j, kind in enumerate(("root", "shoulder", "knee")):
        for i, leg in enumerate(cfg.robot.legs):
            axes[j].plot(t, q[:, i, j], label=f"{leg}_{kind}_joint")
        axes[j].set_ylabel(f"{kind} [rad]")
        axes[j].grid(True, alpha=0.3)
        axes[j].legend(fontsize=8, ncol=4, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"Joint angles over a {plan.slots[0].params.gait} walk "
                 f"(half step in, 3 steps, half step out)")
    return _save(fig, out / "walk_joints.png", 110)


def write_plots(cfg: Config, out: Path) -> list[Path]:
    """Write ``foot_path.png``, ``foot_profiles.png`` and ``walk_joints.png`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    cycles = comparison_cycles(cfg)
    return [plot_foot_path(cfg, cycles, out), plot_foot_profiles(cfg, cycles, out),
            plot_walk_joints(cfg, out)]
