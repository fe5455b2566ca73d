"""Stumble handling: the retried swings (C², the plan's state at the hit and at touch-down) and
the hit detection."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import load_config
from crawler_motion.motion.foothold import lowering_start
from crawler_motion.motion.gait import WalkParams, iter_walk
from crawler_motion.motion.stumble import (
    ARM_HEIGHT,
    HIT_CONFIRM,
    MIN_RETRY_TIME,
    HitWatch,
    Retry,
    StumbleSettings,
    lift_swing,
    replan_swing,
)
from crawler_motion.motion.trajectory import Piecewise

CFG = load_config()
SETTINGS = StumbleSettings()


def _swing() -> tuple[Piecewise, float]:
    """A front leg's steady swing of the default walk (slot time from 0) and its swing time."""
    for slot in iter_walk(CFG, WalkParams.defaults(CFG.gait), 2):
        if slot.kind == "steady" and 0 in slot.group:
            return slot.legs[0], slot.swing_time
    raise AssertionError("no steady slot swings leg 0")


PLAN, SWING = _swing()
T_LOWER = lowering_start(PLAN, SWING)


def _jumps(plan: Piecewise) -> np.ndarray:
    """|left - right| of position, velocity and acceleration at every inner junction."""
    out = []
    for k, b in enumerate(plan.breaks[1:-1]):
        seg = plan.segments[k]
        left = seg.evaluate(seg.duration)
        right = plan.segments[k + 1].evaluate(0.0)
        out.append([np.abs(a - c).max() for a, c in zip(left, right, strict=True)])
        assert b == pytest.approx(plan.breaks[k] + seg.duration)
    return np.array(out)


def _check_retry(retry: Retry, t_hit: float) -> None:
    plan = retry.plan
    jumps = _jumps(plan)
    assert np.all(jumps[:, 0] < 1e-9) and np.all(jumps[:, 1] < 1e-7)
    assert np.all(jumps[:, 2] < 1e-4)  # C²: accelerations [m/s²] agree to rounding
    for t in (0.0, t_hit, SWING, PLAN.t_end):  # the plan's state before, at and after
        for a, b in zip(plan.evaluate(t), PLAN.evaluate(t), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-9)
    after = np.linspace(SWING, PLAN.t_end, 7)
    np.testing.assert_allclose(plan.evaluate(after)[0], PLAN.evaluate(after)[0], atol=1e-12)
    apex = PLAN.evaluate(np.linspace(t_hit, SWING, 50))[0][:, 2].max()
    z = plan.evaluate(np.linspace(t_hit, SWING, 400))[0][:, 2]
    assert z.max() == pytest.approx(apex + SETTINGS.lift, abs=2e-4)  # lifted higher
    assert retry.z_top == pytest.approx(apex + SETTINGS.lift, abs=2e-4)
    assert t_hit < retry.t_top <= retry.t_lower < SWING
    assert plan.phase_at(retry.t_lower + 1e-6) == ["lower"]


# near lift-off, and near touch-down: the latest hits with the stop and MIN_RETRY_TIME left
@pytest.mark.parametrize("t_hit", [0.01, 0.05, SWING - SETTINGS.stop_time - MIN_RETRY_TIME - 0.05,
                                   SWING - SETTINGS.stop_time - MIN_RETRY_TIME])
def test_a_hit_near_lift_off_or_touch_down_stops_backs_off_lifts_higher_and_lands_as_planned(
        t_hit: float) -> None:
    backing = StumbleSettings(retreat=0.005)
    retry = replan_swing(PLAN, SWING, t_hit, backing)
    assert retry is not None
    _check_retry(retry, t_hit)
    top = retry.plan.evaluate(retry.t_top)[0][0]
    stop = t_hit + SETTINGS.stop_time
    stopped = retry.plan.evaluate(stop)
    assert np.abs(stopped[1]).max() < 1e-9  # at rest after the stop
    stride = (PLAN.evaluate(SWING)[0] - PLAN.evaluate(0.0)[0])[0, :2]
    direction = stride / np.linalg.norm(stride)
    back = (stopped[0][0, :2] - top[:2]) @ direction
    assert back == pytest.approx(backing.retreat, abs=1e-9)
    plain = replan_swing(PLAN, SWING, t_hit, SETTINGS)  # the default: no retreat
    assert plain is not None
    np.testing.assert_allclose(plain.plan.evaluate(plain.t_top)[0][0, :2],
                               stopped[0][0, :2], atol=1e-12)


@pytest.mark.parametrize("t_hit", [0.0, 0.1, 0.2, 0.28,
                                   min(T_LOWER - 0.01, SWING - MIN_RETRY_TIME)])
def test_the_vertical_only_retry_lifts_higher_on_the_planned_path(t_hit: float) -> None:
    retry = lift_swing(PLAN, SWING, t_hit, SETTINGS)
    assert retry is not None
    _check_retry(retry, t_hit)
    times = np.linspace(t_hit, SWING, 50)
    np.testing.assert_allclose(retry.plan.evaluate(times)[0][:, :2],
                               PLAN.evaluate(times)[0][:, :2], atol=1e-9)  # same x, y


@pytest.mark.parametrize(("margin", "retried"), [(1e-6, True), (-1e-6, False)])
def test_a_hit_too_close_to_the_touch_down_cannot_be_retried(margin: float, retried: bool
                                                            ) -> None:
    t_lift = SWING - MIN_RETRY_TIME - margin
    assert (lift_swing(PLAN, SWING, t_lift, SETTINGS) is not None) is retried
    t_replan = t_lift - SETTINGS.stop_time
    assert (replan_swing(PLAN, SWING, t_replan, SETTINGS) is not None) is retried


@settings(max_examples=25, deadline=None)
@given(st.floats(0.0, 0.43), st.floats(0.0, 0.03), st.floats(0.05, 0.3))
def test_every_retry_is_c2_and_meets_the_plan(t_hit: float, lift: float, lift_time: float
                                             ) -> None:
    s = StumbleSettings(lift=lift, lift_time=lift_time)
    for make in (replan_swing, lift_swing):
        retry = make(PLAN, SWING, t_hit, s)
        if retry is None:
            continue
        jumps = _jumps(retry.plan)
        assert np.all(jumps[:, :2] < 1e-7) and np.all(jumps[:, 2] < 1e-4)
        for a, b in zip(retry.plan.evaluate(SWING), PLAN.evaluate(SWING), strict=True):
            np.testing.assert_allclose(a, b, atol=1e-9)


@pytest.mark.parametrize(("field", "value"), [
    ("force", -0.1), ("force", 100.1), ("lift", 0.051), ("retreat", -1e-9),
    ("lift_time", 0.049), ("lift_time", 1.01), ("stop_time", 0.0), ("force", math.nan),
    ("lift", True), ("enabled", 1),
])
def test_bad_settings_are_refused_with_the_range(field: str, value: object) -> None:
    with pytest.raises(ConfigError, match=f"stumble {field}"):
        StumbleSettings(**{field: value})


@pytest.mark.parametrize(("field", "value"), [
    ("force", 0.0), ("force", 100.0), ("lift", 0.0), ("lift", 0.05), ("lift_time", 0.05),
    ("stop_time", 0.5),
])
def test_boundary_settings_are_accepted(field: str, value: float) -> None:
    assert getattr(StumbleSettings(**{field: value}), field) == value


def _feed(watch: HitWatch, rows: list[tuple[float, bool, float, float]],
          stamps: list[float] | None = None) -> list[float]:
    """Times at which leg 0 is reported, from (t, touching, force, z) rows (each a new
    contact estimate unless ``stamps`` says otherwise)."""
    hits = []
    for k, (t, touching, force, z) in enumerate(rows):
        stamp = t if stamps is None else stamps[k]
        if watch.update(t, [touching, False], [force, 0.0], 10.0, [z, 0.0], stamp):
            hits.append(t)
    return hits


#: Planned lift-off z of the watched swings [m]: rows at z 0 are above it by `ARM_HEIGHT`.
LIFT_OFF_Z = -ARM_HEIGHT


@pytest.mark.parametrize(("rows", "expected"), [
    # still on its foothold at lift-off: not armed, no hit
    ([(0.0, True, 20.0, 0.0), (0.01, True, 20.0, 0.0), (0.02, True, 20.0, 0.0)], []),
    # off the ground, then two estimates at the force: a hit at the second
    ([(0.0, False, 0.0, 0.0), (0.1, True, 10.0, 0.0), (0.11, True, 10.0, 0.0)], [0.11]),
    # below the force, or not twice in a row: none
    ([(0.0, False, 0.0, 0.0), (0.1, True, 9.99, 0.0), (0.11, True, 9.99, 0.0)], []),
    ([(0.0, False, 0.0, 0.0), (0.1, True, 20.0, 0.0), (0.11, False, 20.0, 0.0),
      (0.12, True, 20.0, 0.0)], []),
    # from the lowering on: a touch-down, not a hit
    ([(0.0, False, 0.0, 0.0), (0.3, True, 20.0, 0.0), (0.31, True, 20.0, 0.0)], []),
])
def test_hits_need_an_armed_swing_the_force_twice_and_the_time_before_lowering(
        rows: list[tuple[float, bool, float, float]], expected: list[float]) -> None:
    assert HIT_CONFIRM == 2
    watch = HitWatch(2)
    watch.begin(0, 0.3, LIFT_OFF_Z)
    assert _feed(watch, rows) == expected


@pytest.mark.parametrize(("rows", "expected"), [
    # after the rise, above the first hit: one estimate at the force is the second hit
    ([(0.2, True, 10.0, 0.05)], [0.2]),
    ([(0.2, True, 9.99, 0.05), (0.21, True, 9.99, 0.05)], []),
    # during the rise: nothing
    ([(0.15, True, 20.0, 0.05), (0.16, True, 20.0, 0.05)], []),
    # lowered to the height it hit at: landing, not hitting
    ([(0.2, True, 20.0, 0.03), (0.21, True, 20.0, 0.05)], []),
])
def test_a_retried_foot_hits_again_when_it_touches_above_the_first_hit(
        rows: list[tuple[float, bool, float, float]], expected: list[float]) -> None:
    watch = HitWatch(2)
    watch.begin(0, 0.3, LIFT_OFF_Z)
    retry = Retry(PLAN, 0.2, 0.35, 0.06)
    watch.retry(0, retry, 0.03)
    assert watch.retried[0]
    assert _feed(watch, rows) == expected


@pytest.mark.parametrize(("rows", "stamps", "expected"), [
    # read unloaded while still at its lift-off height (a light stance foot), then dragged off
    # its foothold: never armed, no hit
    ([(0.0, False, 0.0, LIFT_OFF_Z), (0.01, True, 20.0, LIFT_OFF_Z + 0.001),
      (0.02, True, 20.0, LIFT_OFF_Z + 0.003)], None, []),
    # off the ground just below the arming height: still not armed
    ([(0.0, False, 0.0, LIFT_OFF_Z + ARM_HEIGHT - 1e-4), (0.1, True, 20.0, 0.0),
      (0.11, True, 20.0, 0.0)], None, []),
    # one estimate seen by two ticks: counted once, no hit
    ([(0.0, False, 0.0, 0.0), (0.1, True, 20.0, 0.0), (0.11, True, 20.0, 0.0)],
     [0.0, 0.1, 0.1], []),
    # ... and a third tick with a new estimate confirms it
    ([(0.0, False, 0.0, 0.0), (0.1, True, 20.0, 0.0), (0.11, True, 20.0, 0.0),
      (0.12, True, 20.0, 0.0)], [0.0, 0.1, 0.1, 0.12], [0.12]),
])
def test_hits_are_armed_above_the_lift_off_and_count_estimates_not_ticks(
        rows: list[tuple[float, bool, float, float]], stamps: list[float] | None,
        expected: list[float]) -> None:
    watch = HitWatch(2)
    watch.begin(0, 0.3, LIFT_OFF_Z)
    assert _feed(watch, rows, stamps) == expected
