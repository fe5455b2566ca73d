"""``crawler-motion bench-mission``: the navigator's mission overhead (prints figures, asserts
nothing).

On a 4 m x 4 m map of 0.05 m cells holding the harbour's quay and box (`TerrainView`, all
known), a mission runs the shipped harbour mission's cover task on the ``apf`` navigator, in
the loop the node runs per map: `MissionRunner.before` + `ApfNavigator.step` +
`MissionRunner.after`, the body moved along the twist (kinematic, 10 Hz). Timed per call with
``time.perf_counter`` (the garbage collector on, as in the node):

- *navigator cycle*: every cycle of the cover task (median, 99th percentile, max) against the
  target median of `CYCLE_TARGET`;
- *re-plan of a cover slice*: the next waypoint chosen on the live map
  (`CoverTask._next_end`: the slice's clear points on the navigator's field) against
  `REPLAN_TARGET`; and the covered-share measure and clean-up choice of the same task;
- *far goals*: cycles of goals at the navigator's ``max_goal_distance`` (less 1 %) in eight
  directions from the box's side, against the cycle period `PERIOD` (the 99th percentile
  within it; the plan beyond the map's obstacles is the straight line: `apf.planner.open_line`).

The machine may be shared: read the figures as orders of magnitude and rerun before drawing
conclusions.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Sequence

import numpy as np

from crawler_motion.navigation.apf_navigator import ApfNavigator
from crawler_motion.navigation.mission import parse_mission
from crawler_motion.navigation.mission_runner import MissionRunner, MissionState
from crawler_motion.navigation.navigator import NavState, TerrainView
from crawler_motion.tools.live_cases import BOXES as HARBOUR_BOXES

#: Targets (issue "missions"): navigator cycle median [s] and a cover slice's re-plan [s].
CYCLE_TARGET = 0.002
REPLAN_TARGET = 0.2
#: The map: 4 m x 4 m of 0.05 m cells from this corner [m]; the harbour's boxes (x0, x1, y0,
#: y1 [m]) and its cover task.
ORIGIN = (-0.5, -3.0)
SIZE, RES = 4.0, 0.05
BOXES = HARBOUR_BOXES["harbour"]
COVER = "tasks: [{cover: {area: [0.4, -2.6, 2.4, -0.6], spacing: 0.15}}]"
#: Virtual radius of the standing robot [m], the cycle period [s] and the cycles to time.
RADIUS, PERIOD = 0.215, 0.1
#: Where the far goals start from: beside the harbour's box [m].
FAR_START = (1.5, -1.0)


def harbour_view() -> TerrainView:
    """The 4 m x 4 m known map with the harbour's boxes as obstacle cells."""
    n = round(SIZE / RES)
    centres = np.array(ORIGIN)[:, None] + (np.arange(n) + 0.5) * RES
    gx, gy = np.meshgrid(centres[0], centres[1])
    obstacle = np.zeros((n, n), dtype=bool)
    for x0, x1, y0, y1 in BOXES:
        obstacle |= (gx > x0) & (gx < x1) & (gy > y0) & (gy < y1)
    return TerrainView(np.array(ORIGIN), RES, np.ones((n, n), bool), obstacle, np.zeros((n, n)))


def run(cycles: int) -> dict[str, list[float]]:
    """Time ``cycles`` cycles of the cover task from (0.4, -0.6); per-call times [s]."""
    view = harbour_view()
    nav = ApfNavigator()
    runner = MissionRunner(parse_mission(COVER), nav, np.array([0.4, -0.6]), 0.0, 0.16)
    pose = np.array([0.4, -0.6, 0.0])
    disc = RADIUS + nav.settings.margin
    times: dict[str, list[float]] = {"cycle": [], "replan": [], "share": [], "cleanup": []}
    for k in range(cycles):
        if runner.state is not MissionState.RUNNING:
            break
        now = k * PERIOD
        t0 = time.perf_counter()
        runner.before(tuple(pose), view, disc, now)
        out = nav.step(tuple(pose), RADIUS, view, now)
        runner.after(view, disc, now)
        times["cycle"].append(time.perf_counter() - t0)
        if out.twist is not None and nav.state is NavState.ACTIVE:
            vx, vy, wz = out.twist
            c, s = math.cos(pose[2]), math.sin(pose[2])
            pose += PERIOD * np.array([c * vx - s * vy, s * vx + c * vy, wz])
    cover = runner._cover  # the task's own parts, timed on the last map and pose
    if cover is not None:
        for _ in range(20):
            cover._along = None
            t0 = time.perf_counter()
            cover._next_end(view, disc, 0.0)
            times["replan"].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            cover.tracker.share(view, cover.task.polygon, cover._field(view, disc))
            times["share"].append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            cover._cleanup(view, disc, 0.0)
            times["cleanup"].append(time.perf_counter() - t0)
    return times


def run_far(cycles: int) -> tuple[list[float], list[str]]:
    """Time ``cycles`` cycles towards each of 8 goals at 0.99 ``max_goal_distance`` from
    `FAR_START`; per-call times [s] and each goal's end state."""
    view, times, ends = harbour_view(), [], []
    for angle in np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False):
        nav = ApfNavigator()
        far = 0.99 * nav.settings.max_goal_distance
        goal = np.array(FAR_START) + far * np.array([math.cos(angle), math.sin(angle)])
        nav.set_goal(float(goal[0]), float(goal[1]), 0.0)
        pose = np.array([*FAR_START, angle])
        for k in range(cycles):
            t0 = time.perf_counter()
            out = nav.step(tuple(pose), RADIUS, view, k * PERIOD)
            times.append(time.perf_counter() - t0)
            if nav.state is not NavState.ACTIVE:
                break
            if out.twist is not None:
                vx, vy, wz = out.twist
                c, s = math.cos(pose[2]), math.sin(pose[2])
                pose += PERIOD * np.array([c * vx - s * vy, s * vx + c * vy, wz])
        ends.append(f"{math.degrees(angle):.0f}°: {nav.state.value}")
    return times, ends


def _p99(t: list[float]) -> float:
    return t[min(len(t) - 1, math.ceil(0.99 * len(t)) - 1)]


def main(argv: Sequence[str] | None = None) -> int:
    """Run and print the table; exit 0."""
    parser = argparse.ArgumentParser(prog="crawler-motion bench-mission",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=600,
                        help="navigator cycles to time (default 600: 60 s of the task)")
    args = parser.parse_args(argv)
    times = run(max(1, args.cycles))
    times["far"], ends = run_far(max(1, args.cycles // 6))
    print("# mission overhead on a 4 m x 4 m map (harbour cover task, apf navigator)\n")
    print(f"{'':34} {'calls':>6} {'median ms':>10} {'p99 ms':>8} {'max ms':>8}")
    for name, label in (("cycle", "navigator cycle (before+step+after)"),
                        ("replan", "re-plan of a cover slice"),
                        ("share", "covered-share measure"), ("cleanup", "clean-up choice"),
                        ("far", "navigator cycle, far goals")):
        t = sorted(times[name])
        if not t:
            continue
        p99 = _p99(t)
        print(f"{label:34} {len(t):6d} {1e3 * statistics.median(t):10.2f} {1e3 * p99:8.2f} "
              f"{1e3 * t[-1]:8.2f}")
    cyc = statistics.median(times["cycle"])
    print(f"\n- navigator cycle median {1e3 * cyc:.2f} ms (target <= {1e3 * CYCLE_TARGET:g} ms) "
          f"-> {'met' if cyc <= CYCLE_TARGET else 'NOT met'}")
    if times["replan"]:
        rep = max(times["replan"])
        print(f"- cover slice re-plan max {1e3 * rep:.1f} ms (target <= {1e3 * REPLAN_TARGET:g}"
              f" ms) -> {'met' if rep <= REPLAN_TARGET else 'NOT met'}")
    far = _p99(sorted(times["far"]))
    print(f"- far goals ({', '.join(ends)}): cycle p99 {1e3 * far:.1f} ms (target <= the "
          f"period {1e3 * PERIOD:g} ms) -> {'met' if far <= PERIOD else 'NOT met'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
