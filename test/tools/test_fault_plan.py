"""The mission soak's fault plan and expectations, and the motion figures it judges by (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.tools.fault_plan import (
    STOP_RANGE,
    Fault,
    FaultKind,
    Recovery,
    expectation,
    fault_plan,
    kinds_and_targets,
)
from crawler_motion.tools.mission_soak import STILL, motion, still_after


def test_a_plan_is_the_same_for_a_seed_and_holds_every_kind_in_each_round() -> None:
    plan = fault_plan(7, 30)
    assert plan == fault_plan(7, 30)
    assert plan != fault_plan(8, 30)
    n = len(kinds_and_targets())
    assert n == 12  # kill and stop of 4 processes, garbage, e-stop, future odom, flood
    first = {(f.kind, f.target) for f in plan[:n]}
    assert first == set(kinds_and_targets())
    for fault in plan:
        if fault.kind is FaultKind.STOP:
            assert STOP_RANGE[0] <= fault.length <= STOP_RANGE[1]
        assert 15.0 <= fault.quiet <= 45.0


@pytest.mark.parametrize("count, quiet, words", [
    (-1, (15.0, 45.0), "negative"),
    (3, (20.0, 10.0), "low <= high"),
    (3, (-1.0, 10.0), "low <= high"),
])
def test_bad_plans_are_refused(count: int, quiet: tuple[float, float], words: str) -> None:
    with pytest.raises(ValueError, match=words):
        fault_plan(1, count, quiet)


@pytest.mark.parametrize("fault, hold, recovery", [
    (Fault(FaultKind.KILL, "navigator", 0.0, 10.0), True, Recovery.RESEND),
    (Fault(FaultKind.KILL, "terrain_mapper", 0.0, 10.0), True, Recovery.AUTOMATIC),
    (Fault(FaultKind.KILL, "planner_node", 0.0, 10.0), True, Recovery.RECOVER),
    (Fault(FaultKind.STOP, "navigator", 2.5, 10.0), True, Recovery.AUTOMATIC),
    # a stop shorter than map_max_age + the time to stop a walk: no hold can be required
    (Fault(FaultKind.STOP, "terrain_mapper", 2.99, 10.0), False, Recovery.AUTOMATIC),
    (Fault(FaultKind.STOP, "terrain_mapper", 3.0, 10.0), True, Recovery.AUTOMATIC),
    (Fault(FaultKind.STOP, "planner_node", 1.2, 10.0), False, Recovery.RECOVER),
    (Fault(FaultKind.ESTOP, None, 0.0, 10.0), True, Recovery.RECOVER),
    (Fault(FaultKind.FUTURE_ODOM, None, 0.0, 10.0), False, Recovery.NONE),
    (Fault(FaultKind.GOAL_FLOOD, None, 2.0, 10.0), False, Recovery.NONE),
])
def test_expectations(fault: Fault, hold: bool, recovery: Recovery) -> None:
    exp = expectation(fault)
    assert exp.hold is hold and exp.recovery is recovery


def _path(speeds: list[tuple[float, float]]) -> np.ndarray:
    """A path at 50 Hz: (duration [s], speed [m/s]) pieces along x."""
    rows, t, x = [], 0.0, 0.0
    for duration, speed in speeds:
        for _ in range(round(duration * 50)):
            rows.append((t, x, 0.0))
            t += 0.02
            x += speed * 0.02
    return np.array(rows)


def test_the_body_is_still_once_it_stops_and_the_motion_after_is_measured() -> None:
    path = _path([(2.0, 0.1), (3.0, 0.0), (1.0, 0.05)])
    assert still_after(path, 0.0, 6.0) == pytest.approx(2.0, abs=0.03)
    assert still_after(path, 0.0, 2.3) is None  # not watched long enough to tell
    assert still_after(_path([(4.0, 0.1)]), 0.0, 4.0) is None
    assert still_after(_path([(4.0, 0.9 * STILL / 0.5)]), 0.0, 4.0) == 0.0  # creeping < STILL
    assert motion(path, 2.1, 4.9) == pytest.approx(0.0)
    assert motion(path, 2.1, 6.0) == pytest.approx(0.05 * 1.0, abs=0.002)
    assert motion(path, 10.0, 11.0) == 0.0
