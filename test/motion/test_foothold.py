"""Terrain-adaptive touch-down offsets: C² at every event, held footholds, the search and its
refusal, unknown contacts."""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import load_config
from crawler_motion.motion.contact_estimation import FootContact
from crawler_motion.motion.foothold import (
    EARLY_CONFIRM,
    FootholdAdapter,
    FootholdSettings,
    Mode,
    polynomial,
    stop_quintic,
)
from crawler_motion.motion.trajectory import Piecewise, SwingShape, swing_segments

YES, NO, UNKNOWN = FootContact.YES, FootContact.NO, FootContact.UNKNOWN
GROUND = -0.07  # planned ground z of the test swing [m]
SWING = 0.6  # [s]
DT = 0.001  # tick [s]
H = 1e-5  # finite-difference step [s]


def _plan() -> Piecewise:
    shape = SwingShape(0.01, 0.01, SWING, load_config().gait.profiles["smooth"])
    return Piecewise(swing_segments(np.array([-0.03, 0.19, GROUND]),
                                    np.array([0.03, 0.19, GROUND]), shape))


PLAN = _plan()
T_LOWER = float(PLAN.breaks[PLAN.phases.index("lower")])


def _z(t: float) -> tuple[float, float]:
    """Planned z [m] and ż [m/s] at ``t`` (resting on the ground after the swing)."""
    if t >= SWING:
        return GROUND, 0.0
    pos, vel, _ = PLAN.evaluate(max(t, 0.0))
    return float(pos[0, 2]), float(vel[0, 2])


def _offset(adapter: FootholdAdapter, t: float) -> tuple[float, float]:
    z, zd = _z(t)
    delta, rate = adapter.offsets(t, [z], [zd])
    return delta[0], rate[0]


def _derivatives(adapter: FootholdAdapter, t: float, side: float) -> np.ndarray:
    """δ, δ', δ'' at ``t`` from one ``side`` (-1 before, +1 after), without events."""
    a = copy.deepcopy(adapter)
    d0, r0 = _offset(a, t)
    _, r1 = _offset(a, t + side * H)
    return np.array([d0, r0, (r1 - r0) / (side * H)])


def _assert_c2(before: FootholdAdapter, after: FootholdAdapter, t: float) -> None:
    left, right = _derivatives(before, t, -1.0), _derivatives(after, t, 1.0)
    assert abs(left[0] - right[0]) < 1e-9, (t, left, right)
    assert abs(left[1] - right[1]) < 1e-6, (t, left, right)
    assert abs(left[2] - right[2]) < 0.05, (t, left, right)


Contacts = Callable[[float], FootContact]


def _run(adapter: FootholdAdapter, contact: Contacts, end: float, start: float = 0.0
         ) -> tuple[list[tuple[float, Mode, Mode]], str | None, list[float]]:
    """Tick from ``start`` to ``end``: the mode changes (time, before, after) each checked
    C² at its event time, the failure, the offsets."""
    changes: list[tuple[float, Mode, Mode]] = []
    offsets = []
    k = round(start / DT)
    while (t := k * DT) <= end + 1e-12:
        before = copy.deepcopy(adapter)
        failure = adapter.update(t, [_z(t)[0]], [contact(t)])
        if adapter.modes() != before.modes():
            mode0, mode1 = before.modes()[0], adapter.modes()[0]
            changes.append((t, mode0, mode1))
            at = T_LOWER if mode0 is Mode.BLEND else (SWING if mode1 is Mode.SEARCH else t)
            _assert_c2(before, adapter, at)
        offsets.append(_offset(adapter, t)[0])
        if failure is not None:
            return changes, failure, offsets
        k += 1
    return changes, None, offsets


def _swinging(held: float = 0.0, settings: FootholdSettings | None = None) -> FootholdAdapter:
    adapter = FootholdAdapter(("lf",), settings)
    adapter.reset([held])
    before = copy.deepcopy(adapter)
    adapter.begin_swing(0, PLAN, 0.0, SWING)
    if held:
        _assert_c2(before, adapter, 0.0)
    return adapter


def _contact_below(height: float, after: float = SWING) -> Contacts:
    """Contact once the planned foot is within ``height`` of its ground (or after ``after``)."""
    def contact(t: float) -> FootContact:
        z = _z(t)[0] if t < SWING else GROUND
        return YES if (T_LOWER <= t and z - GROUND <= height) or t >= after else NO
    return contact


def test_early_contact_stops_smoothly_and_the_foot_stays_where_it_landed() -> None:
    adapter = _swinging()
    changes, failure, offsets = _run(adapter, _contact_below(0.009), 1.5)
    assert failure is None
    assert [(m0, m1) for _, m0, m1 in changes] == [(Mode.HELD, Mode.STOP), (Mode.STOP, Mode.HELD)]
    held = adapter.held()[0]
    assert 0.001 < held < 0.009  # above the planned ground, below where it touched
    tail = offsets[round(SWING / DT):]
    assert np.ptp(tail) < 1e-12 and tail[0] == pytest.approx(held)  # constant in stance


def test_the_stop_quintic_meets_its_boundary_conditions() -> None:
    c = stop_quintic(0.1, -0.2, 3.0, 0.04)
    assert polynomial(c, 0.0) == pytest.approx((0.1, -0.2, 3.0))
    end = polynomial(c, 0.04)
    assert end[0] == pytest.approx(0.1 - 0.2 * 0.02) and end[1:] == pytest.approx((0, 0),
                                                                                   abs=1e-9)


@given(st.floats(-1, 1), st.floats(-0.5, 0.5), st.floats(-20, 20), st.floats(0.005, 1.0))
def test_every_stop_lands_at_rest_halfway_along_its_speed(z: float, v: float, a: float,
                                                         t: float) -> None:
    p, dp, ddp = polynomial(stop_quintic(z, v, a, t), t)
    assert p == pytest.approx(z + v * t / 2, abs=1e-9)
    assert abs(dp) < 1e-9 and abs(ddp) < 1e-6 * max(1.0, abs(a))


def test_the_next_swing_lifts_from_the_foothold_and_blends_back_to_the_plan() -> None:
    adapter = _swinging(held=0.008)
    assert _offset(adapter, 0.0)[0] == pytest.approx(0.008)
    changes, failure, offsets = _run(adapter, _contact_below(0.0005), 1.0)
    assert failure is None
    assert changes[0][1:] == (Mode.BLEND, Mode.HELD) and changes[0][0] >= T_LOWER
    assert offsets[round(T_LOWER / DT) + 1] == 0.0  # lowers to the planned ground again


def test_a_swing_without_contact_searches_below_the_ground_until_contact() -> None:
    adapter = _swinging()
    changes, failure, _ = _run(adapter, _contact_below(-1.0, after=SWING + 0.25), 1.5)
    assert failure is None
    assert [(m0, m1) for _, m0, m1 in changes] == [
        (Mode.HELD, Mode.SEARCH), (Mode.SEARCH, Mode.STOP), (Mode.STOP, Mode.HELD)]
    held = adapter.held()[0]
    assert -0.02 < held < -0.002  # below the planned ground: where it found it


def test_no_ground_within_the_search_depth_ends_the_walk_with_the_leg_and_the_depth() -> None:
    settings = FootholdSettings(search_depth=0.01, search_speed=0.02)
    adapter = _swinging(settings=settings)
    _, failure, offsets = _run(adapter, lambda t: NO, 3.0)
    assert failure is not None and "LF" in failure and "10.0 mm" in failure
    assert offsets[-1] == pytest.approx(-0.01)  # at rest at the depth, not descending
    assert _offset(adapter, 5.0) == pytest.approx((-0.01, 0.0))


def test_the_search_profile_is_c2_and_stays_within_the_depth() -> None:
    s = FootholdSettings()
    times = np.linspace(-0.01, s.search_time + 0.01, 4001)
    prof = np.array([s.search(t) for t in times])
    assert prof[:, 0].min() >= 0.0 and prof[:, 0].max() == pytest.approx(s.search_depth)
    assert prof[:, 1].max() == pytest.approx(s.search_speed)
    assert np.all(np.diff(prof[:, 0]) >= -1e-15)
    step = times[1] - times[0]
    assert np.abs(np.diff(prof[:, 0])).max() <= s.search_speed * step * 1.001
    assert np.abs(np.diff(prof[:, 2])).max() < 0.01  # no jump of the acceleration


@pytest.mark.parametrize("contacts", [None, [UNKNOWN]])
def test_unknown_contacts_leave_the_blind_plan(contacts: list[FootContact] | None) -> None:
    adapter = _swinging()
    for k in range(round(1.5 / DT)):
        t = k * DT
        assert adapter.update(t, [_z(t)[0]], contacts) is None
        assert _offset(adapter, t) == (0.0, 0.0)


def test_a_contact_just_before_the_planned_touch_down_changes_nothing() -> None:
    """On flat ground the contact comes with the touch-down (here 10 ms early, the foot
    within the tolerance): no stop, no search, δ stays 0."""
    assert 0.0 < _z(SWING - 0.01)[0] - GROUND < FootholdSettings().tolerance
    adapter = _swinging()
    changes, failure, offsets = _run(adapter, _contact_below(-1.0, after=SWING - 0.01), 1.2)
    assert (changes, failure) == ([], None)
    assert max(abs(x) for x in offsets) == 0.0


def test_single_force_spikes_during_the_lowering_are_no_contact() -> None:
    adapter = _swinging()
    k = round((T_LOWER + 0.03) / DT)
    forces = [5.0]
    for i in range(k, k + EARLY_CONFIRM + 2):
        t = i * DT
        spike = i % 2 == 0
        adapter.update(t, [_z(t)[0]], [YES if spike else NO], forces)
    assert adapter.modes() == (Mode.HELD,)
    adapter.update(1.0 * SWING - 0.05, [_z(SWING - 0.05)[0]], [YES], [1.0])  # under the force
    adapter.update(1.0 * SWING - 0.049, [_z(SWING - 0.049)[0]], [YES], [1.0])
    assert adapter.modes() == (Mode.HELD,)


@pytest.mark.parametrize(("field", "value"), [
    ("tolerance", -0.001), ("tolerance", float("nan")), ("stop_time", 0.0),
    ("search_depth", 0.2), ("search_speed", 0.0), ("touch_force", -1.0), ("enabled", 1),
    ("stop_time", "0.04"), ("enabled", "yes")])
def test_bad_settings_are_refused_with_the_reason(field: str, value: object) -> None:
    with pytest.raises(ConfigError, match=field if field != "enabled" else "true or false"):
        FootholdSettings(**{field: value})  # type: ignore[arg-type]


@pytest.mark.parametrize(("field", "value"), [
    ("tolerance", 0.0), ("tolerance", 0.05), ("search_depth", 0.0), ("stop_time", 0.005)])
def test_boundary_settings_are_accepted(field: str, value: float) -> None:
    assert getattr(FootholdSettings(**{field: value}), field) == value  # type: ignore[arg-type]
