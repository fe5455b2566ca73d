"""The walk's touch-down offsets in the planner core: the contact estimate in, the foot targets
and the walk's end out."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.motion.contact_estimation import ContactEstimate, FootContact
from crawler_motion.motion.fastpath import FastKinematics, Track, joint_targets
from crawler_motion.motion.foothold import FootholdSettings, Mode
from crawler_motion.motion.gait import WalkParams, plan_walk, standing_pose
from crawler_motion.planner.contacts import ContactMonitor
from crawler_motion.planner.core import PlannerCore
from crawler_motion.planner.footholds import Footholds
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
            core.contacts.last = _estimate(t, state)
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
            footholds.monitor.last = _estimate(t, FootContact.YES)
            t0 = pause if t >= 0.5 else 0.0  # frozen for ``pause`` s at 0.5 s of the slot
            out.append(footholds.targets(track, kin, t + t0, t0)[0])
        runs.append(np.array(out))
    np.testing.assert_allclose(runs[0], runs[1], atol=1e-12)
    blind = np.array([joint_targets(track, kin, k * DT)[0] for k in range(60)])
    assert np.abs(runs[0] - blind).max() > 1e-3  # the early contacts did move the feet
