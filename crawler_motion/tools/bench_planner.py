"""The planner's rows of the bench: its tick while walking, planning ahead, calibrated legs,
and the tick beside its peer (StanfordQuadruped's ``Controller.run``) in alternating blocks."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import replace

from crawler_motion.model.config import Config
from crawler_motion.motion.gait import WalkParams, standing_pose, validate_params
from crawler_motion.planner.core import PlannerCore
from crawler_motion.tools.bench_timing import Row, measure

#: Planner tick rate of the planner rows [Hz].
PLANNER_RATE = 100.0
#: Alternating blocks of the side-by-side rows (tick, peer, tick, peer, ...).
SIDE_BY_SIDE_BLOCKS = 5


class WalkingCore:
    """A `PlannerCore` walking until stopped at `PLANNER_RATE`: ``tick`` is one tick on its
    clock, ``plan`` plans the next slot ahead between ticks as the node's planning thread
    does (the time of each plan made, in ns, in ``planning``)."""

    def __init__(self, cfg: Config) -> None:
        self.core = core = PlannerCore(cfg, PLANNER_RATE)
        pose = standing_pose(cfg)
        self.now = 0.0
        core.set_measured(pose, self.now)
        core.submit('{"command": "stand"}', self.now)
        while core.state != "STANDING":
            self.now += 1.0 / PLANNER_RATE
            core.set_measured(pose, self.now)
            core.tick(self.now)
        core.submit('{"command": "walk"}', self.now)  # until stopped
        self.planning: list[int] = []

    def tick(self) -> None:
        """One tick, a period after the last."""
        self.now += 1.0 / PLANNER_RATE
        self.core.tick(self.now)

    def plan(self) -> None:
        """Plan the next slot if it is due (untimed by the rows, timed here)."""
        t0 = time.perf_counter_ns()
        if self.core.plan_ahead():
            self.planning.append(time.perf_counter_ns() - t0)


def planner_rows(cfg: Config, scale: float) -> list[Row]:
    """`PlannerCore.tick` while walking at `PLANNER_RATE`, as the node runs it (the next slot
    planned by `PlannerCore.plan_ahead` right after a tick, outside the timed call), then the
    same without planning ahead (the tick plans at the boundary), and `plan_ahead` itself."""
    params = validate_params(WalkParams.defaults(cfg.gait), cfg)
    n_groups = len(cfg.gait.gaits[params.gait])
    slot_time = (params.swing_time + float(params.stance_time)) / n_groups  # type: ignore[arg-type]
    calls = max(200, int(6000 * scale))
    slots = calls / (PLANNER_RATE * slot_time)
    rows = []
    for ahead in (True, False):
        walking = WalkingCore(cfg)
        if ahead:
            name = (f"planner tick (`PlannerCore.tick`, walking, {PLANNER_RATE:g} Hz, next "
                    f"slot planned ahead between ticks, as the node does)")
            note = f"{slots:.0f} slot boundaries in the run, all switched without planning"
        else:
            name = "planner tick without `plan_ahead` (the boundary tick plans the slot)"
            note = (f"{slots:.0f} slot boundaries in the run (1 tick in "
                    f"{PLANNER_RATE * slot_time:.0f}): they make the p99")
        row = measure(name, walking.tick, calls, warmup=100,
                      between=walking.plan if ahead else None)
        if walking.core.state != "WALKING":
            note += f"; ended in {walking.core.state}"
        rows.append(Row(row.name, row.calls, row.median, row.p99, note))
        if ahead and walking.planning:
            us = sorted(x / 1e3 for x in walking.planning)
            rows.append(Row("`PlannerCore.plan_ahead` (plan + check the next slot + its "
                            "evaluator), once per slot", len(us), statistics.median(us),
                            us[min(len(us) - 1, round(0.99 * (len(us) - 1)))],
                            "runs in the planning thread, before the slot boundary"))
    return rows


def calibrated_rows(cfg: Config, scale: float) -> list[Row]:
    """The planner tick (planned ahead) with every leg calibrated: synthetic assembly errors
    (`calibration.synthetic.perturbed_robot`, seed 1)."""
    from crawler_motion.calibration.synthetic import perturbed_robot

    row = planner_rows(replace(cfg, robot=perturbed_robot(cfg.robot, 1)), scale)[0]
    return [Row("planner tick, calibrated legs (Newton-refined IK, synthetic errors)",
                row.calls, row.median, row.p99, row.note)]


def side_by_side(cfg: Config, peer: Callable[[], object], scale: float) -> tuple[Row, Row]:
    """The planner tick (planned ahead) and one call of ``peer`` in `SIDE_BY_SIDE_BLOCKS`
    alternating blocks each, so that both see the same machine; each row pools its blocks
    (the median of the block medians, the largest block p99)."""
    walking = WalkingCore(cfg)
    calls = max(100, int(1500 * scale))
    ours: list[Row] = []
    theirs: list[Row] = []
    for _ in range(SIDE_BY_SIDE_BLOCKS):
        ours.append(measure("", walking.tick, calls, warmup=50, between=walking.plan))
        theirs.append(measure("", peer, calls, warmup=50))
    note = f"{SIDE_BY_SIDE_BLOCKS} alternating blocks of {calls} calls"
    return (_pooled("planner tick, side by side with the peer (default walk, planned ahead)",
                    ours, note),
            _pooled("peer: StanfordQuadruped `Controller.run`, trot (its clone, this "
                    "process)", theirs, note))


def _pooled(name: str, blocks: list[Row], note: str) -> Row:
    medians = [b.median for b in blocks if b.median is not None]
    p99s = [b.p99 for b in blocks if b.p99 is not None]
    return Row(name, sum(b.calls for b in blocks), statistics.median(medians),
               max(p99s), note)
