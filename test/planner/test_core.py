"""The planner state machine, driven tick by tick with a synthetic monotonic clock."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.errors import CommandError, GaitError
from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.motion.fastpath import Track
from crawler_motion.motion.gait import GaitSequencer, WalkParams, plan_walk, standing_pose
from crawler_motion.planner import moves, next_slot, upfront
from crawler_motion.planner.commands import needs_stand, twist_to_params
from crawler_motion.planner.core import JointTarget, PlannerCore
from crawler_motion.planner.held_stand import STAND_HOLD
from crawler_motion.planner.moves import sitting_pose
from crawler_motion.planner.next_slot import PLAN_AHEAD_HORIZON
from crawler_motion.planner.state import (
    ESTOP,
    HOLDING,
    IDLE,
    MOVING,
    SITTING,
    STANDING,
    STOPPING,
    WALKING,
)
from crawler_motion.planner.walk import WalkController

CFG = load_config()
ROBOT = CFG.robot
DT = 0.01
STAND = standing_pose(CFG)
LO = ROBOT.lower_limits().reshape(-1)
HI = ROBOT.upper_limits().reshape(-1)
SLOT = 0.6  # the study's diagonal slot: (swing 0.6 + stance 0.6) / 2 groups
#: The walks of these state-machine tests: the study's diagonal gait (its timing is written
#: out below); the default gait's own walk through the core: test_the_default_gait_*.
DIAGONAL = WalkParams.defaults(CFG.gait, gait="diagonal")


class Clock:
    """Drives a core at 100 Hz and records every target."""

    def __init__(self, core: PlannerCore, t: float = 0.0) -> None:
        self.core = core
        self.t = t
        self.targets: list[tuple[float, JointTarget | None]] = []
        self.states: list[tuple[float, str]] = []

    def tick(self) -> JointTarget | None:
        target = self.core.tick(self.t)
        self.targets.append((self.t, target))
        self.states.append((self.t, self.core.state))
        self.t = round(self.t + DT, 9)
        return target

    def run(self, seconds: float) -> None:
        for _ in range(round(seconds / DT)):
            self.tick()

    def until(self, state: str, limit: float = 30.0) -> float:
        """Tick until the core is in ``state``; the time of the tick that got there."""
        end = self.t + limit
        while self.t < end:
            self.tick()
            if self.core.state == state:
                return self.targets[-1][0]
        raise AssertionError(f"not {state} after {limit} s: {self.core.status()}")

    def measure(self, q: np.ndarray | None = None) -> None:
        last = self.core.tick(self.t)
        pose = q if q is not None else (last.positions if last is not None else STAND)
        self.core.set_measured(pose, self.t)

    def send(self, text: str) -> None:
        self.core.submit(text, self.t)


def standing(t: float = 0.0, **kwargs) -> Clock:
    clock = Clock(PlannerCore(CFG, 100.0, **{"defaults": DIAGONAL, **kwargs}), t)
    clock.measure(STAND)
    clock.send('{"command": "stand"}')
    clock.until(STANDING)
    return clock


def positions(clock: Clock) -> np.ndarray:
    return np.array([tg.positions for _, tg in clock.targets if tg is not None])


# ------------------------------------------------------------------ stand / sit
def test_idle_publishes_nothing_and_a_stand_before_the_first_state_is_held_then_refused():
    core = PlannerCore(CFG)
    assert core.tick(0.0) is None and core.state == IDLE
    core.submit('{"command": "stand"}', 0.0)  # held, not refused
    assert "stand held" in core.status()["last_event"]
    assert core.state == IDLE and core.tick(0.01) is None
    assert core.tick(STAND_HOLD + 0.02) is None  # no state within the hold: refused
    assert "no measured joint_states within 1 s" in core.status()["last_refusal"]
    core.set_measured(STAND, STAND_HOLD + 0.03)  # too late: nothing starts by itself
    assert core.state == IDLE
    with pytest.raises(CommandError, match=r"joint_states is 1\.50 s old"):
        core.submit('{"command": "stand"}', STAND_HOLD + 1.53)
    assert core.state == IDLE


@pytest.mark.parametrize("wait", [0.0, 0.5, STAND_HOLD])
def test_a_stand_sent_before_the_first_state_starts_when_it_arrives(wait):
    clock = Clock(PlannerCore(CFG))
    clock.send('{"command": "stand", "body_height": 0.08}')
    clock.run(wait)
    assert clock.core.state == IDLE
    start = sitting_pose(CFG)
    clock.core.set_measured(start, clock.t)
    assert clock.core.state == MOVING
    first = clock.tick()
    np.testing.assert_array_equal(first.positions, start.reshape(-1))  # from the measured pose
    clock.until(STANDING)
    np.testing.assert_allclose(positions(clock)[-1], standing_pose(CFG, 0.08).reshape(-1),
                               atol=1e-12)


@pytest.mark.parametrize("later", ['{"command": "estop"}', '{"command": "stop"}'])
def test_a_later_command_replaces_a_held_stand(later):
    clock = Clock(PlannerCore(CFG))
    clock.send('{"command": "stand"}')
    try:
        clock.send(later)
    except CommandError:
        pass
    clock.core.set_measured(STAND, clock.t)
    assert clock.core.state != MOVING  # nothing starts by itself


def test_stand_from_a_measured_pose_is_smooth_and_reaches_standing():
    start = sitting_pose(CFG).copy()
    start[0] += [0.3, -0.2, 0.1]  # not any special pose
    clock = Clock(PlannerCore(CFG))
    clock.measure(start)
    clock.send('{"command": "stand"}')
    assert clock.core.state == MOVING
    first = clock.tick()
    np.testing.assert_array_equal(first.positions, start.reshape(-1))  # no jump
    np.testing.assert_array_equal(first.velocities, 0.0)
    t_end = clock.until(STANDING)
    q = positions(clock)
    np.testing.assert_allclose(q[-1], STAND.reshape(-1), atol=1e-12)
    assert t_end == pytest.approx(moves.MIN_MOVE_TIME, abs=1e-9)
    assert np.all((q >= LO) & (q <= HI))
    assert np.abs(np.diff(q, axis=0)).max() < 0.05  # no jump
    # velocities are the derivative of the positions
    v = np.array([tg.velocities for _, tg in clock.targets])
    np.testing.assert_allclose((q[2:] - q[:-2]) / (2 * DT), v[1:-1], atol=3e-3)


def test_a_long_move_keeps_to_the_velocity_limits():
    slow = replace(CFG, robot=replace(ROBOT, velocity=np.array([1.0, 0.8, 0.6])))
    far = STAND.copy()
    far[:, 2] = ROBOT.upper[2]
    duration = moves.move_duration(slow, far, STAND)
    assert duration > 2 * moves.MIN_MOVE_TIME
    clock = Clock(PlannerCore(slow))
    clock.measure(far)
    clock.send('{"command": "stand"}')
    assert clock.until(STANDING) == pytest.approx(duration, abs=DT)
    q = positions(clock)
    step = np.abs(np.diff(q, axis=0)).max(axis=0)  # per tick
    limit = moves.MOVE_SPEED_FRACTION * np.tile(slow.robot.velocity, 4) * DT
    assert np.all(step <= limit * 1.001)
    assert step[2] > 0.95 * limit[2]  # the knee sets the pace


def test_stand_measured_outside_limits():
    clock = Clock(PlannerCore(CFG))
    bad = STAND.copy()
    bad[1, 2] = ROBOT.lower[2] - 0.05
    clock.measure(bad)
    with pytest.raises(CommandError, match="measured leg lb knee joint"):
        clock.send('{"command": "stand"}')
    assert clock.core.state == IDLE
    near = STAND.copy()
    near[1, 2] = ROBOT.lower[2] - 0.01  # within the tolerance: starts on the limit
    clock.measure(near)
    clock.send('{"command": "stand"}')
    assert clock.tick().positions[5] == ROBOT.lower[2]


def test_stand_at_a_body_height_then_walk_keeps_it():
    clock = standing()
    clock.measure()
    clock.send('{"command": "stand", "body_height": 0.06}')
    clock.until(STANDING)
    feet = forward_kinematics(ROBOT, positions(clock)[-1].reshape(4, 3))
    np.testing.assert_allclose(feet, ROBOT.standing_feet(0.06), atol=1e-12)
    clock.send('{"command": "walk", "steps": 1}')
    assert clock.core.walk_params.body_height == 0.06
    clock.until(STANDING)
    feet = forward_kinematics(ROBOT, positions(clock)[-1].reshape(4, 3))
    np.testing.assert_allclose(feet, ROBOT.standing_feet(0.06), atol=1e-9)


def test_sit_and_stand_again():
    clock = standing()
    clock.measure()
    clock.send('{"command": "sit"}')
    clock.until(SITTING)
    q = positions(clock)[-1]
    np.testing.assert_allclose(q, sitting_pose(CFG).reshape(-1), atol=1e-12)
    feet = forward_kinematics(ROBOT, q.reshape(4, 3))
    np.testing.assert_allclose(feet[:, 2], -ROBOT.body_height_range[0], atol=1e-12)
    reach = np.hypot(*(feet - ROBOT.hips)[:, :2].T)
    assert np.all(reach < ROBOT.reach)  # tucked
    assert np.all((q > LO) & (q < HI))
    clock.run(0.2)
    assert clock.core.state == SITTING and clock.tick() is clock.tick()  # held
    with pytest.raises(CommandError, match="walk refused in state SITTING: send stand first"):
        clock.send('{"command": "walk"}')
    clock.measure()
    clock.send('{"command": "stand"}')
    clock.until(STANDING)


def test_sit_from_idle_starts_at_the_measurement():
    clock = Clock(PlannerCore(CFG))
    clock.measure(STAND)
    clock.send('{"command": "sit"}')
    assert clock.core.status()["target"] == "sit"
    np.testing.assert_array_equal(clock.tick().positions, STAND.reshape(-1))
    clock.until(SITTING)
    np.testing.assert_allclose(positions(clock)[-1], sitting_pose(CFG).reshape(-1), atol=1e-12)


# ------------------------------------------------------------------ walking
@pytest.mark.parametrize(("gait", "steps"), [("diagonal", 1), ("diagonal", 3), ("wave", 2)])
def test_walk_n_steps_returns_to_standing(gait, steps):
    clock = standing()
    n = len(CFG.gait.gaits[gait])
    clock.send(f'{{"command": "walk", "gait": "{gait}", "steps": {steps}, "turn": 0.1, '
               f'"heading": 0.4}}')
    t0 = clock.t
    status = clock.core.status()
    assert (status["state"], status["step"], status["steps"]) == (WALKING, 0, steps)
    seen = []
    while clock.core.state != STANDING:
        clock.tick()
        seen.append(clock.core.status()["step"])
        assert clock.t - t0 < 60
    if gait == "diagonal":  # (swing + stance) / n per slot, stance = (n - 1) x swing
        duration = (2 * (n - 1) + steps * n) * 0.6
    else:  # a crawl sways its body in transfers sized to its travel (the plan's durations)
        duration = plan_walk(CFG, WalkParams.defaults(CFG.gait, gait=gait, turn=0.1,
                                                      heading=0.4), steps).duration
    assert clock.targets[-1][0] - t0 == pytest.approx(duration, abs=1.5 * DT)
    assert seen == sorted(seen) and seen[-1] == steps and set(seen) == set(range(steps + 1))
    assert clock.core.status()["steps"] == steps
    feet = forward_kinematics(ROBOT, positions(clock)[-1].reshape(4, 3))
    np.testing.assert_allclose(feet, ROBOT.standing_feet(), atol=1e-9)
    q = positions(clock)
    assert np.all(np.isfinite(q)) and np.all((q >= LO) & (q <= HI))
    assert np.abs(np.diff(q, axis=0)).max() < 0.1  # no jumps anywhere


def test_walk_targets_follow_the_planned_walk():
    """Tick output = IK of gait.plan_walk at the same times; velocities = its joint rates."""
    clock = standing()
    params = replace(DIAGONAL, turn=0.2, stride=0.05)
    plan = plan_walk(CFG, params, 2)
    clock.send('{"command": "walk", "steps": 2, "turn": 0.2, "stride": 0.05}')
    t0 = clock.t
    clock.until(STANDING)
    times = np.array([t for t, _ in clock.targets if t - t0 < plan.duration - 1e-9])
    got = [tg for t, tg in clock.targets if t - t0 < plan.duration - 1e-9]
    q, qd = plan.joints(times - t0)
    np.testing.assert_allclose([g.positions for g in got], q.reshape(len(times), 12),
                               atol=1e-8)
    np.testing.assert_allclose([g.velocities for g in got], qd.reshape(len(times), 12),
                               atol=1e-7)


def test_stop_mid_walk_finishes_the_slot_then_the_half_step():
    clock = standing()
    clock.send('{"command": "walk"}')
    t0 = clock.t
    clock.run(1.55)  # inside the third slot [1.2, 1.8)
    assert clock.core.state == WALKING and clock.core.status()["steps"] is None
    clock.send('{"command": "stop"}')
    assert clock.core.state == STOPPING
    t_stand = clock.until(STANDING)
    assert t_stand - t0 == pytest.approx(3 * SLOT + SLOT, abs=DT + 1e-9)
    feet = forward_kinematics(ROBOT, positions(clock)[-1].reshape(4, 3))
    np.testing.assert_allclose(feet, ROBOT.standing_feet(), atol=1e-9)


def test_params_change_only_at_slot_boundaries():
    a, b = standing(), standing()
    for clock in (a, b):
        clock.send('{"command": "walk"}')
    t0 = a.t
    a.run(1.5)
    b.run(1.5)  # mid slot [1.2, 1.8)
    b.send('{"command": "walk", "stride": 0.03, "turn": 0.2}')
    assert b.core.walk_params.stride == 0.06  # not yet
    while a.t - t0 < 2.2:
        ta, tb = a.tick(), b.tick()
        t = a.targets[-1][0] - t0
        if t < 3 * SLOT - 1e-9:
            np.testing.assert_array_equal(ta.positions, tb.positions)
            assert b.core.walk_params.stride == 0.06
    assert b.core.walk_params.stride == 0.03 and b.core.walk_params.turn == 0.2
    assert np.abs(ta.positions - tb.positions).max() > 1e-3
    # a gait change is refused while walking, and leaves everything as it was
    rev = b.core.revision
    with pytest.raises(CommandError, match="gait can only change while standing"):
        b.send('{"command": "walk", "gait": "wave"}')
    assert b.core.state == WALKING and b.core.walk_params.gait == "diagonal"
    assert b.core.revision == rev + 1  # only the refusal


def test_walk_command_while_walking_sets_a_new_step_budget_at_the_next_slot():
    clock = standing()
    clock.send('{"command": "walk"}')
    t0 = clock.t
    clock.run(0.9)  # inside the second slot [0.6, 1.2)
    clock.send('{"command": "walk", "steps": 1, "stride": 0.04}')
    assert clock.core.status()["steps"] is None and clock.core.walk_params.stride == 0.06
    clock.run(0.35)
    assert clock.core.status()["steps"] == 1 and clock.core.walk_params.stride == 0.04
    assert clock.until(STOPPING) - t0 == pytest.approx(4 * SLOT, abs=DT)  # 2 more slots
    assert clock.until(STANDING) - t0 == pytest.approx(5 * SLOT, abs=DT)
    assert clock.core.status()["step"] == 1


def test_walk_refused_as_a_whole_when_it_cannot_be_executed():
    params = WalkParams.defaults(CFG.gait, stride=0.08, heading=math.pi / 2)
    with pytest.raises(GaitError):
        plan_walk(CFG, params, 1)
    clock = standing()
    with pytest.raises(CommandError, match=r"walk refused as a whole: .*leg lb"):
        clock.send('{"command": "walk", "steps": 5, "stride": 0.08, "heading": 1.5707963}')
    assert clock.core.state == STANDING
    clock.run(0.1)
    assert clock.core.state == STANDING


def test_a_failing_slot_stops_the_walk(monkeypatch):
    monkeypatch.setattr(next_slot, "SLOWED_SHARES", ())  # no slower slot passes either
    clock = standing(cmd_vel_timeout=5.0)
    clock.core.on_twist(0.0, 0.066, 0.0, clock.t)  # sideways: fine
    t0 = clock.t
    clock.run(0.9)
    clock.core.on_twist(0.0, 0.133, 0.0, clock.t)  # within the limits, out of reach
    clock.run(0.1)
    assert clock.core.state == WALKING
    clock.run(0.25)  # boundary at 1.2
    assert clock.core.state == STOPPING
    assert "slot check failed" in clock.core.status()["last_event"]
    assert clock.until(STANDING) - t0 == pytest.approx(3 * SLOT, abs=DT)
    feet = forward_kinematics(ROBOT, positions(clock)[-1].reshape(4, 3))
    np.testing.assert_allclose(feet, ROBOT.standing_feet(), atol=1e-9)


def test_a_failing_cmd_vel_slot_is_slowed_and_stated():
    """The twist of the test above with `next_slot.SLOWED_SHARES`: the slot is walked at a
    share of the stride, stated in the status, and a feasible twist is walked as asked again."""
    clock = standing(cmd_vel_timeout=5.0)
    clock.core.on_twist(0.0, 0.066, 0.0, clock.t)
    clock.run(0.9)
    asked = 0.133 * float(clock.core.walk_params.stance_time)
    clock.core.on_twist(0.0, 0.133, 0.0, clock.t)  # within the limits, out of reach
    clock.run(0.35)  # boundary at 1.2
    status = clock.core.status()
    assert clock.core.state == WALKING
    assert status["slowed_share"] in next_slot.SLOWED_SHARES
    assert status["slowed_slots"] == 1
    assert status["last_event"].startswith(f"slot slowed to {status['slowed_share']:.0%}")
    assert "reachable" in status["last_event"]
    assert clock.core.walk_params.stride == pytest.approx(asked * status["slowed_share"])
    clock.core.on_twist(0.0, 0.066, 0.0, clock.t)
    clock.run(2 * SLOT)
    status = clock.core.status()
    assert (status["slowed_share"], status["slowed_slots"]) == (1.0, 1)
    assert clock.core.state == WALKING


def test_holding_when_not_even_a_stop_slot_passes(monkeypatch):
    clock = standing()
    clock.send('{"command": "walk"}')
    clock.run(0.3)

    def refuse(*args):
        raise GaitError("synthetic failure")

    monkeypatch.setattr(next_slot, "check_trajectories", refuse)  # the next slot's check
    clock.run(0.4)
    assert clock.core.state == HOLDING
    held = clock.tick()
    assert held is clock.tick() and np.all(held.velocities == 0.0)
    monkeypatch.undo()
    clock.measure()
    clock.send('{"command": "stand"}')
    clock.until(STANDING)


# ------------------------------------------------------------------ estop, refusals
def test_estop_latches_until_reset_then_needs_stand():
    clock = standing()
    clock.send('{"command": "walk"}')
    clock.run(0.35)
    clock.send('{"command": "estop"}')
    assert clock.tick() is None and clock.core.state == ESTOP
    for text in ('{"command": "stand"}', '{"command": "walk"}', '{"command": "sit"}'):
        with pytest.raises(CommandError, match="e-stop latched"):
            clock.send(text)
    with pytest.raises(CommandError, match="state ESTOP"):
        clock.core.on_twist(0.05, 0, 0, clock.t)
    clock.run(1.0)
    assert all(tg is None for _, tg in clock.targets[-100:])
    clock.send('{"command": "reset"}')
    assert clock.core.state == IDLE and clock.tick() is None
    with pytest.raises(CommandError, match="send stand first"):
        clock.send('{"command": "walk"}')
    clock.measure(STAND)
    clock.send('{"command": "stand"}')
    assert clock.tick() is not None
    clock.until(STANDING)


def _walking():
    clock = standing()
    clock.send('{"command": "walk"}')
    clock.run(0.2)
    return clock


def _moving():
    clock = Clock(PlannerCore(CFG))
    clock.measure(STAND)
    clock.send('{"command": "stand"}')
    clock.run(0.2)
    return clock


def _idle():
    clock = Clock(PlannerCore(CFG))
    clock.measure(STAND)
    return clock


def _stopping():
    clock = _walking()
    clock.send('{"command": "stop"}')
    return clock


@pytest.mark.parametrize(("setup", "text", "fragment"), [
    (standing, '{"command": "reset"}', "it clears a latched e-stop"),
    (standing, '{"command": "walk", "arc": 0.035}', "walk refused: arc"),
    (standing, "{bad json", "not valid JSON"),
    (standing, '{"command": "walk", "stride": 0.2}', "outside [0, 0.08] m"),
    (_walking, '{"command": "sit"}', "sit refused while WALKING"),
    (_walking, '{"command": "stand"}', "stand refused while WALKING"),
    (_walking, '{"command": "walk", "gait": "wave"}', "gait can only change"),
    (_moving, '{"command": "walk"}', "a stand move is in progress"),
    (_moving, '{"command": "stop"}', "cannot be interrupted"),
    (_moving, '{"command": "sit"}', "a stand move is in progress"),
    (_stopping, '{"command": "walk"}', "stopping; wait for STANDING"),
    (_idle, '{"command": "walk"}', "walk refused in state IDLE: send stand first"),
    (_idle, '{"command": "stop", "steps": 2}', "'stop' does not take"),
])
def test_refusals_keep_the_state(setup, text, fragment):
    clock = setup()
    core = clock.core
    before = (core.state, core.walk_params, core.status()["steps"], core.status()["source"])
    with pytest.raises(CommandError) as info:
        clock.send(text)
    assert fragment in str(info.value)
    assert (core.state, core.walk_params, core.status()["steps"],
            core.status()["source"]) == before
    status = core.status()
    assert fragment in status["last_refusal"] and status["refusals"] == 1
    assert ("warn", f"refused: {info.value}") in core.pop_events()
    assert status["twist_refusals"] == 0


def test_a_refused_twist_is_counted_apart_from_refused_commands():
    clock = _idle()
    core = clock.core
    with pytest.raises(CommandError):
        core.on_twist(0.05, 0.0, 0.0, clock.t)
    with pytest.raises(CommandError):
        clock.send('{"command": "walk"}')
    status = core.status()
    assert (status["refusals"], status["twist_refusals"]) == (2, 1)


# ------------------------------------------------------------------ cmd_vel
def test_cmd_vel_walk_stops_when_twists_stop_arriving():
    clock = standing(cmd_vel_timeout=0.5)
    clock.core.on_twist(0.05, 0.0, 0.1, clock.t)
    assert clock.core.state == WALKING and clock.core.status()["source"] == "cmd_vel"
    p = clock.core.walk_params
    assert p.stride == pytest.approx(0.05 * 0.6) and p.turn == pytest.approx(0.1 * 1.2)
    t0 = clock.t
    for _ in range(40):  # twists at 25 Hz for 1.6 s keep it walking
        clock.run(0.04)
        clock.core.on_twist(0.05, 0.0, 0.1, clock.t)
    assert clock.core.state == WALKING
    t_last = clock.t
    stop_at = clock.until(STOPPING)
    assert stop_at - t_last == pytest.approx(0.5, abs=DT + 1e-9)
    assert "cmd_vel timeout" in clock.core.status()["last_event"]
    clock.until(STANDING)
    assert clock.t - t0 < 1.6 + 0.5 + 2 * SLOT + 0.1


def test_cmd_vel_zero_twist_stops_and_updates_apply_at_slots():
    clock = standing()
    clock.core.on_twist(0.0, 0.0, 0.2, clock.t)  # turn on the spot
    assert clock.core.walk_params.stride == 0.0
    clock.run(0.3)
    clock.core.on_twist(0.1, 0.0, 0.0, clock.t)
    assert clock.core.walk_params.stride == 0.0
    clock.run(0.35)
    assert clock.core.walk_params.stride == pytest.approx(0.06)
    with pytest.raises(CommandError, match="exceeds the maximum"):
        clock.core.on_twist(0.5, 0.0, 0.0, clock.t)
    assert clock.core.state == WALKING
    clock.core.on_twist(0.0, 0.0, 0.0, clock.t)
    assert clock.core.state == STOPPING
    clock.until(STANDING)


def test_finite_walk_ignores_cmd_vel_timeout_and_zero_twists():
    clock = standing(cmd_vel_timeout=0.1)
    clock.send('{"command": "walk", "steps": 2}')
    clock.core.on_twist(0.0, 0.0, 0.0, clock.t)
    with pytest.raises(CommandError, match="cmd_vel ignored in state WALKING"):
        clock.core.on_twist(0.05, 0.0, 0.0, clock.t)
    t0 = clock.t
    t_stop = clock.until(STOPPING)
    assert t_stop - t0 == pytest.approx(5 * SLOT, abs=DT)  # start + 2 x 2 steady slots
    assert clock.core.status()["step"] == 2


def test_cmd_vel_refused_from_idle_and_while_paused():
    core = PlannerCore(CFG)
    core.on_twist(0.0, 0.0, 0.0, 0.0)  # zero: nothing to do
    with pytest.raises(CommandError, match="cmd_vel ignored in state IDLE: send stand first"):
        core.on_twist(0.05, 0.0, 0.0, 0.0)
    with pytest.raises(CommandError, match="finite"):
        core.on_twist(math.nan, 0.0, 0.0, 0.0)
    clock = standing()
    clock.core.set_paused(True, clock.t, "axis 3 overcurrent")
    with pytest.raises(CommandError, match="paused: motor manager fault"):
        clock.core.on_twist(0.05, 0.0, 0.0, clock.t)
    with pytest.raises(CommandError, match="axis 3 overcurrent"):
        clock.send('{"command": "walk"}')
    assert clock.core.state == STANDING


# ------------------------------------------------------------------ pause
def test_pause_holds_before_a_new_slot_and_resumes_smoothly():
    clock = standing()
    clock.send('{"command": "walk"}')
    t0 = clock.t
    clock.run(0.25)
    clock.core.set_paused(True, clock.t, "axis 7 fault")
    assert clock.core.status()["paused"] and clock.core.status()["pause_reason"]
    clock.run(0.5)  # the slot ends at 0.6 and is not followed by another
    q = positions(clock)
    held = q[-1]
    boundary = next(i for i, (t, _) in enumerate(clock.targets) if t - t0 >= SLOT - 1e-9)
    assert np.all(q[boundary:] == held)  # held from the slot end on
    assert np.abs(q[boundary - 1] - held).max() < 0.01  # the slot ran to its end
    assert clock.core.state == WALKING
    clock.run(1.0)
    assert np.all(positions(clock)[-100:] == held)
    clock.core.set_paused(False, clock.t)
    sagged = held + 0.05  # the joints drifted while paused
    clock.core.set_measured(sagged, clock.t)
    n = len(positions(clock))
    clock.run(0.02)
    q = positions(clock)[n:]
    step = ROBOT.velocity.max() * DT
    assert np.abs(q[0] - sagged).max() <= step  # resumes from the measured pose
    clock.run(1.2)  # the resume move (>= 1 s) ends at the held pose, then the walk goes on
    q = positions(clock)[n:]
    assert np.abs(np.diff(q, axis=0)).max() <= step
    assert any(np.abs(row - held).max() < 1e-9 for row in q) and not np.all(q[-1] == held)
    clock.send('{"command": "stop"}')
    clock.until(STANDING)


def test_pause_during_stop_waits_then_finishes():
    clock = standing()
    clock.send('{"command": "walk"}')
    clock.run(0.7)
    clock.send('{"command": "stop"}')
    clock.core.set_paused(True, clock.t)
    clock.run(2.0)
    assert clock.core.state == STOPPING
    clock.core.set_paused(False, clock.t)
    clock.measure()
    t = clock.t
    # the resume move from the measured pose (the minimum 1 s: nothing drifted), then a slot
    assert clock.until(STANDING) - t == pytest.approx(moves.MIN_MOVE_TIME + SLOT, abs=3 * DT)


# ------------------------------------------------------------------ output properties
@settings(max_examples=10, deadline=None)
@given(st.sampled_from(["diagonal", "wave"]), st.sampled_from(["rest", "smooth"]),
       st.floats(0.0, 0.08), st.floats(-math.pi, math.pi), st.floats(-0.35, 0.35),
       st.floats(0.2, 0.8))
def test_ticks_never_nan_or_outside_limits(gait, profile, stride, heading, turn, swing):
    clock = standing()
    text = (f'{{"command": "walk", "steps": 1, "gait": "{gait}", "profile": "{profile}", '
            f'"stride": {stride}, "heading": {heading}, "turn": {turn}, '
            f'"swing_time": {swing}}}')
    try:
        clock.send(text)
    except CommandError as exc:
        assert "refused as a whole" in str(exc)
        assert clock.core.state == STANDING
        return
    clock.until(STANDING, limit=60)
    q = positions(clock)
    v = np.array([tg.velocities for _, tg in clock.targets if tg is not None])
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(v))
    assert np.all((q >= LO) & (q <= HI))


def test_track_evaluation_matches_the_piecewise_trajectories():
    seq = GaitSequencer(CFG, WalkParams.defaults(CFG.gait, gait="wave", turn=0.2,
                                                 stance_time=3.0))
    for _ in range(5):
        slot = seq.next_slot()
        track = Track(slot.legs)
        for tau in np.linspace(-0.1, slot.duration + 0.1, 37):
            pos, vel = track.evaluate(float(tau))
            ref = [leg.evaluate(min(max(tau, 0.0), slot.duration)) for leg in slot.legs]
            np.testing.assert_allclose(pos, np.concatenate([r[0][0] for r in ref]),
                                       atol=1e-12)
            np.testing.assert_allclose(vel, np.concatenate([r[1][0] for r in ref]),
                                       atol=1e-10)


def test_status_fields_and_revision():
    core = PlannerCore(CFG)
    s = core.status()
    assert {"state", "gait", "profile", "step", "steps", "paused", "last_refusal",
            "stamp"} <= s.keys()
    assert (s["state"], s["gait"], s["profile"], s["paused"]) == (IDLE, CFG.gait.gait,
                                                                  "smooth", False)
    rev = core.revision
    core.tick(0.5)
    assert core.revision == rev  # a tick that changes nothing changes no status
    core.set_paused(True, 0.6, "x")
    assert core.revision == rev + 1 and core.status()["stamp"] == 0.6


def test_an_infeasible_twist_held_still_is_checked_once(monkeypatch):
    monkeypatch.setattr(next_slot, "SLOWED_SHARES", ())  # and none slower passes
    clock = standing()
    calls = []

    def counting(*args):
        calls.append(args)
        return plan_walk(*args)

    monkeypatch.setattr(upfront, "plan_walk", counting)
    for _ in range(5):
        with pytest.raises(CommandError, match="walk refused as a whole"):
            clock.core.on_twist(0.0, 0.133, 0.0, clock.t)
        clock.tick()
    assert len(calls) == 1 and clock.core.state == STANDING
    assert clock.core.status()["refusals"] == 5


def test_a_twist_whose_walk_is_refused_as_a_whole_starts_slowed_and_says_so():
    """The twist above with `next_slot.SLOWED_SHARES`: the walk starts at the first share of
    its stride and turn that passes the up-front check, stated; the twist held still asks for
    its own stride at every slot (and gets the share that passes)."""
    clock = standing(cmd_vel_timeout=5.0)
    asked = 0.133 * float(clock.core.defaults.stance_time)
    assert clock.core.requests.upfront(
        twist_to_params(0.0, 0.133, 0.0, CFG, clock.core.defaults), 1) is not None
    clock.core.on_twist(0.0, 0.133, 0.0, clock.t)
    status = clock.core.status()
    assert clock.core.state == WALKING and status["refusals"] == 0
    assert status["slowed_share"] in next_slot.SLOWED_SHARES and status["slowed_slots"] == 1
    assert status["last_event"].startswith("slot slowed to") and "reachable" in (
        status["last_event"])
    assert clock.core.walk_params.stride == pytest.approx(asked * status["slowed_share"])
    for _ in range(20):  # 2 s of the twist at 10 Hz
        clock.core.on_twist(0.0, 0.133, 0.0, clock.t)
        clock.run(0.1)
    status = clock.core.status()
    assert clock.core.state == WALKING and status["slowed_slots"] > 1, status


def test_a_twist_sent_once_is_asked_for_again_at_every_slot_never_a_slowed_one():
    """One twist, no more (a teleop that publishes on change): every slot asks for the
    twist's own stride and is slowed from it, never from the last slowed stride (0.6 x 0.6
    ...), and the status says so at every slot; a stop ends it (share 1 again)."""
    clock = standing(cmd_vel_timeout=5.0)
    asked = 0.133 * float(clock.core.defaults.stance_time)
    clock.core.on_twist(0.0, 0.133, 0.0, clock.t)
    seen = set()
    for _ in range(40):  # 4 s
        clock.run(0.1)
        status = clock.core.status()
        stride = clock.core.walk_params.stride
        seen.add(round(stride / asked, 6))
        assert stride == pytest.approx(asked * status["slowed_share"]), status
    assert seen <= {round(x, 6) for x in (1.0, *next_slot.SLOWED_SHARES)}, seen
    assert min(seen) < 1.0 and clock.core.status()["slowed_slots"] > 3
    clock.core.on_twist(0.0, 0.0, 0.0, clock.t)
    clock.until(STANDING)
    assert clock.core.status()["slowed_share"] == 1.0


# ------------------------------------------------------------------ planning ahead
AHEAD_SCRIPTS = [  # (time after the walk starts [s], command); then run to STANDING
    ("steps", [(0.0, '{"command": "walk", "steps": 2}')]),
    ("change-mid-slot", [(0.0, '{"command": "walk"}'),
                         (0.95, '{"command": "walk", "stride": 0.03, "turn": 0.2}'),
                         (2.05, '{"command": "stop"}')]),
    ("stop-just-before-a-boundary", [(0.0, '{"command": "walk"}'), (1.19, '{"command": "stop"}')]),
    ("new-budget", [(0.0, '{"command": "walk", "steps": 3}'),
                    (0.65, '{"command": "walk", "steps": 1, "profile": "rest"}')]),
]


def _run_script(script: list[tuple[float, str]], ahead: bool) -> tuple[Clock, int]:
    clock = standing()
    t0 = clock.t
    todo = list(script)
    planned = 0
    while True:
        while todo and clock.t - t0 >= todo[0][0] - 1e-9:
            clock.send(todo.pop(0)[1])
        clock.tick()
        if ahead:
            planned += clock.core.plan_ahead(clock.t)  # as the node: the next tick's time
        if clock.core.state == STANDING and not todo:
            return clock, planned
        assert clock.t - t0 < 30.0


def assert_same_targets(plain: Clock, early: Clock) -> None:
    """The same ticks and targets, but for the joint tables' interpolation of slots planned
    ahead: within 1e-7 rad and 1e-5 rad/s (the contract of `motion.jointtable`), and some of
    them served by a table (not bit for bit)."""
    assert len(plain.targets) == len(early.targets)
    tabulated = 0
    for (ta, a), (tb, b) in zip(plain.targets, early.targets, strict=True):
        assert ta == tb
        np.testing.assert_allclose(a.positions, b.positions, rtol=0, atol=1e-7)
        np.testing.assert_allclose(a.velocities, b.velocities, rtol=0, atol=1e-5)
        tabulated += not np.array_equal(a.positions, b.positions)
    assert tabulated > 0


@pytest.mark.parametrize("script", [s for _, s in AHEAD_SCRIPTS],
                         ids=[name for name, _ in AHEAD_SCRIPTS])
def test_planning_ahead_changes_no_target(script, monkeypatch):
    """Planned between ticks or at the boundary: the same targets (a slot planned ahead is
    served by its joint table, within its tolerances), and with `plan_ahead` after every tick
    no tick ever plans a slot itself."""
    plain, _ = _run_script(script, ahead=False)
    in_tick = []
    real_try_slot = WalkController._try_slot
    planning_ahead = [False]

    def counting(self, params, stopping):
        if not planning_ahead[0]:
            in_tick.append(self.slot_t0)
        return real_try_slot(self, params, stopping)

    real_plan_ahead = PlannerCore.plan_ahead

    def marked(self, now=None):
        planning_ahead[0] = True
        try:
            return real_plan_ahead(self, now)
        finally:
            planning_ahead[0] = False

    monkeypatch.setattr(WalkController, "_try_slot", counting)
    monkeypatch.setattr(PlannerCore, "plan_ahead", marked)
    early, planned = _run_script(script, ahead=True)
    assert_same_targets(plain, early)
    assert [s for _, s in plain.states] == [s for _, s in early.states]
    assert planned >= 3
    assert in_tick == []  # every slot was planned ahead (changes were replanned ahead too)


def test_plan_ahead_does_nothing_when_there_is_nothing_to_plan():
    clock = standing()
    assert clock.core.plan_ahead() is False  # standing
    clock.send('{"command": "walk", "steps": 1}')
    clock.tick()
    assert clock.core.plan_ahead() is True
    assert clock.core.plan_ahead() is False  # already planned, inputs unchanged
    clock.send('{"command": "stop"}')
    assert clock.core.plan_ahead() is True  # the stop changed the next slot


def test_plan_ahead_waits_for_the_horizon_before_the_boundary():
    clock = standing()
    clock.send('{"command": "walk"}')
    t0 = clock.t
    clock.tick()
    horizon = PLAN_AHEAD_HORIZON
    assert SLOT > horizon + 2 * DT
    assert clock.core.plan_ahead(t0 + SLOT - horizon - DT) is False  # too early
    assert clock.core.plan_ahead(t0 + SLOT - horizon + DT) is True


def test_a_plan_made_outside_the_lock_is_not_used_once_its_inputs_changed():
    """ahead_job -> (a stop arrives) -> run -> store_ahead: the stored plan no longer matches,
    so the boundary tick plans the stop itself; the walk is exactly the plain one."""
    plain, early = standing(), standing()
    for clock in (plain, early):
        clock.send('{"command": "walk"}')
        clock.run(0.5)  # inside the first slot, within PLAN_AHEAD_HORIZON of its end
    job = early.core.ahead_job(early.t)
    assert job is not None and early.core.ahead_job(early.t) is not None  # nothing stored yet
    for clock in (plain, early):
        clock.send('{"command": "stop"}')
    ahead = job.run()  # planned for "keep walking"
    assert early.core.store_ahead(ahead) is True
    assert early.core.ahead_job(early.t) is not None  # the stop needs a new plan
    plain.until(STANDING)
    early.until(STANDING)
    assert [s for _, s in plain.states] == [s for _, s in early.states]
    np.testing.assert_array_equal(positions(plain), positions(early))


def test_a_plan_for_a_finished_slot_is_dropped():
    clock = standing()
    clock.send('{"command": "walk"}')
    clock.run(0.5)
    job = clock.core.ahead_job(clock.t)
    assert job is not None
    clock.run(0.2)  # past the boundary: the tick planned and started the next slot
    assert clock.core.store_ahead(job.run()) is False


@pytest.mark.parametrize("twist", [None, (0.08, 0.0, 0.0), (0.0, 0.06, 0.1)])
def test_the_default_gait_walks_through_the_core_as_planned(twist):
    # A core with the shipped defaults walks the default gait (planned from the ZMP): its
    # targets are the IK of the same plan, without a jump, and it ends STANDING.
    clock = standing(defaults=WalkParams.defaults(CFG.gait))
    assert clock.core.status()["gait"] == "diagonal_zmp"
    t0 = clock.t
    if twist is None:
        clock.send('{"command": "walk", "steps": 2}')
        plan = plan_walk(CFG, WalkParams.defaults(CFG.gait), 2)
        clock.until(STANDING)
        times = np.array([t for t, _ in clock.targets if t - t0 < plan.duration - 1e-9])
        got = np.array([tg.positions for t, tg in clock.targets
                        if t - t0 < plan.duration - 1e-9])
        np.testing.assert_allclose(got, plan.joints(times - t0)[0].reshape(len(times), 12),
                                   atol=1e-8)
    else:
        for _ in range(150):
            clock.core.on_twist(*twist, clock.t)
            clock.tick()
        clock.until(STANDING)  # the twists stop: the walk stops into standing
    q = positions(clock)
    assert np.abs(np.diff(q, axis=0)).max() < 0.05  # no jump
    np.testing.assert_allclose(q[-1], STAND.reshape(-1), atol=1e-9)


def test_a_new_walks_upfront_check_can_run_before_the_command(monkeypatch):
    # the node runs the job without its lock, then submits: the submit finds it cached
    clock = standing(defaults=WalkParams.defaults(CFG.gait))
    core = clock.core
    assert core.upfront_job(text='{"command": "stand"}') is None
    assert core.upfront_job(text="not json") is None
    assert core.upfront_job(twist=(0.0, 0.0, 0.0)) is None  # a zero twist starts nothing
    job = core.upfront_job(text='{"command": "walk", "steps": 2, "heading": 0.5}')
    assert job is not None
    job()
    calls = []
    monkeypatch.setattr(upfront, "plan_walk", lambda *a: calls.append(a))
    clock.send('{"command": "walk", "steps": 2, "heading": 0.5}')
    assert core.state == WALKING and calls == []  # the verdict came from the cache
    clock.until(STANDING)
    job = core.upfront_job(twist=(0.05, 0.0, 0.0))
    assert job is not None
    job()  # (the stub stands in for plan_walk here: one call, by the job)
    assert len(calls) == 1
    core.on_twist(0.05, 0.0, 0.0, clock.t)
    assert core.state == WALKING and len(calls) == 1


def test_a_twist_refused_as_beyond_the_limits_is_named_in_the_status():
    clock = standing()
    with pytest.raises(CommandError):
        clock.core.on_twist(1e6, 0.0, 0.0, clock.t)
    status = clock.core.status()
    assert status["refused_twist"] == [1e6, 0.0, 0.0] and "cmd_vel speed" in status[
        "last_refusal"]
    with pytest.raises(CommandError):
        clock.send('{"command": "reset"}')  # another refusal: no twist named
    assert clock.core.status()["refused_twist"] is None


@pytest.mark.parametrize("setup", [_idle, _stopping])
def test_a_twist_the_robot_must_stand_for_says_so(setup):
    """The text the navigator's watch reads: a twist refused until stand is sent, or not."""
    clock = setup()
    with pytest.raises(CommandError) as info:
        clock.core.on_twist(0.05, 0.0, 0.0, clock.t)
    assert needs_stand(str(info.value)) is (setup is _idle), str(info.value)


@pytest.mark.parametrize("resuming, needs", [(False, True), (True, False)])
def test_a_twist_while_holding_needs_stand_unless_a_resume_is_due(resuming, needs):
    """HOLDING says 'send stand first' only when no resume from the measured pose is due
    (an interruption resumes by itself; a walk that could not stop waits for stand)."""
    clock = standing()
    clock.core.ctx.state = HOLDING
    with pytest.raises(CommandError) as info:
        clock.core.requests.twist(0.05, 0.0, 0.0, clock.core._base(), clock.t, resuming)
    assert needs_stand(str(info.value)) is needs, str(info.value)


@pytest.mark.parametrize("how", ["command", "twist"])
def test_a_first_slot_planned_up_front_changes_no_target(how, monkeypatch):
    """The node runs a walk's up-front job without its lock; the job plans the first slot
    (and its joint table), and the start under the lock only commits it: the same targets."""

    def walk(up_front: bool) -> tuple[Clock, list[float]]:
        clock = standing()
        text = '{"command": "walk", "steps": 2}'
        job = (clock.core.upfront_job(text=text) if how == "command"
               else clock.core.upfront_job(twist=(0.05, 0.0, 0.0)))
        assert job is not None
        if up_front:
            job()
        planned: list[float] = []
        real = WalkController.start

        def counting(self, params, steps, source, now, first=None):
            if first is None:
                planned.append(now)
            return real(self, params, steps, source, now, first)

        monkeypatch.setattr(WalkController, "start", counting)
        if how == "command":
            clock.send(text)
        else:
            clock.core.on_twist(0.05, 0.0, 0.0, clock.t)
        monkeypatch.undo()
        clock.run(2.0)
        return clock, planned

    (plain, planned_plain), (early, planned_early) = walk(False), walk(True)
    assert planned_plain and not planned_early
    assert_same_targets(plain, early)
