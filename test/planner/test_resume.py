"""Resume from the measured pose, and the driver's state ending a walk (pure core)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.motion.gait import standing_pose
from crawler_motion.planner.core import PlannerCore
from crawler_motion.planner.driver_view import (
    ENDING_STATES,
    DriverChange,
    DriverReport,
    DriverView,
    parse_driver_status,
    rate_problem,
)
from crawler_motion.planner.resume import FREEZE_GAP
from crawler_motion.planner.state import IDLE, MOVING, STANDING, WALKING

CFG = load_config()
DT = 0.01
STEP = float(CFG.robot.velocity.max()) * DT  # one velocity-limited step [rad]
STAND = standing_pose(CFG).reshape(-1)


def report(state: str, epoch: int) -> DriverReport:
    return DriverReport(state, epoch)


class Run:
    """A core at 100 Hz fed back its own targets as measurements (a perfect robot)."""

    def __init__(self) -> None:
        self.core = PlannerCore(CFG, 100.0)
        self.t = 0.0
        self.q = STAND.copy()
        self.out: list[np.ndarray | None] = []
        self.core.on_driver(report("enabled", 1), 0.0)

    def tick(self, follow: bool = True) -> np.ndarray | None:
        self.core.set_measured(self.q, self.t)
        target = self.core.tick(self.t)
        pos = None if target is None else np.array(target.positions)
        if pos is not None and follow:
            self.q = pos
        self.out.append(pos)
        self.t = round(self.t + DT, 9)
        return pos

    def run(self, seconds: float, follow: bool = True) -> None:
        for _ in range(round(seconds / DT)):
            self.tick(follow)

    def walking(self) -> None:
        self.tick()
        self.core.submit('{"command": "stand"}', self.t)
        while self.core.state != STANDING:
            self.tick()
        self.core.submit('{"command": "walk", "swing_time": 0.4}', self.t)
        self.run(0.5)
        assert self.core.state == WALKING


@pytest.mark.parametrize("state", sorted(ENDING_STATES))
def test_a_driver_that_stops_following_ends_the_walk(state):
    run = Run()
    run.walking()
    run.core.on_driver(report(state, 1), run.t)
    assert run.core.state == IDLE and "ended" in run.core.status()["last_event"]
    run.run(0.3)
    assert run.out[-30:] == [None] * 30  # nothing is published
    with pytest.raises(CommandError, match="console recover"):
        run.core.submit('{"command": "stand"}', run.t)
    run.core.on_driver(report("enabled", 2), run.t)  # reset + enable: still nothing moves
    run.run(1.0)
    assert run.core.state == IDLE and run.out[-100:] == [None] * 100
    run.core.submit('{"command": "stand"}', run.t)
    assert run.core.state == MOVING


def test_a_re_enable_mid_walk_resumes_from_the_measured_pose():
    run = Run()
    run.walking()
    run.run(0.3, follow=False)  # the manager held: the joints did not follow
    sagged = run.q + 0.03
    run.q = sagged
    run.core.on_driver(report("enabled", 2), run.t - DT / 2)  # between two ticks
    first = run.tick()
    assert first is not None and np.abs(first - sagged).max() <= STEP
    run.run(3.0)
    q = np.array([p for p in run.out[-300:] if p is not None])
    assert np.abs(np.diff(q, axis=0)).max() <= STEP and run.core.state == WALKING
    assert run.core.status()["resuming"] is False


@pytest.mark.parametrize("gap", [FREEZE_GAP + DT, 0.5, 1.0, 5.0])
def test_a_frozen_planner_resumes_from_the_measured_pose(gap):
    run = Run()
    run.walking()
    run.t += gap  # the process was stopped
    first = run.tick()
    assert first is not None and np.abs(first - run.out[-2]).max() <= STEP
    run.run(2.0)
    q = np.array([p for p in run.out[-200:] if p is not None])
    assert np.abs(np.diff(q, axis=0)).max() <= STEP


def test_a_short_late_tick_does_not_interrupt():
    run = Run()
    run.walking()
    run.t += FREEZE_GAP - 2 * DT
    run.tick()
    assert not run.core.status()["resuming"] and run.core.status()["interruptions"] == 0


def test_the_status_counts_interruptions_once_each():
    run = Run()
    run.walking()
    for n in (1, 2):
        run.t += FREEZE_GAP + DT
        run.tick()
        assert run.core.status()["interruptions"] == n
        run.core.set_paused(True, run.t, "heartbeat missing")  # while the resume runs: a walk
        run.core.set_paused(False, run.t)  # runs on to its slot end, no new interruption
        assert run.core.status()["interruptions"] == n
        run.run(2.0)
        assert not run.core.status()["resuming"]


def test_a_measurement_from_before_the_interruption_is_not_resumed_from():
    run = Run()
    run.walking()
    run.core.set_measured(run.q, run.t)
    run.core.on_driver(report("enabled", 2), run.t)
    assert run.core.tick(run.t) is None  # the measurement is not newer than the re-enable
    run.core.set_measured(run.q, run.t + DT)
    assert run.core.tick(run.t + DT) is not None


def test_no_fresh_measurement_publishes_nothing_until_one_comes():
    run = Run()
    run.walking()
    run.core.on_driver(report("enabled", 2), run.t)
    t = run.t + 2.0  # measurement 2 s old
    assert run.core.tick(t) is None
    run.core.set_measured(run.q, t)
    target = run.core.tick(t + DT)
    assert target is not None and np.abs(target.positions - run.q).max() <= STEP


def test_a_pause_while_standing_resumes_with_a_move_from_the_measured_pose():
    run = Run()
    run.walking()
    run.core.submit('{"command": "stop"}', run.t)
    while run.core.state != STANDING:
        run.tick()
    run.core.set_paused(True, run.t, "heartbeat missing")
    run.run(0.2, follow=False)
    run.q = run.q - 0.04
    run.core.set_paused(False, run.t)
    first = run.tick()
    assert run.core.state == MOVING and np.abs(first - (run.q)).max() <= STEP
    run.run(1.5)
    assert run.core.state == STANDING


@pytest.mark.parametrize("text, match", [
    ("nope", "not JSON"),
    ("[1]", "JSON object"),
    ('{"state": "flying", "enable_epoch": 0}', "state 'flying'"),
    ('{"state": "enabled"}', "enable_epoch"),
    ('{"state": "enabled", "enable_epoch": -1}', "enable_epoch"),
    ('{"state": "enabled", "enable_epoch": true}', "enable_epoch"),
    ('{"state": "enabled", "enable_epoch": 0, "command_timeout": 0}', "command_timeout"),
])
def test_bad_driver_status_is_a_clear_error(text, match):
    with pytest.raises(CommandError, match=match):
        parse_driver_status(text)


def test_driver_view_changes():
    view = DriverView()
    ok = parse_driver_status(json.dumps({"state": "enabled", "enable_epoch": 0, "reason": ""}))
    assert view.update(ok) is DriverChange.NONE and not view.ending
    assert view.update(report("enabled", 0)) is DriverChange.NONE
    assert view.update(report("estop", 0)) is DriverChange.ENDED and view.ending
    assert view.update(report("disabled", 0)) is DriverChange.NONE  # a fault reset: paused
    assert view.update(report("enabled", 1)) is DriverChange.REENABLED
    assert view.update(report("enabled", 1)) is DriverChange.NONE


def test_a_restarted_driver_ends_the_walk():
    run = Run()
    run.core.on_driver(DriverReport("enabled", 1, instance="a"), 0.0)
    run.walking()
    run.core.on_driver(DriverReport("enabled", 1, instance="b"), run.t)  # same epoch, new process
    assert run.core.state == IDLE and "the driver restarted" in run.core.status()["last_event"]


@pytest.mark.parametrize("rate, timeout, refused", [
    (100.0, 0.2, False),
    (10.0, 0.2, False),  # boundary: two periods = the timeout
    (9.9, 0.2, True),
    (1.0, 1.0, True),
    (1.0, None, False),  # the driver's timeout unknown
])
def test_rate_against_the_driver_command_timeout(rate, timeout, refused):
    text = json.dumps({"state": "enabled", "enable_epoch": 0,
                       **({} if timeout is None else {"command_timeout": timeout})})
    problem = rate_problem(rate, parse_driver_status(text))
    assert bool(problem) == refused and (not refused or "watchdog would trip" in problem)


def test_a_stand_sent_before_the_first_tick_is_not_an_interruption():
    core = PlannerCore(CFG, 100.0)
    core.on_driver(report("enabled", 1), 0.0)
    core.set_measured(STAND, 0.0)
    core.submit('{"command": "stand"}', 0.0)
    assert core.tick(0.0) is not None
    status = core.status()
    assert status["interruptions"] == 0 and not status["resuming"], status["last_event"]


def test_a_measurement_made_while_the_planner_was_stopped_is_not_resumed_from():
    """After a tick gap the resume waits for a state measured in the last period or later:
    states that waited in the queue while the process was stopped (the joints still settling
    on the last target) are not resumed from."""
    run = Run()
    run.walking()
    last = run.t - DT
    run.t += 0.6  # the process was stopped for 0.6 s
    run.core.set_measured(run.q, last + 0.05)  # measured early in the stop, taken now
    assert run.core.tick(run.t) is None
    run.core.set_measured(run.q, run.t - 0.5 * DT)  # measured just before the continuation
    assert run.core.tick(run.t + DT) is not None
