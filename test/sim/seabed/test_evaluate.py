"""The walk evaluator: the plan's no-slip path, and a physical walk that advances as planned."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from crawler_motion.motion.gait import WalkParams, plan_walk
from crawler_motion.sim.seabed.evaluate import EvalResult, evaluate_walk, format_table
from crawler_motion.sim.seabed.metrics import (
    attitude,
    no_slip_path,
    plan_phases,
    planned_displacement,
    stance_runs,
    steady_cycles,
)
from crawler_motion.sim.seabed.replay import ReplayOptions


@pytest.fixture(scope="module")
def diagonal_walk(cfg) -> EvalResult:
    return evaluate_walk(cfg, WalkParams.defaults(cfg.gait, gait="diagonal"), steps=2)


def test_diagonal_walk_in_water_advances_as_planned(diagonal_walk):
    result = diagonal_walk
    assert len(result.cycles) == 2
    summary = result.summary()
    assert 0.9 <= summary["advance_ratio"] <= 1.1
    assert summary["planned_advance"] == pytest.approx(0.12, rel=1e-3)  # 2 stances x 0.06 m
    assert abs(summary["lateral_drift"]) < 0.01
    assert summary["body_contact"] == 0.0
    assert 0.0 < summary["torque_p99"] <= 4.0  # the effort limit
    assert result.speedup > 1.0


def test_result_is_plain_json(diagonal_walk):
    data = json.loads(json.dumps(diagonal_walk.to_dict(), allow_nan=False))
    assert data["summary"]["turn_ratio"] is None  # a straight walk has no turn to compare
    assert data["medium"] == "water" and len(data["cycles"]) == 2
    table = format_table([("diagonal fwd water flat", diagonal_walk)])
    assert "diagonal fwd water flat" in table.splitlines()[2]
    assert table.splitlines()[2].split("|")[4].strip() == "-"


@pytest.mark.parametrize(("params", "advance", "turn"), [
    ({"gait": "diagonal"}, 0.12, 0.0),
    # stance 3 x 0.6 s + 4 x 0.3 s of transfer: 0.06 m per 3.0 s stance, 3.6 s cycle
    ({"gait": "wave"}, 0.072, 0.0),
    ({"gait": "diagonal", "heading": math.pi / 2}, 0.12, 0.0),
    ({"gait": "diagonal", "stride": 0.0, "turn": 0.2}, 0.0, 0.2),
])
def test_no_slip_path_of_the_plan(cfg, params, advance, turn):
    plan = plan_walk(cfg, WalkParams.defaults(cfg.gait, **params), 2)
    time = np.arange(0.0, plan.duration, 0.002)
    phases = plan_phases(plan, time)
    path = no_slip_path(plan, time, phases.stance)
    k0, k1 = steady_cycles(plan, time)[0]
    assert np.hypot(*(path[k1, :2] - path[k0, :2])) == pytest.approx(advance, abs=2e-3)
    assert path[k1, 2] - path[k0, 2] == pytest.approx(turn, abs=5e-3)


@pytest.mark.parametrize(("params", "steps", "expected"), [
    # diagonal: start half step 0.06 m + 0.12 m per cycle; wave: 0.072 m per cycle, start
    # 3 x 1/6 stride and stop 0.5 - e = 0.4 stride (its last transfer's share e = 0.1)
    ({"gait": "diagonal"}, 1, (0.18, 0.0, 0.0)),
    ({"gait": "diagonal"}, 3, (0.42, 0.0, 0.0)),
    ({"gait": "wave"}, 1, (0.126, 0.0, 0.0)),
    ({"gait": "diagonal", "heading": math.pi / 2}, 1, (0.0, 0.18, 0.0)),
])
def test_planned_displacement_of_a_whole_walk(cfg, params, steps, expected):
    plan = plan_walk(cfg, WalkParams.defaults(cfg.gait, **params), steps)
    assert planned_displacement(plan) == pytest.approx(expected, abs=1e-5)


def test_planned_displacement_of_a_turn_on_the_spot(cfg):
    params = WalkParams.defaults(cfg.gait, gait="diagonal", stride=0.0, turn=0.2)
    x, y, yaw = planned_displacement(plan_walk(cfg, params, 2))
    assert abs(x) < 1e-6 and abs(y) < 1e-6
    assert yaw == pytest.approx(0.5, abs=1e-3)  # 2 cycles of 0.2 rad plus the half steps


def test_plan_phases_boundaries(cfg):
    plan = plan_walk(cfg, WalkParams.defaults(cfg.gait, gait="diagonal"), 1)
    swing = plan.slots[0].swing_time
    group = list(plan.slots[0].group)
    phases = plan_phases(plan, np.array([0.0, 1e-9, swing / 2, swing - 1e-9, swing,
                                         swing + 1e-9]))
    others = [i for i in range(4) if i not in group]
    # at lift-off (A) and touch-down (E) the foot is on the ground: every foot down there
    assert phases.stance[0].all() and phases.stance[4].all()
    assert not phases.stance[1:4, group].any() and phases.stance[5, group].all()
    assert phases.swing_phase[2, group] == pytest.approx(0.5)
    assert phases.stance[:5, others].all() and np.isnan(phases.swing_phase[:5, others]).all()
    assert not phases.stance[5, others].any()  # the next slot: the other pair has lifted off
    assert phases.swing_phase[5, others] == pytest.approx(1e-9 / swing)


def test_stance_runs_and_attitude():
    stance = np.array([[1, 0], [1, 1], [0, 1], [1, 1]], dtype=bool)
    assert stance_runs(stance) == [(0, 0, 1), (0, 3, 3), (1, 1, 3)]
    half = math.sqrt(0.5)
    assert attitude(np.array([[half, 0, 0, half]]))[0] == pytest.approx([0, 0, math.pi / 2])
    assert attitude(np.array([[half, 0, half, 0]]))[0, 1] == pytest.approx(math.pi / 2)


def test_replay_options_are_validated():
    with pytest.raises(ValueError, match="sample_period"):
        ReplayOptions(control_period=0.01, sample_period=0.02)


@pytest.mark.parametrize(("rate", "spin", "displacement"), [
    (0.01, 0.01 / 0.008, 0.0),  # rolls without sliding: the centre moves, the contact does not
    (0.01, 0.0, 0.01),  # slides without turning: 10 mm in 1 s
    (0.0, 1.0, 0.008),  # spins in place: the contact point scrubs r per radian
    (-0.01, -0.01 / 0.008, 0.0),  # rolls back
])
def test_the_contact_point_of_a_rolling_foot_does_not_move(rate, spin, displacement):
    """A sphere of radius 8 mm whose centre moves at ``rate`` [m/s] along x while it turns at
    ``spin`` [rad/s] about y for 1 s: its contact point's net travel over the ground."""
    from crawler_motion.sim.seabed.evaluate import _contact_velocity, net_slide
    from crawler_motion.sim.seabed.replay import Recording

    t = np.linspace(0.0, 1.0, 501)
    n = t.size
    velocity = np.zeros((n, 1, 6))
    velocity[:, 0, 0], velocity[:, 0, 4] = rate, spin
    feet = np.zeros((n, 1, 3))
    feet[:, 0, 0] = rate * t
    rec = Recording(time=t, base=np.zeros((n, 7)), feet=feet, foot_velocity=velocity,
                    loads=np.ones((n, 1)), body_contact=np.zeros(n, dtype=bool),
                    torque=np.zeros((n, 12)))
    assert net_slide(_contact_velocity(rec, 0.008)[:, 0], t) == pytest.approx(displacement,
                                                                             abs=1e-12)
