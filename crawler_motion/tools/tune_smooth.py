"""Choose the `smooth` profile's time split and junction speeds (prints the figures).

Criterion: minimum peak foot acceleration |a| over the swing, for the configured default step,
subject to the spec's shape rules and "lift fast, put down slowly":
- lower time >= 1.25 x lift time;
- z strictly monotone on lift and lower, z >= z_B on the arc, horizontal progress monotone;
- the foot keeps moving at B and D: junction speeds v_b, v_d >= 0.5 (in units of the
  segment's mean vertical speed).
Run: crawler-motion tune-smooth [--config PATH]  (needs scipy: pip install crawler_motion[tune])
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

import numpy as np

from crawler_motion.model.config import load_config
from crawler_motion.model.gait_config import ProfileConfig
from crawler_motion.motion.trajectory import Piecewise, SwingShape, swing_segments

PROG = "crawler-motion tune-smooth"
#: The optional dependency group (``pip install crawler_motion[tune]``) that brings scipy.
EXTRA = "tune"
RATIO = 1.25
MIN_SPEED = 0.5


def load_minimize() -> Any:
    """``scipy.optimize.minimize``; raises ImportError naming the extra when scipy is absent."""
    try:
        from scipy.optimize import minimize
    except ImportError as exc:
        raise ImportError(f"{PROG} needs scipy, which is not installed; install the optional "
                          f"dependencies with: pip install 'crawler_motion[{EXTRA}]'") from exc
    return minimize


def swing(profile: ProfileConfig, stride: float, lift: float, arc: float, t_w: float
          ) -> Piecewise:
    """The swing A->E of the default step along +x."""
    a = np.array([-stride / 2, 0.0, 0.0])
    e = np.array([stride / 2, 0.0, 0.0])
    return Piecewise(swing_segments(a, e, SwingShape(lift, arc, t_w, profile)))


def figures(pw: Piecewise, n: int = 4001) -> dict[str, float]:
    """Peak |a|, integrated squared jerk and shape-rule violations of a swing."""
    t = np.linspace(pw.t0, pw.t_end, n)
    pos, vel, acc = pw.evaluate(t)
    idx = pw.index(t)
    jerk = np.gradient(acc, t, axis=0)
    lift_v = vel[idx == 0, 2]
    lower_v = vel[idx == 2, 2]
    arc_z = pos[idx == 1, 2]
    violation = (max(0.0, -lift_v[1:-1].min()) + max(0.0, lower_v[1:-1].max())
                 + max(0.0, pw.segments[1].start[2] - arc_z.min())
                 + max(0.0, -vel[idx == 1, 0].min()))
    return {"peak_acc": float(np.linalg.norm(acc, axis=1).max()),
            "sq_jerk": float(np.trapezoid(np.sum(jerk**2, axis=1), t)),
            "peak_az": float(np.abs(acc[:, 2]).max()),
            "peak_ax": float(np.abs(acc[:, 0]).max()),
            "violation": violation}


def make(x: np.ndarray) -> ProfileConfig:
    """The profile of the optimisation variables (lift and lower fractions, v_b, v_d)."""
    f_lift, f_lower, v_b, v_d = x
    return ProfileConfig(lift_fraction=f_lift, arc_fraction=1 - f_lift - f_lower,
                         lower_fraction=f_lower, v_b=v_b, v_d=v_d)


def cost(x: np.ndarray, step: tuple[float, float, float, float]) -> float:
    """Peak |a| of the default ``step`` (stride, lift, arc, swing time), heavily penalised
    outside the shape rules."""
    f_lift, f_lower, v_b, v_d = x
    pen = (max(0.0, RATIO * f_lift - f_lower) + max(0.0, 0.05 - f_lift)
           + max(0.0, f_lift + f_lower - 0.9) + max(0.0, MIN_SPEED - v_b)
           + max(0.0, MIN_SPEED - v_d) + max(0.0, v_b - 3) + max(0.0, v_d - 3))
    if pen > 0:
        return 1e3 * (1 + pen)
    fig = figures(swing(make(x), *step), 801)
    return fig["peak_acc"] + 1e4 * fig["violation"]


def optimise(minimize: Any, step: tuple[float, float, float, float]) -> ProfileConfig:
    """The best profile of Nelder-Mead runs from a few starting points (rounded to 1e-3)."""
    best = None
    for f_lift in (0.15, 0.2, 0.25):
        for v in (0.8, 1.5, 2.0):
            res = minimize(cost, np.array([f_lift, f_lift * 1.4, v, v]), args=(step,),
                           method="Nelder-Mead",
                           options={"xatol": 1e-4, "fatol": 1e-5, "maxiter": 4000})
            if best is None or res.fun < best.fun:
                best = res
    assert best is not None
    return make(np.round(best.x, 3))


def main(argv: Sequence[str] | None = None) -> int:
    """Optimise and print the chosen values and the figures of both profiles; exit status."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=None)
    args = parser.parse_args(argv)
    try:
        minimize = load_minimize()
    except ImportError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    g = load_config(args.config).gait
    step = (g.stride, g.lift, g.arc, g.swing_time)
    chosen = optimise(minimize, step)
    print(f"chosen smooth profile: lift {chosen.lift_fraction:.3f}, arc "
          f"{chosen.arc_fraction:.3f}, lower {chosen.lower_fraction:.3f} of the swing; "
          f"v_b {chosen.v_b:.3f}, v_d {chosen.v_d:.3f}")
    print(f"{'profile':<22}{'peak |a| m/s2':>15}{'peak az':>10}{'peak ax':>10}"
          f"{'int jerk^2':>14}{'violation':>11}")
    for name, prof in (("rest (configured)", g.profiles["rest"]),
                       ("smooth (configured)", g.profiles["smooth"]),
                       ("smooth (optimised)", chosen)):
        fig = figures(swing(prof, *step))
        print(f"{name:<22}{fig['peak_acc']:>15.3f}{fig['peak_az']:>10.3f}{fig['peak_ax']:>10.3f}"
              f"{fig['sq_jerk']:>14.1f}{fig['violation']:>11.2e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
