"""Tests of crawler_motion.driver.gate: the motion gate's states and transitions."""

from __future__ import annotations

import pytest

from crawler_motion.driver.gate import MAX_ENABLE_RESENDS, GateState, MotionGate

S = GateState


def _gate(*steps: str) -> MotionGate:
    """A gate after ``steps``: enable, estop, reset, trip_hold, trip_disable, close, ..."""
    gate = MotionGate()
    for step in steps:
        if step == "enable":
            gate.enable()
        elif step == "estop":
            gate.estop("test")
        elif step == "reset":
            gate.reset()
        elif step == "close":
            gate.close()
        elif step == "deactivate":
            gate.deactivate("hold")
        elif step.startswith("trip_"):
            gate.accept(0.0)
            assert gate.watch(1.0, 0.5, step.removeprefix("trip_"))
    return gate


@pytest.mark.parametrize(("steps", "state", "active", "enabled", "tripped", "latched"), [
    ((), S.INACTIVE, False, False, False, False),
    (("enable",), S.ENABLED, True, True, False, False),
    (("enable", "trip_hold"), S.HOLDING, True, True, True, False),
    (("enable", "trip_disable"), S.TRIPPED, True, False, True, False),
    (("enable", "trip_hold", "enable"), S.ENABLED, True, True, False, False),
    (("enable", "estop"), S.ESTOP, True, False, False, True),
    (("enable", "trip_hold", "estop"), S.ESTOP, True, False, True, True),
    (("enable", "estop", "reset"), S.DISABLED, True, False, False, False),
    (("enable", "trip_hold", "estop", "reset"), S.DISABLED, True, False, False, False),
    (("estop",), S.ESTOP, False, False, False, True),
    (("estop", "reset"), S.INACTIVE, False, False, False, False),
    (("enable", "estop", "close"), S.ESTOP, False, False, False, True),
    (("enable", "close"), S.INACTIVE, False, False, False, False),
    (("enable", "deactivate"), S.INACTIVE, False, False, False, False),
])
def test_states(steps, state, active, enabled, tripped, latched):
    gate = _gate(*steps)
    assert gate.state is state
    assert (gate.active, gate.enabled, gate.tripped, gate.latched) == (
        active, enabled, tripped, latched)
    assert gate.motion_allowed == (state is S.ENABLED)


def test_watchdog_arms_with_the_first_command_and_trips_after_the_timeout():
    gate = _gate("enable")
    assert not gate.watch(100.0, 0.2, "hold")  # unarmed: never trips
    gate.accept(10.0)
    assert not gate.watch(10.2, 0.2, "hold")  # exactly the timeout: not yet
    assert gate.watch(10.2 + 1e-9, 0.2, "hold") and gate.state is S.HOLDING
    assert not gate.watch(20.0, 0.2, "hold")  # trips once


@pytest.mark.parametrize(("steps", "on_deactivate", "sent"), [
    (("enable",), "hold", "hold"),
    (("enable",), "disable", "disable"),
    ((), "hold", "disable"),  # hold would power unpowered axes
    (("enable", "trip_disable"), "hold", "disable"),
])
def test_deactivate_command(steps, on_deactivate, sent):
    assert _gate(*steps).deactivate(on_deactivate) == sent


def test_estop_keeps_the_first_reason_and_blocks():
    gate = _gate("enable")
    assert gate.estop("first") and not gate.estop("second")
    assert gate.estop_reason == "first" and "~/reset" in gate.blocked_reason()
    assert "watchdog" in _gate("enable", "trip_hold").blocked_reason()
    assert "not enabled" in _gate("enable", "estop", "reset").blocked_reason()


def test_heartbeat_reactions():
    gate = _gate("enable")
    gate.sent("enable", 0.0)
    assert gate.on_heartbeat("disabled", 0.1, 0.1, idle=True) is None  # within one period
    for i in range(MAX_ENABLE_RESENDS):
        assert gate.on_heartbeat("disabled", 1.0 + i, 0.1, idle=True) == "enable"
        gate.sent("enable", 1.0 + i)
    assert gate.on_heartbeat("disabled", 10.0, 0.1, idle=True) is None  # resends used up
    gate = _gate("enable")
    assert gate.on_heartbeat("enabled", 1.0, 0.1, idle=True) is None  # confirmed
    assert gate.on_heartbeat("disabled", 2.0, 0.1, idle=True) is None  # needs ~/enable
    gate.estop("x")
    assert gate.on_heartbeat("enabled", 3.0, 0.1, idle=False) is None  # a command queued
    assert gate.on_heartbeat("enabled", 3.0, 0.1, idle=True) == "estop"
    gate.sent("estop", 3.0)
    assert gate.on_heartbeat("disabled", 3.05, 0.1, idle=True) is None  # just sent
    assert gate.on_heartbeat("estop", 4.0, 0.1, idle=True) is None
