"""Smoothness of one foot cycle: our sextics against the study's quartic, CHAMP and MIT Cheetah.

For the configured default step (stride, lift + arc height, swing time; stance time = swing
time) every controller's foot trajectory over one full cycle (swing, then stance) is written
as polynomial pieces in time and evaluated analytically:

- peak |a|: the largest |acceleration| over the open pieces, one-sided end values included,
  found at the real roots of d|a|^2/dt in each piece plus a 40 kHz grid with both ends (a
  velocity step at a junction adds a Dirac impulse that no finite number describes: such
  rows are marked and the velocity step is its own column);
- largest acceleration step: max over every junction of the cycle (lift-off and touch-down
  included, the cycle wraps) of |a(t+) - a(t-)|, the jump of the acceleration vector;
- largest velocity step: the same for the velocity (0 for a C^1 cycle);
- peak jerk, "away from the jumps": the largest |da/dt| inside the pieces (same method as
  peak |a|, one-sided limits at the ends), i.e. the Dirac parts of the jerk at acceleration
  steps are left out; an acceleration step is reported in its own column instead;
- touch-down velocity relative to the body (the swing's end velocity in the body frame) and
  relative to the ground (plus the body velocity at that instant, which is minus the stance
  foot's velocity at the start of the stance: zero for our rest-sextic stance, which stops
  the body at every touch-down, stride / t_s for the constant-speed stances).

Controllers: ``smooth`` and ``rest`` sextics (`trajectory.step_cycle`, rest-sextic stance), the
study's quartic (`SwingShape` degree 4, rest profile, the package's rest-sextic stance),
CHAMP's swing (degree-11 Bezier, 12 control points, as scaled by CHAMP: x by stride / 0.4
with the ends forced to -/+ stride / 2, z by height / 0.15; CHAMP's optional stance
penetration depth is 0 here; stance linear at constant speed), the MIT Cheetah swing (cubic
smoothstep in x and y, two smoothstep halves in z; stance linear at constant speed) and our
continuous-stance option (`continuous.continuous_step_cycle`, smooth profile).

Prints a markdown table and writes ``smoothness.png`` (x and z acceleration against time)
into ``--out`` (default ``plots/``). Run: crawler-motion smoothness [--out DIR]
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.polynomial import polynomial as npoly

from crawler_motion.model.config import load_config
from crawler_motion.motion.continuous import continuous_step_cycle
from crawler_motion.motion.trajectory import Piecewise, SwingShape, step_cycle

#: Sampling rate of the grid added to the analytic extrema [Hz].
GRID_HZ = 40_000.0
#: Velocity [m/s] and acceleration [m/s^2] steps below these are rounding, not a jump.
STEP_EPS = 1e-9
ACC_EPS = 1e-6

CHAMP_X = (-0.5, -0.70125, -0.75, -0.75, -0.75, 0.0, 0.0, 0.0, 0.758, 0.758, 0.7065, 0.5)
CHAMP_Z = (0.0, 0.0, 0.926, 0.926, 0.926, 0.926, 0.926, 1.191, 1.191, 1.191, 0.0, 0.0)


@dataclass(frozen=True)
class Piece:
    """One polynomial piece: ``coeffs`` (3, n) in normalised time u = tau / duration."""

    phase: str
    duration: float
    coeffs: np.ndarray


@dataclass(frozen=True)
class Cycle:
    """One controller's cycle from lift-off: swing pieces, then stance pieces."""

    name: str
    pieces: tuple[Piece, ...]
    ours: bool


@dataclass(frozen=True)
class Figures:
    """The report's columns for one cycle."""

    peak_acc: float
    acc_step: float
    acc_step_at: str
    vel_step: float
    vel_step_at: str
    peak_jerk: float
    touch_body: np.ndarray
    touch_ground: np.ndarray
    stance_acc: float  # peak |a| of the stance foot = peak acceleration of the body


def from_piecewise(pw: Piecewise) -> list[Piece]:
    """Pieces of a `Piecewise` (already in normalised time)."""
    return [Piece(seg.phase, seg.duration, np.array(seg.coeffs, dtype=float))
            for seg in pw.segments]


def resample(coeffs: np.ndarray, start: float, length: float) -> np.ndarray:
    """Coefficients in v of the polynomial ``coeffs`` (in u) with u = start + length * v."""
    c = np.atleast_2d(coeffs)
    n = c.shape[-1]
    basis = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            basis[i, j] = math.comb(i, j) * start ** (i - j) * length**j
    return c @ basis


def bezier_power(points: np.ndarray) -> np.ndarray:
    """Power-basis coefficients in s of the Bezier curve with control ``points`` (n + 1,)."""
    n = len(points) - 1
    out = np.zeros(n + 1)
    for k in range(n + 1):
        out[k] = sum(points[i] * math.comb(n, i) * math.comb(n - i, k - i) * (-1) ** (k - i)
                     for i in range(k + 1))
    return out


def linear_stance(stride: float, stance_time: float) -> Piece:
    """Stance from +stride/2 to -stride/2 at constant speed, on the ground."""
    c = np.zeros((3, 2))
    c[0] = [stride / 2, -stride]
    return Piece("stance", stance_time, c)


def champ_cycle(stride: float, height: float, t_w: float, t_s: float) -> Cycle:
    """CHAMP: degree-11 Bezier swing over s in [0, 1], constant-speed stance."""
    c = np.zeros((3, 12))
    c[0] = bezier_power(stride * np.array(CHAMP_X))
    c[2] = bezier_power(height * np.array(CHAMP_Z))
    return Cycle("CHAMP Bezier (deg 11)", (Piece("swing", t_w, c),
                                           linear_stance(stride, t_s)), ours=False)


def mit_cycle(stride: float, height: float, t_w: float, t_s: float) -> Cycle:
    """MIT Cheetah: smoothstep b(u) = 3u^2 - 2u^3 in x; z up then down, a smoothstep each."""
    x = np.array([-stride / 2, 0.0, 3 * stride, -2 * stride])
    up = np.zeros((3, 4))
    up[0] = resample(x, 0.0, 0.5)[0]
    up[2] = [0.0, 0.0, 3 * height, -2 * height]
    down = np.zeros((3, 4))
    down[0] = resample(x, 0.5, 0.5)[0]
    down[2] = [height, 0.0, -3 * height, 2 * height]
    return Cycle("MIT Cheetah (cubic)", (Piece("swing-up", t_w / 2, up),
                                         Piece("swing-down", t_w / 2, down),
                                         linear_stance(stride, t_s)), ours=False)


def cycles(stride: float, lift: float, arc: float, t_w: float, t_s: float,
           profiles: dict) -> list[Cycle]:
    """All controllers for one step along +x, foot at the origin in the middle of the stride."""
    center = np.zeros(3)
    stride_v = np.array([stride, 0.0])
    smooth = SwingShape(lift, arc, t_w, profiles["smooth"])
    rest = SwingShape(lift, arc, t_w, profiles["rest"])
    quartic = SwingShape(lift, arc, t_w, profiles["rest"], degree=4)
    return [
        Cycle("ours: smooth sextic", tuple(from_piecewise(step_cycle(center, stride_v, smooth,
                                                                     t_s))), ours=True),
        Cycle("ours: rest sextic", tuple(from_piecewise(step_cycle(center, stride_v, rest,
                                                                   t_s))), ours=True),
        Cycle("study's quartic", tuple(from_piecewise(step_cycle(center, stride_v, quartic,
                                                                 t_s))), ours=False),
        champ_cycle(stride, lift + arc, t_w, t_s),
        mit_cycle(stride, lift + arc, t_w, t_s),
        Cycle("ours: continuous stance", tuple(from_piecewise(continuous_step_cycle(
            center, stride_v, smooth, t_s))), ours=True),
    ]


def derivative(piece: Piece, order: int) -> np.ndarray:
    """Coefficients (3, m) in u of the ``order``-th time derivative."""
    rows = [npoly.polyder(row, order) if order else row for row in piece.coeffs]
    return np.array(rows) / piece.duration**order


def at(coeffs: np.ndarray, u: np.ndarray | float) -> np.ndarray:
    """Evaluate (3, m) coefficients at u: shape ``u.shape + (3,)``."""
    return np.stack([npoly.polyval(u, row) for row in coeffs], axis=-1)


def peak_norm(piece: Piece, order: int) -> float:
    """Largest Euclidean norm of the ``order``-th derivative on the closed piece."""
    c = derivative(piece, order)
    square = np.zeros(1)
    for row in c:
        square = npoly.polyadd(square, npoly.polymul(row, row))
    crit = npoly.polyroots(npoly.polyder(square)) if len(square) > 2 else np.array([])
    crit = crit.real[(np.abs(crit.imag) < 1e-9) & (crit.real >= 0.0) & (crit.real <= 1.0)]
    n = max(2, math.ceil(piece.duration * GRID_HZ) + 1)
    u = np.concatenate((np.linspace(0.0, 1.0, n), crit))
    return float(np.sqrt(np.max(npoly.polyval(u, square).clip(min=0.0))))


def junction_name(prev: Piece, nxt: Piece) -> str:
    if nxt.phase == "stance" and prev.phase != "stance":
        return "E (touch-down)"
    if prev.phase == "stance" and nxt.phase != "stance":
        return "A (lift-off)"
    return f"{prev.phase}/{nxt.phase}"


def largest(steps: dict[str, float], eps: float) -> tuple[float, str]:
    """The largest step and the junction(s) where it happens ("-" if none is above eps)."""
    top = max(steps.values())
    if top <= eps:
        return 0.0, "-"
    where = [name for name, value in steps.items() if value >= top - eps]
    return top, ", ".join(where)


def figures(cycle: Cycle) -> Figures:
    """The table's columns for one cycle."""
    pieces = cycle.pieces
    peak_acc = max(peak_norm(p, 2) for p in pieces)
    peak_jerk = max(peak_norm(p, 3) for p in pieces)
    dvs: dict[str, float] = {}
    das: dict[str, float] = {}
    touch_body = touch_ground = np.zeros(3)
    for k, prev in enumerate(pieces):
        nxt = pieces[(k + 1) % len(pieces)]
        name = junction_name(prev, nxt)
        dvs[name] = float(np.linalg.norm(at(derivative(nxt, 1), 0.0)
                                         - at(derivative(prev, 1), 1.0)))
        das[name] = float(np.linalg.norm(at(derivative(nxt, 2), 0.0)
                                         - at(derivative(prev, 2), 1.0)))
        if name.startswith("E"):
            touch_body = at(derivative(prev, 1), 1.0)
            body = -at(derivative(nxt, 1), 0.0)  # stance foot velocity = -body velocity
            touch_ground = touch_body + body
    vel_step, vel_at = largest(dvs, STEP_EPS)
    acc_step, acc_at = largest(das, ACC_EPS)
    stance_acc = max(peak_norm(p, 2) for p in pieces if p.phase == "stance")
    return Figures(peak_acc, acc_step, acc_at, vel_step, vel_at, peak_jerk, touch_body,
                   touch_ground, stance_acc)


def table(rows: list[tuple[Cycle, Figures]]) -> str:
    """The markdown table."""
    head = ("| controller | peak \\|a\\| [m/s²] | largest a step at a junction [m/s²] | "
            "largest v step [m/s] | peak jerk [m/s³] | touch-down v rel. body [m/s] | "
            "touch-down v rel. ground [m/s] | peak body \\|a\\| (stance) [m/s²] |")
    lines = [head, "|" + "---|" * 8]
    for cycle, f in rows:
        impulse = " †" if f.vel_step > 0 else ""
        lines.append(
            f"| {cycle.name} | {f.peak_acc:.3f}{impulse} | {f.acc_step:.3f} ({f.acc_step_at}) | "
            f"{f.vel_step:.3f} ({f.vel_step_at}) | {f.peak_jerk:.1f} | "
            f"{np.linalg.norm(f.touch_body):.3f} | {np.linalg.norm(f.touch_ground):.3f} | "
            f"{f.stance_acc:.3f} |")
    return "\n".join(lines)


def honesty(rows: list[tuple[Cycle, Figures]]) -> list[str]:
    """Where the best of ours is beaten, column by column (computed, not hand-written)."""
    columns = {
        "peak |a| (finite part)": lambda f: f.peak_acc,
        "largest acceleration step": lambda f: f.acc_step,
        "largest velocity step": lambda f: f.vel_step,
        "peak jerk": lambda f: f.peak_jerk,
        "touch-down speed rel. body": lambda f: float(np.linalg.norm(f.touch_body)),
        "touch-down speed rel. ground": lambda f: float(np.linalg.norm(f.touch_ground)),
        "peak body acceleration (stance)": lambda f: f.stance_acc,
    }
    notes = []
    for title, key in columns.items():
        best_c, best_f = min(rows, key=lambda r: key(r[1]))
        ours_c, ours_f = min((r for r in rows if r[0].ours), key=lambda r: key(r[1]))
        if key(best_f) < key(ours_f) - 1e-9:
            notes.append(f"- {title}: {best_c.name} has {key(best_f):.3f}, the best of ours "
                         f"({ours_c.name}) {key(ours_f):.3f} ({key(ours_f) / key(best_f):.1f}x)")
        else:
            ties = [c.name for c, f in rows if abs(key(f) - key(ours_f)) <= 1e-9]
            notes.append(f"- {title}: ours is best ({key(ours_f):.3f}; tied: {', '.join(ties)})")
    return notes


def plot(rows: list[tuple[Cycle, Figures]], out: Path, title: str) -> Path:
    """x and z acceleration against time for every controller; returns the PNG path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    styles = ["-", "--", ":", "-.", (0, (5, 1)), (0, (3, 1, 1, 1))]
    for (cycle, f), style in zip(rows, styles, strict=False):
        t_parts, a_parts = [], []
        t0 = 0.0
        for piece in cycle.pieces:
            n = max(2, math.ceil(piece.duration * 2000) + 1)
            u = np.linspace(0.0, 1.0, n)
            t_parts.append(t0 + u * piece.duration)
            a_parts.append(at(derivative(piece, 2), u))
            t0 += piece.duration
        t = np.concatenate(t_parts)
        acc = np.concatenate(a_parts)
        label = cycle.name + (" (+ velocity step: impulse not drawn)" if f.vel_step else "")
        for ax, dim in zip(axes, (0, 2), strict=True):
            ax.plot(t, acc[:, dim], linestyle=style, linewidth=1.3, label=label)
    for ax, name in zip(axes, ("x", "z"), strict=True):
        ax.set_ylabel(f"a_{name} [m/s²]")
        ax.grid(True, alpha=0.3)
        ax.axhline(0.0, color="black", linewidth=0.5)
    axes[1].set_xlabel("time from lift-off [s]")
    axes[0].set_title(title)
    axes[1].legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / "smoothness.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """Print the table and the notes, write the figure."""
    parser = argparse.ArgumentParser(prog="crawler-motion smoothness",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="plots", help="output directory (default: plots/)")
    parser.add_argument("--config", default=None, help="robot.yaml (default: the shipped one)")
    args = parser.parse_args(argv)
    cfg = load_config(args.config)
    g = cfg.gait
    t_w = g.swing_time
    t_s = t_w
    rows = [(c, figures(c)) for c in cycles(g.stride, g.lift, g.arc, t_w, t_s, g.profiles)]
    step = (f"stride {g.stride:g} m, lift {g.lift:g} + arc {g.arc:g} m, swing {t_w:g} s, "
            f"stance {t_s:g} s")
    print(f"## Foot-cycle smoothness ({step})\n")
    print(table(rows))
    print("\n† the velocity is discontinuous at a junction (lift-off/touch-down): the "
          "acceleration there holds a Dirac impulse; the peak is that of the finite part.")
    print("Peak jerk is the largest |da/dt| inside the pieces (one-sided at their ends); the "
          "Dirac parts at acceleration steps are excluded and reported as the a-step column.")
    print("Ground-relative touch-down velocity = body-frame velocity + body velocity; our "
          "rest-sextic stance stops the body at touch-down (body velocity 0), the "
          "constant-speed stances move it at stride / t_s = "
          f"{g.stride / t_s:.3f} m/s.\n")
    print("### Where ours is not the best\n")
    print("\n".join(honesty(rows)))
    path = plot(rows, Path(args.out), f"Foot acceleration over one cycle ({step})")
    print(f"\nfigure: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
