"""The walk's touch-down offsets in the planner core: the contact estimate in, the foot targets
and the walk's end out."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.motion.attitude import AttitudeSettings
from crawler_motion.motion.contact_estimation import ContactEstimate, FootContact
from crawler_motion.motion.fastpath import FastKinematics, Track, joint_targets
from crawler_motion.motion.foothold import FootholdSettings, Mode
from crawler_motion.motion.gait import WalkParams, plan_walk, standing_pose
from crawler_motion.motion.jointtable import JointTable
from crawler_motion.motion.stumble import StumbleSettings
from crawler_motion.planner.contacts import ContactMonitor
from crawler_motion.planner.core import PlannerCore
from crawler_motion.planner.footholds import Footholds, slot_facts
from crawler_motion.planner.state import HOLDING, STANDING

CFG = load_config()
ROBOT = CFG.robot
DT = 0.01


def _estimate(t: float, state: FootContact) -> ContactEstimate:
    n = ROBOT.n_legs
    return ContactEstimate(t, (state,) * n, np.full(n, 5.0), np.zeros((n, 3)))


def _standing() -> tuple[PlannerCore, float]:
    core = PlannerCore(CFG, 100.0)
    core.set_measured(standing_pose(CFG), 0.0)
    core.submit('{"command": "stand"}', 0.0)
    t = 0.0
    while core.state != STANDING:
        core.tick(t)
        t = round(t + DT, 9)
    return core, t


def _walk(core: PlannerCore, t: float, state: FootContact | None, limit: float = 10.0
          ) -> tuple[list[np.ndarray], float]:
    core.submit('{"command": "walk", "steps": 1}', t)
    feet = []
    end = t + limit
    while t < end and core.state not in (STANDING, HOLDING):
        if state is not None:
            core.contacts.take(_estimate(t, state), t)
        target = core.tick(t)
        assert target is not None
        feet.append(forward_kinematics(ROBOT, target.positions.reshape(-1, 3)))
        t = round(t + DT, 9)
    return feet, t


@pytest.mark.parametrize("state", [None, FootContact.UNKNOWN])
def test_unknown_contacts_walk_the_blind_plan(state: FootContact | None) -> None:
    core, t = _standing()
    core.walk.foothold.configure(FootholdSettings(enabled=True))
    feet, _ = _walk(core, t, state)
    plan = plan_walk(CFG, WalkParams.defaults(CFG.gait), 1)
    planned = plan.legs[0].evaluate(np.arange(len(feet)) * DT)[0]
    np.testing.assert_allclose(np.array(feet)[:, 0], planned, atol=1e-8)
    assert core.state == STANDING


def test_a_foot_that_finds_no_ground_holds_the_walk_with_the_leg_and_the_depth() -> None:
    core, t = _standing()
    core.walk.foothold.configure(FootholdSettings(enabled=True, search_depth=0.005))
    feet, t = _walk(core, t, FootContact.NO)
    assert core.state == HOLDING
    events = " ".join(message for _, message in core.pop_events())
    assert "found no ground within the search depth 5.0 mm" in events
    held = core.tick(t)
    assert held is not None and np.all(held.velocities == 0.0)
    z = np.array(feet)[:, :, 2]
    lowest = z.min(axis=0)
    assert np.all(lowest >= -ROBOT.body_height - 0.005 - 1e-9)  # never beyond the depth
    assert lowest.min() == pytest.approx(-ROBOT.body_height - 0.005)


def test_disabled_adaptation_ignores_the_contacts() -> None:
    core, t = _standing()
    assert not core.walk.foothold.settings.enabled  # the default
    feet, _ = _walk(core, t, FootContact.NO)
    assert core.state == STANDING
    assert set(core.walk.foothold.adapter.modes()) == {Mode.HELD}
    assert np.array(feet)[:, :, 2].min() == pytest.approx(-ROBOT.body_height)


def test_the_offsets_run_on_the_walk_clock_through_a_freeze() -> None:
    """A walk frozen mid-slot resumes with its slot start shifted: the offsets continue
    where they were (a stop begun before the freeze ends the same)."""
    plan = plan_walk(CFG, WalkParams.defaults(CFG.gait), 2)
    slot = plan.slots[1]
    track = Track(slot.legs)
    kin = FastKinematics(ROBOT)
    runs = []
    for pause in (0.0, 3.7):
        footholds = Footholds(ROBOT, FootholdSettings(enabled=True))
        footholds.monitor = ContactMonitor(ROBOT)
        footholds.begin_slot(slot)
        out = []
        for k in range(60):
            t = k * DT
            footholds.monitor.take(_estimate(t, FootContact.YES), t)
            t0 = pause if t >= 0.5 else 0.0  # frozen for ``pause`` s at 0.5 s of the slot
            out.append(footholds.targets(track, kin, t + t0, t0)[0])
        runs.append(np.array(out))
    np.testing.assert_allclose(runs[0], runs[1], atol=1e-12)
    blind = np.array([joint_targets(track, kin, k * DT)[0] for k in range(60)])
    assert np.abs(runs[0] - blind).max() > 1e-3  # the early contacts did move the feet


def _hit_walk(core: PlannerCore, t: float, hit_from: float, hit_until: float,
              limit: float = 10.0) -> tuple[list[np.ndarray], float]:
    """A 1-step walk whose first swinging leg touches something with 20 N from slot time
    ``hit_from`` to ``hit_until`` [s] of its swing (off the ground before); the feet out."""
    core.submit('{"command": "walk", "steps": 1}', t)
    footholds = core.walk.foothold
    n = ROBOT.n_legs
    first: tuple[int, ...] | None = None
    feet = []
    end = t + limit
    while t < end and core.state not in (STANDING, HOLDING):
        slot = footholds._slot
        states = [FootContact.YES] * n
        force = np.zeros((n, 3))
        force[:, 2] = 5.0
        if slot is not None and slot.swing_time > 0.0:
            first = first or slot.group
            s = t - core.walk.slot_t0
            for i in slot.group:
                states[i] = FootContact.NO
                if slot.group == first and hit_from <= s < hit_until:
                    states[i] = FootContact.YES
                    force[i] = (-20.0, 0.0, 0.0)  # a face ahead of the foot pushes it back
        core.contacts.take(ContactEstimate(t, tuple(states), force[:, 2].copy(), force), t)
        target = core.tick(t)
        assert target is not None
        feet.append(forward_kinematics(ROBOT, target.positions.reshape(-1, 3)))
        t = round(t + DT, 9)
    return feet, t


def test_a_swinging_foot_that_hits_once_is_lifted_higher_and_lands_as_planned() -> None:
    core, t = _standing()
    core.walk.foothold.configure(FootholdSettings(enabled=True))
    feet, _ = _hit_walk(core, t, 0.2, 0.22)
    assert core.state == STANDING, core.pop_events()
    z = np.array(feet)[:, :, 2]
    other = _standing()
    other[0].walk.foothold.configure(FootholdSettings(enabled=True))
    unhit, _ = _hit_walk(*other, 1.0, 1.0)  # the same contacts without the hit
    lift = core.walk.foothold.stumble.lift
    assert z.max() == pytest.approx(np.array(unhit)[:, :, 2].max() + lift, abs=1e-3)
    assert len(feet) == len(unhit)
    np.testing.assert_allclose(feet[-1], unhit[-1], atol=1e-9)  # the same footholds
    steps = np.diff(np.array(feet), axis=0)
    assert np.abs(np.diff(steps, axis=0)).max() < 5e-3  # no jump of the targets [m/tick]


def test_a_foot_that_hits_again_after_the_retry_holds_the_walk_with_leg_and_place() -> None:
    core, t = _standing()
    core.walk.foothold.configure(FootholdSettings(enabled=True))
    _hit_walk(core, t, 0.2, 1.0)
    assert core.state == HOLDING
    events = " ".join(message for _, message in core.pop_events())
    assert "hit an obstacle again after lifting 15 mm higher, at x" in events
    assert "send stand (or sit) to recover" in events


def test_a_hit_is_ignored_without_stumble_retry() -> None:
    core, t = _standing()
    core.walk.foothold.configure(FootholdSettings(enabled=True), StumbleSettings(enabled=False))
    feet, _ = _hit_walk(core, t, 0.2, 0.22)
    blind, _ = _walk(*_standing(), None)
    assert core.state == STANDING
    assert np.array(feet)[:, :, 2].max() == pytest.approx(np.array(blind)[:, :, 2].max(),
                                                           abs=1e-4)  # not lifted 15 mm


@pytest.mark.parametrize(("enabled", "mode", "tilted"), [
    (True, "stance_plane", True),  # front feet 1 cm up
    (True, "imu", True),  # no IMU reading: the plane's
    (True, "off", False),
    (False, "stance_plane", False),  # the blind plan
])
def test_the_body_heads_for_the_plane_of_the_footholds(enabled: bool, mode: str,
                                                       tilted: bool) -> None:
    slot = plan_walk(CFG, WalkParams.defaults(CFG.gait), 2).slots[1]
    x = np.array([leg.evaluate(0.0)[0][0, 0] for leg in slot.legs])
    expected = (0.004, 0.0, -math.atan(0.05)) if tilted else (0.0, 0.0, 0.0)
    footholds = Footholds(ROBOT)
    footholds.configure(FootholdSettings(enabled=enabled), None, AttitudeSettings(mode=mode))
    footholds.adapter.reset((0.004 + 0.05 * x).tolist())  # on a plane rising 5 % ahead
    footholds.begin_slot(slot)
    assert footholds.pose.target == pytest.approx(expected, abs=1e-12)
    assert footholds.pose.evaluate(slot.duration)[0] == footholds.pose.target


def test_imu_levelling_cancels_the_mean_measured_tilt() -> None:
    slots = plan_walk(CFG, WalkParams.defaults(CFG.gait), 2).slots
    footholds = Footholds(ROBOT)
    footholds.configure(FootholdSettings(enabled=True), None, AttitudeSettings(mode="imu"))
    footholds.begin_slot(slots[0])
    for roll, pitch in ((0.01, 0.03), (0.03, 0.05)):  # the body tilted by 0.02, 0.04 rad
        footholds.measure_attitude(roll, pitch)
    footholds.begin_slot(slots[1])
    assert footholds.pose.target == pytest.approx((0.0, -0.02, -0.04))


@pytest.mark.parametrize(("state", "tabulated"), [(None, True), (FootContact.YES, False)])
def test_the_blind_plan_is_served_by_the_slot_s_joint_table(
        state: FootContact | None, tabulated: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """Blind: the tick interpolates the slot's `JointTable`; with contacts known the feet
    may move off the plan, so the tick solves them (the table is never read)."""
    served: list[float] = []
    real = JointTable.evaluate

    def counting(self: JointTable, t: float) -> tuple[list[float], list[float]] | None:
        joints = real(self, t)
        if joints is not None:
            served.append(t)
        return joints

    monkeypatch.setattr(JointTable, "evaluate", counting)
    core, t = _standing()
    if state is not None:
        core.walk.foothold.configure(FootholdSettings(enabled=True))
    core.submit('{"command": "walk", "steps": 1}', t)
    n_ticks = 0
    while core.state not in (STANDING, HOLDING):
        if state is not None:
            core.contacts.take(_estimate(t, state), t)
        assert core.tick(t) is not None
        core.plan_ahead(t)  # as the node: the slots after the first are planned ahead
        n_ticks += 1
        t = round(t + DT, 9)
    assert core.state == STANDING
    assert (len(served) >= 0.5 * n_ticks) if tabulated else not served


def test_a_stumble_s_retried_track_is_never_read_from_the_slot_s_table() -> None:
    cfg_slots = plan_walk(CFG, WalkParams.defaults(CFG.gait), 2)
    seq_slots = [s for s in cfg_slots.slots if s.swing_time > 0.0]
    slot, other = seq_slots[0], seq_slots[1]
    footholds = Footholds(ROBOT)
    footholds.begin_slot(slot, slot_facts(slot, ROBOT))
    kin = FastKinematics(ROBOT)
    t = 0.6 * slot.duration
    table = JointTable.build(slot.legs, ROBOT)
    assert table is not None and footholds.targets(Track(slot.legs), kin, t, 0.0) == (
        table.evaluate(t))
    footholds.replanned = retried = Track([leg.shifted(-other.legs[0].t0) for leg in other.legs])
    q, qd = footholds.targets(Track(slot.legs), kin, t, 0.0)
    want_q, want_qd = kin.solve(*retried.evaluate(t))
    np.testing.assert_allclose(q, want_q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(qd, want_qd, rtol=0, atol=1e-12)
