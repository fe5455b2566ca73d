"""Stand / sit moves: the measured-pose tolerance, refusals and the move itself."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.motion.gait import standing_pose
from crawler_motion.planner.context import PlannerContext
from crawler_motion.planner.moves import (
    MEASURED_LIMIT_TOLERANCE,
    MIN_MOVE_TIME,
    JointMove,
    MoveController,
    outside_tolerance,
)
from crawler_motion.planner.state import ESTOP, IDLE, MOVING, STANDING, STOPPING

CFG = load_config()
ROBOT = CFG.robot
STAND = standing_pose(CFG)


@pytest.mark.parametrize("offset, outside", [
    (0.0, False),
    (MEASURED_LIMIT_TOLERANCE * 0.999, False),
    (MEASURED_LIMIT_TOLERANCE * 1.001, True),
    (-MEASURED_LIMIT_TOLERANCE * 0.999, False),
    (-MEASURED_LIMIT_TOLERANCE * 1.001, True),
])
def test_measured_angles_within_the_tolerance_of_a_limit(offset, outside):
    q = STAND.copy()
    q[2, 1] = (ROBOT.upper[1] if offset >= 0 else ROBOT.lower[1]) + offset
    assert outside_tolerance(ROBOT, q) is outside


def controller(state=STANDING, measured=True, paused=False) -> MoveController:
    ctx = PlannerContext(12)
    ctx.state = state
    ctx.paused = paused
    moves = MoveController(CFG, ctx, 1.0)
    if measured:
        moves.set_measured(STAND, 0.0)
    return moves


def moving() -> MoveController:
    moves = controller(IDLE)
    moves.start(0.0, STAND, STANDING, "stand")
    return moves


@pytest.mark.parametrize("make, now, reason", [
    (lambda: controller(ESTOP), 0.5, "e-stop latched"),
    (lambda: controller(STOPPING), 0.5, "refused while STOPPING"),
    (lambda: moving(), 0.5, "a stand move is in progress"),
    (lambda: controller(paused=True), 0.5, "paused"),
    (lambda: controller(measured=False), 0.5, "no measured joint_states"),
    (lambda: controller(), 1.01, r"1\.01 s old \(max 1 s\)"),
])
def test_refusals(make, now, reason):
    moves = make()
    state, move = moves.ctx.state, moves.move
    with pytest.raises(CommandError, match=reason):
        moves.start(now, STAND, STANDING, "stand")
    assert moves.ctx.state == state and moves.move is move


def test_a_measurement_exactly_max_age_old_still_starts_a_move():
    moves = controller()
    moves.start(1.0, STAND, STANDING, "stand")
    assert moves.ctx.state == MOVING and moves.target == "stand"


def test_a_move_runs_to_its_end_state_and_holds_the_pose():
    moves = controller()
    moves.set_measured(STAND + 0.05, 0.0)
    moves.start(0.0, STAND, STANDING, "stand")
    move = moves.move
    assert move is not None and move.duration >= MIN_MOVE_TIME
    first = moves.tick(0.0)
    np.testing.assert_allclose(first.positions, (STAND + 0.05).reshape(-1), atol=1e-12)
    np.testing.assert_allclose(first.velocities, 0.0, atol=1e-12)
    mid = moves.tick(move.duration / 2)
    np.testing.assert_allclose(mid.positions, (STAND + 0.025).reshape(-1), atol=1e-12)
    end = moves.tick(move.duration)
    assert moves.ctx.state == STANDING and moves.move is None and end is moves.ctx.hold
    np.testing.assert_array_equal(end.positions, STAND.reshape(-1))


def test_a_move_starts_from_the_measured_pose_clipped_into_the_limits():
    start = STAND.copy()
    start[0, 0] = ROBOT.upper[0] + MEASURED_LIMIT_TOLERANCE / 2
    move = JointMove(CFG, start, STAND, 0.0, STANDING, "stand")
    assert move.at(0.0).positions[0] == ROBOT.upper[0]
