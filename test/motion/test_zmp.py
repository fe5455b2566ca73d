"""Tests of crawler_motion.motion.zmp: the default gait's body plan keeps the zero-moment point
on the support line (planned, for every walk kind) and stays C² across slots.

The ZMP is computed here from the plan's definition, not from the module's sway: the stance
feet stand still on the ground, so the body's acceleration in the world is minus the stance
contact points' acceleration in base_link, and ``p = -a_body / w²`` relative to the body
centre; its distance to the line through the two stance contact points is checked.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crawler_motion.model.config import load_config
from crawler_motion.model.medium import MediumConfig
from crawler_motion.motion.gait import GaitSequencer, WalkParams, plan_walk
from crawler_motion.motion.trajectory import Piecewise
from crawler_motion.motion.zmp import (
    SETTLE_TIME,
    ZmpWeights,
    line_distance,
    line_terms,
    solve_sway,
)

CFG = load_config()
GAIT = CFG.gait
ZMP_GAIT = "diagonal_zmp"
#: Planned ZMP distance allowed [m]: steady slots, and start / stop slots (the body changes
#: its motion there and the sway starts from or ends at rest).
STEADY_BOUND = 0.5e-3
EDGE_BOUND = 3e-3


def walk(stopping_after: int = 5, **overrides: object) -> list:
    """The slots of a walk of the default gait with ``overrides``, stopping after
    ``stopping_after`` slots."""
    seq = GaitSequencer(CFG, WalkParams.defaults(GAIT, **overrides))
    slots = []
    for k in range(40):
        slot = seq.next_slot(stopping=k >= stopping_after)
        if slot is None:
            break
        slots.append(slot)
    return slots


def zmp_distance(slot, cfg=CFG, samples: int = 81) -> np.ndarray:
    """Distance [m] of the ZMP from the support line over the slot's swing (see the module
    docstring)."""
    omega2 = cfg.medium.omega2(float(slot.params.body_height))
    t = np.linspace(0.0, slot.swing_time, samples)
    stance = [i for i in range(len(slot.contacts)) if i not in slot.group]
    pos = [slot.contacts[i].evaluate(t)[0][:, :2] for i in stance]
    acc = np.mean([slot.contacts[i].evaluate(t)[2][:, :2] for i in stance], axis=0)
    zmp = acc / omega2 + cfg.medium.zmp_shift  # p = c - c''/w², c = 0, c'' = -acc
    return line_distance(zmp, pos[0], pos[1])


def test_the_default_gait_is_the_zmp_diagonal():
    assert GAIT.gait == ZMP_GAIT
    assert ZMP_GAIT in GAIT.zmp_gaits
    for kept in ("diagonal", "diagonal_sway", "wave"):
        assert kept in GAIT.gaits and kept not in GAIT.zmp_gaits


WALK_KINDS = {
    "forward": {},
    "backward": {"heading": math.pi},
    "sideways": {"heading": math.pi / 2},
    "45 deg": {"heading": math.pi / 4},
    "any heading": {"heading": -2.1},
    "turn on the spot": {"stride": 0.0, "turn": 0.3},
    "arc": {"turn": 0.2},
    "short stride": {"stride": 0.02},
}


@pytest.mark.parametrize("kind", WALK_KINDS)
def test_the_planned_zmp_stays_on_the_support_line(kind):
    slots = walk(**WALK_KINDS[kind])
    assert slots[0].kind == "start" and slots[-1].kind == "stop"
    for slot in slots:
        bound = STEADY_BOUND if slot.kind == "steady" else EDGE_BOUND
        found = zmp_distance(slot)
        assert found.max() <= bound, (kind, slot.kind, found.max())


def test_without_the_sway_the_same_walk_rocks():
    # The same slots without their sway (the plan's contact points plus the sway) put the ZMP
    # far off the line: the check above can fail.
    slots = walk()
    steady = next(s for s in slots if s.kind == "steady")
    t = np.linspace(0.0, steady.swing_time, 81)
    sway = steady.sway.evaluate(t)
    stance = [i for i in range(4) if i not in steady.group]
    pos = [steady.contacts[i].evaluate(t)[0][:, :2] + sway[0][:, :2] for i in stance]
    acc = np.mean([steady.contacts[i].evaluate(t)[2][:, :2] + sway[2][:, :2] for i in stance],
                  axis=0)
    omega2 = CFG.medium.omega2(float(steady.params.body_height))
    assert line_distance(acc / omega2, pos[0], pos[1]).max() > 5e-3
    assert np.abs(sway[0]).max() > 1e-3  # the body does sway


def test_a_cmd_vel_change_at_a_slot_boundary_keeps_the_zmp_on_the_line():
    seq = GaitSequencer(CFG, WalkParams.defaults(GAIT))
    slots = [seq.next_slot() for _ in range(3)]
    seq.set_params(WalkParams.defaults(GAIT, heading=0.8, stride=0.03, turn=0.1))
    slots += [seq.next_slot() for _ in range(3)]
    while not seq.standing:
        slots.append(seq.next_slot(stopping=True))
    for slot in slots:
        # the first slot after the change was previewed as the old walk: the edge bound
        assert zmp_distance(slot).max() <= EDGE_BOUND
    assert_c2(slots)


def joined(slots: list, part: str) -> list[Piecewise]:
    return [Piecewise([seg for s in slots for seg in getattr(s, part)[i].segments])
            for i in range(4)]


def assert_c2(slots: list) -> None:
    """Position, velocity and acceleration continuous at every junction of every leg and of
    the sway (from the coefficients: u = 1 of one segment against u = 0 of the next)."""
    sway = Piecewise([seg for s in slots for seg in s.sway.segments])
    for pw in [*joined(slots, "legs"), sway]:
        c, dur = pw.coeffs, pw.durations[:, None]
        i = np.arange(c.shape[-1])
        left = (c.sum(-1), (c * i).sum(-1) / dur, (c * i * (i - 1)).sum(-1) / dur**2)
        right = (c[..., 0], c[..., 1] / dur, 2 * c[..., 2] / dur**2)
        for x, y, tol in zip(left, right, (1e-9, 1e-7, 1e-5), strict=True):
            assert np.abs(x[:-1] - y[1:]).max() <= tol


@pytest.mark.parametrize("kind", ["forward", "sideways", "turn on the spot", "arc"])
def test_the_body_path_is_c2_across_slots_and_ends_standing(kind):
    slots = walk(**WALK_KINDS[kind])
    assert_c2(slots)
    sway = Piecewise([seg for s in slots for seg in s.sway.segments])
    pos, vel, acc = sway.evaluate(np.array([0.0, sway.t_end]))
    np.testing.assert_allclose(pos, 0.0, atol=1e-12)
    np.testing.assert_allclose(vel, 0.0, atol=1e-9)
    np.testing.assert_allclose(acc, 0.0, atol=1e-7)
    assert slots[-1].duration > slots[-1].swing_time + SETTLE_TIME - 1e-9


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(heading=st.floats(-math.pi, math.pi), stride=st.floats(0.0, 0.045),
       turn=st.floats(-0.2, 0.2), swing=st.floats(0.4, 0.7))
def test_any_reachable_walk_keeps_its_zmp_on_the_line(heading, stride, turn, swing):
    plan = plan_walk(CFG, WalkParams.defaults(GAIT, heading=heading, stride=stride, turn=turn,
                                              swing_time=swing), 2)
    for slot in plan.slots:
        bound = STEADY_BOUND if slot.kind == "steady" else EDGE_BOUND
        assert zmp_distance(slot).max() <= bound
    assert_c2(list(plan.slots))


@pytest.mark.parametrize("medium", [MediumConfig(1.0, 0.0), MediumConfig(0.2, 0.5),
                                    MediumConfig(0.3, 0.0, np.array([0.001, -0.0005, 0.01]))])
def test_the_plan_follows_the_medium(medium):
    # land, a lighter robot with added mass, a buoyancy offset (a constant ZMP shift)
    cfg = replace(CFG, medium=medium)
    seq = GaitSequencer(cfg, WalkParams.defaults(GAIT))
    slots = [seq.next_slot(stopping=k >= 5) for k in range(7)]
    slots = [s for s in slots if s is not None]
    shift = float(np.linalg.norm(medium.zmp_shift))  # the standing robot's own ZMP offset
    for slot in slots:
        bound = EDGE_BOUND + (2 * shift if slot.kind == "start" else 0.0)
        assert zmp_distance(slot, cfg).max() <= bound
    assert zmp_distance(slots[-2], cfg).max() <= STEADY_BOUND  # settled on the shifted ZMP


def test_a_walk_the_limits_refuse_even_with_the_smallest_sway_is_refused_with_the_reason():
    with pytest.raises(Exception, match="cannot be executed: leg"):
        plan_walk(CFG, WalkParams.defaults(GAIT, stride=0.08, heading=math.pi / 2), 1)


# --- the least-squares core -------------------------------------------------------------------

def test_solve_sway_meets_its_boundary_states_and_the_line():
    # A fixed line y = 0.01 (normal +y): the bounded answer holds y at the line's offset,
    # starting and ending at the given states.
    omega2 = 30.0
    knots = np.linspace(0.0, 1.0, 9)
    t = np.linspace(0.0, 1.0, 201)
    normals = np.tile([0.0, 1.0], (len(t), 1))
    targets = np.full(len(t), 0.01)
    start = np.array([[0.0, 0.01], [0.0, 0.0], [0.0, 0.0]])
    end = np.array([[0.002, 0.01], [0.0, 0.0], [0.0, 0.0]])
    plan = solve_sway(knots, start, end, t, normals, targets, np.ones(len(t), bool), omega2,
                      ZmpWeights(sway=1e-4, accel=1e-4))
    np.testing.assert_allclose(plan.states[0], start, atol=1e-12)
    np.testing.assert_allclose(plan.states[-1], end, atol=1e-12)
    sway = Piecewise(plan.segments(len(knots) - 1))
    pos, _, acc = sway.evaluate(t)
    assert np.abs(pos[:, 1] - acc[:, 1] / omega2 - 0.01).max() < 1e-4


def test_line_terms_refuse_a_degenerate_line():
    from crawler_motion.errors import GaitError

    a = np.zeros((3, 2))
    with pytest.raises(GaitError, match="coincide"):
        line_terms(a, a, a, 30.0, np.zeros(2))
