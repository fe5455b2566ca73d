"""Tests of crawler_motion.motion.jointtable: a slot's joints tabulated, within its tolerances.

The reference is the public numpy API (`Piecewise.evaluate`, `inverse_kinematics`,
`joint_velocities`) at the same instant; every cell kept in a table is within `ANGLE_TOL` and
`RATE_TOL` of it, every other cell says so (None: the exact path serves it).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.model.config import RobotConfig, load_config
from crawler_motion.model.kinematics import inverse_kinematics, joint_velocities
from crawler_motion.motion.gait import GaitSequencer, Slot, WalkParams, validate_params
from crawler_motion.motion.jointtable import JointTable
from crawler_motion.motion.trajectory import Piecewise, rest_segment

CFG = load_config()
ROBOT = CFG.robot
CALIBRATED = perturbed_robot(ROBOT, 1)
#: The table's contract (docs/benchmarks.md): every angle it serves within 1e-7 rad of the
#: exact IK, every rate within 1e-5 rad/s (the bus carries 1e-4 rad steps and no rate).
ANGLE_TOL, RATE_TOL = 1e-7, 1e-5

#: every shipped gait at its defaults, then headings, turns and a short swing
WALKS = [*({"gait": name} for name in CFG.gait.gaits),
         {"heading": 1.5708, "stride": 0.04}, {"heading": -2.5, "turn": 0.2, "stride": 0.03},
         {"turn": -0.3, "stride": 0.0},
         {"gait": "diagonal", "swing_time": 0.3, "stance_time": 0.9, "body_height": 0.08}]


def slots_of(walk: dict, n: int = 3) -> list[Slot]:
    """The start slot and the next ``n - 1`` of a walk with parameters ``walk``."""
    params = validate_params(WalkParams.defaults(CFG.gait, **walk), CFG)
    seq = GaitSequencer(CFG, params)
    slots = []
    for _ in range(n):
        slot = seq.next_slot()
        assert slot is not None
        slots.append(slot)
    return slots


def exact(legs: tuple[Piecewise, ...], robot: RobotConfig, t: float
          ) -> tuple[np.ndarray, np.ndarray]:
    pos = np.stack([leg.evaluate(t)[0][0] for leg in legs])
    vel = np.stack([leg.evaluate(t)[1][0] for leg in legs])
    q = inverse_kinematics(robot, pos)
    return q.reshape(-1), joint_velocities(robot, q, vel).reshape(-1)


def assert_within(table: JointTable, legs: tuple[Piecewise, ...], robot: RobotConfig,
                  times: np.ndarray) -> int:
    """Every time served by the table is within its tolerances; returns how many were."""
    served = 0
    for t in times:
        got = table.evaluate(float(t))
        if got is None:
            continue
        q, qd = exact(legs, robot, float(t))
        np.testing.assert_allclose(got[0], q, rtol=0, atol=ANGLE_TOL)
        np.testing.assert_allclose(got[1], qd, rtol=0, atol=RATE_TOL)
        served += 1
    return served


@pytest.mark.parametrize("walk", WALKS, ids=[str(w) or "default" for w in WALKS])
def test_every_walk_kind_is_tabulated_within_the_tolerances(walk):
    for slot in slots_of(walk):
        table = JointTable.build(slot.legs, ROBOT)
        assert table is not None
        times = np.linspace(table.t0, table.t_end, 397)  # not on the grid
        assert assert_within(table, slot.legs, ROBOT, times) >= 0.9 * len(times)


def test_calibrated_legs_are_tabulated_by_their_own_ik():
    slot = slots_of({})[1]
    table = JointTable.build(slot.legs, CALIBRATED)
    assert table is not None and table.exact_cells == 0
    times = np.linspace(table.t0, table.t_end, 101)
    assert assert_within(table, slot.legs, CALIBRATED, times) == len(times)
    nominal = JointTable.build(slot.legs, ROBOT)
    assert nominal is not None
    assert np.abs(np.subtract(table.evaluate(0.1)[0], nominal.evaluate(0.1)[0])).max() > 1e-4


@settings(max_examples=60, deadline=None)
@given(st.floats(min_value=-0.2, max_value=0.8), st.sampled_from(range(3)))
def test_any_time_is_within_the_tolerances_or_left_to_the_exact_path(t, k):
    """Any order of times (the active cell is found again), before, inside and after."""
    slot = slots_of({"heading": 0.7, "turn": 0.1})[k]
    table = JointTable.build(slot.legs, ROBOT)
    assert table is not None
    assert_within(table, slot.legs, ROBOT, np.array([t, 0.5 * t, t]))


def test_the_ends_are_exact_and_held_beyond_them():
    slot = slots_of({})[1]
    table = JointTable.build(slot.legs, ROBOT)
    assert table is not None
    for t, outside in ((table.t0, table.t0 - 0.3), (table.t_end, table.t_end + 0.3)):
        q, qd = exact(slot.legs, ROBOT, t)
        got = table.evaluate(t)
        assert got is not None
        np.testing.assert_allclose(got[0], q, rtol=0, atol=1e-13)
        np.testing.assert_allclose(got[1], qd, rtol=0, atol=1e-12)
        assert table.evaluate(outside) == got


def test_a_coarse_grid_leaves_its_inexact_cells_to_the_exact_path():
    slot = slots_of({})[1]
    table = JointTable.build(slot.legs, ROBOT, step=0.006)
    assert table is not None
    assert 0 < table.exact_cells < table.n_cells
    times = np.linspace(table.t0, table.t_end, 501)
    served = assert_within(table, slot.legs, ROBOT, times)
    assert 0 < served < len(times)


def test_a_slot_whose_ik_fails_gets_no_table():
    stand = ROBOT.standing_feet()
    far = stand.copy()
    far[0] += (0.5, 0.0, 0.0)  # out of the leg's reach mid-way
    legs = [Piecewise([rest_segment(stand[i], stand[i], 0.2),
                       rest_segment(stand[i], far[i], 0.2)]) for i in range(ROBOT.n_legs)]
    assert JointTable.build(legs, ROBOT) is None
    assert JointTable.build(legs[1:] + legs[:1], ROBOT) is None  # whichever leg fails
