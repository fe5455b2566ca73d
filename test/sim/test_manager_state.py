"""Tests of the simulated manager without a bus: its state machine and model, as tables."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.sim.manager_model import ManagerModel
from crawler_motion.sim.manager_state import (
    FaultKind,
    ManagerState,
    ManagerStateMachine,
)

D, E, H, S, F = (ManagerState.DISABLED, ManagerState.ENABLED, ManagerState.HOLD,
                 ManagerState.ESTOP, ManagerState.FAULT)


def machine_in(state: ManagerState, fault: bool = False) -> ManagerStateMachine:
    m = ManagerStateMachine(3)
    m.state = state
    if fault:
        m.faults[1].add(FaultKind.OVER_TEMP)
        m.latched[1].add(FaultKind.OVER_TEMP)
    return m


def test_values_are_the_wire_names():
    assert [s.value for s in ManagerState] == ["disabled", "enabled", "hold", "estop", "fault"]
    assert [k.value for k in FaultKind] == ["over_current", "over_temp", "encoder_fault"]
    assert f"{ManagerState.HOLD}" == "hold" and ManagerState.HOLD == "hold"


@pytest.mark.parametrize(("start", "command", "fault", "end", "entered"), [
    (D, "enable", False, E, True),
    (E, "enable", False, E, True),  # re-entered: the axes hold where they are
    (E, "hold", False, H, True),
    (H, "disable", False, D, True),
    (E, "estop", False, S, True),
    (S, "enable", False, S, False),  # latched: ignored
    (F, "hold", True, F, False),
    (S, "reset", False, D, True),
    (S, "reset", True, F, True),  # a condition still present
    (F, "reset", True, F, True),
    (F, "reset", False, D, True),
    (E, "reset", False, E, False),  # nothing latched: the state stays
])
def test_command_table(start, command, fault, end, entered):
    m = machine_in(start, fault)
    m.timed_out = True
    assert m.command(command) is entered
    assert m.state is end
    assert m.timed_out is not entered


def test_reset_clears_only_latched_bits_whose_condition_is_gone():
    m = machine_in(F, fault=True)
    m.latched[0].add(FaultKind.OVER_CURRENT)  # condition gone (not in faults)
    m.command("reset")
    assert m.latched[0] == set() and m.latched[1] == {FaultKind.OVER_TEMP}


def test_unsupported_command():
    with pytest.raises(ValueError, match="unsupported command 'dance'"):
        machine_in(D).command("dance")
    assert machine_in(S).command("dance") is False  # latched: ignored before the check


@pytest.mark.parametrize(("start", "end"), [(D, F), (E, F), (H, F), (F, F), (S, S)])
def test_fault_injection(start, end):
    m = machine_in(start)
    m.timed_out = True
    assert m.inject_fault(2, "encoder_fault") is True
    assert m.state is end and not m.timed_out
    assert m.faults[2] == m.latched[2] == {FaultKind.ENCODER_FAULT}
    m.clear()
    assert m.faults[2] == set() and m.latched[2] == {FaultKind.ENCODER_FAULT}


@pytest.mark.parametrize("axis", [-1, 3, 1.0, True, "0"])
def test_axis_validation(axis):
    with pytest.raises(ValueError, match=r"axis must be an integer 0\.\.2"):
        machine_in(D).stall(axis, True)


def test_fault_kind_validation():
    with pytest.raises(ValueError, match=r"fault kind must be one of \['over_current', "):
        machine_in(D).inject_fault(0, "flood")


@pytest.mark.parametrize(("state", "since", "starts"), [
    (E, 0.2, False),  # exactly the timeout: not yet
    (E, 0.2001, True),
    (H, 1.0, False),
    (D, 1.0, False),
])
def test_command_timeout(state, since, starts):
    m = machine_in(state)
    assert m.check_timeout(since, 0.2) is starts
    assert m.timed_out is starts
    assert m.check_timeout(since, 0.2) is False  # starts once


def test_flags():
    m = machine_in(E, fault=True)
    m.state = E
    m.stall(0, True)
    flags = m.flags()
    assert [f.enabled for f in flags] == [True] * 3
    assert [f.tracking for f in flags] == [False, True, True]
    assert [f.stalled for f in flags] == [True, False, False]
    assert [f.over_temp for f in flags] == [False, True, False]
    assert not any(f.command_timeout for f in flags)
    m.check_timeout(1.0, 0.2)
    assert all(f.command_timeout and not f.tracking for f in m.flags())
    m.command("disable")
    assert not any(f.enabled or f.tracking for f in m.flags())
    m.stall(0, False)
    assert not any(f.stalled for f in m.flags())


def model(speed: float = 1.0, timeout: float = 0.2) -> ManagerModel:
    return ManagerModel(np.zeros(3), np.full(3, speed), timeout)


@pytest.mark.parametrize(("target", "dt", "expected"), [
    (0.05, 0.1, 0.05),  # reached within the step: no overshoot
    (0.5, 0.1, 0.1),  # limited by the speed
    (-0.5, 0.1, -0.1),
    (0.5, 0.0, 0.0),
])
def test_model_moves_at_the_speed_limit(target, dt, expected):
    m = model()
    m.command("enable")
    assert m.apply_targets({0: target}) is True
    m.advance(dt)
    assert m.pos[0] == pytest.approx(expected) and m.time == pytest.approx(dt)


def test_model_ignores_targets_unless_enabled_and_holds_on_timeout():
    m = model()
    assert m.apply_targets({0: 1.0}) is False and m.target[0] == 0.0
    m.command("enable")
    m.apply_targets({0: 1.0})
    m.machine.stall(1, True)
    m.apply_targets({1: 1.0})
    m.advance(0.2)  # exactly the timeout: still moving
    assert m.pos[0] == pytest.approx(0.2) and m.pos[1] == 0.0 and not m.machine.timed_out
    m.advance(0.1)  # expired at t = 0.3 s: holds where it is, does not move this step
    assert m.machine.timed_out and m.pos[0] == pytest.approx(0.2)
    assert m.target[0] == pytest.approx(0.2)
    m.apply_targets({0: 1.0})  # a fresh target resumes
    m.advance(0.1)
    assert not m.machine.timed_out and m.pos[0] == pytest.approx(0.3)


def test_model_fault_holds_and_dt_is_checked():
    m = model()
    m.command("enable")
    m.apply_targets({2: 1.0})
    m.advance(0.1)
    m.inject_fault(2, "over_current")
    assert m.state is F and m.target[2] == pytest.approx(m.pos[2])
    with pytest.raises(ValueError, match="dt must be a finite time"):
        m.advance(-0.1)
    with pytest.raises(ValueError, match="unsupported command"):
        model().command("dance")
