"""Tests of crawler_motion.motion.continuous: the continuous-stance step option.

Expected values are computed independently of the module: junction states from one-sided
evaluation with ``numpy.polynomial``, the horizontal swing from a 7x7 linear solve of the
documented constraints in absolute time, the stance velocity from ``-stride / t_s`` and the
body velocity from ``stride / t_s``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.polynomial import polynomial as npoly

from crawler_motion.errors import TrajectoryError
from crawler_motion.model.config import load_config
from crawler_motion.motion.continuous import (
    body_velocity,
    continuous_step_cycle,
    continuous_swing_segments,
    stance_velocity,
)
from crawler_motion.motion.trajectory import Piecewise, SwingShape, step_cycle

CFG = load_config()
GAIT = CFG.gait
PROFILES = GAIT.profiles
FEET = CFG.robot.standing_feet()
CENTER = FEET[0]
FAST = settings(max_examples=60, deadline=None)


def shape(profile: str = "smooth", lift: float = GAIT.lift, arc: float = GAIT.arc,
          swing: float = GAIT.swing_time) -> SwingShape:
    return SwingShape(lift, arc, swing, PROFILES[profile])


def stride_vec(length: float, heading: float) -> np.ndarray:
    return length * np.array([math.cos(heading), math.sin(heading)])


def one_sided(pw: Piecewise, k: int, at_end: bool) -> tuple[np.ndarray, ...]:
    """Position, velocity, acceleration of segment ``k`` at its start or end (numpy.polynomial)."""
    seg = pw.segments[k]
    u = 1.0 if at_end else 0.0
    t = seg.duration
    out = []
    for order in range(3):
        out.append(np.array([npoly.polyval(u, npoly.polyder(row, order)) for row in seg.coeffs])
                   / t**order)
    return tuple(out)


def scales(pw: Piecewise, center: np.ndarray, stride: float, height: float
           ) -> tuple[float, float, float]:
    """Position, velocity and acceleration scales of a cycle (for relative tolerances)."""
    pos = max(float(np.abs(center).max()), stride, height)
    t = float(pw.durations.min())
    return pos, pos / t, pos / (t * t)


cycles = st.fixed_dictionaries({
    "profile": st.sampled_from(["rest", "smooth"]),
    "stride": st.one_of(st.just(0.0), st.floats(1e-4, GAIT.max_stride)),
    "heading": st.floats(-math.pi, math.pi),
    "lift": st.floats(1e-3, 0.03),
    "arc": st.one_of(st.just(0.0), st.floats(0.0, 0.03)),
    "swing": st.floats(0.1, 5.0),
    "stance": st.floats(0.1, 5.0),
    "leg": st.integers(0, 3),
})


def build(d: dict) -> tuple[Piecewise, np.ndarray, np.ndarray]:
    center = FEET[d["leg"]]
    stride = stride_vec(d["stride"], d["heading"])
    pw = continuous_step_cycle(center, stride, shape(d["profile"], d["lift"], d["arc"],
                                                     d["swing"]), d["stance"])
    return pw, center, stride


def assert_c2(pw: Piecewise, center: np.ndarray, stride: float, height: float) -> None:
    """Position, velocity, acceleration continuous at B, D, E and A (the wrap) to 1e-9."""
    tol = [1e-9 * s for s in scales(pw, center, stride, height)]
    n = len(pw.segments)
    for k in range(n):
        left = one_sided(pw, k, at_end=True)
        right = one_sided(pw, (k + 1) % n, at_end=False)
        for order, (lv, rv) in enumerate(zip(left, right, strict=True)):
            assert np.abs(lv - rv).max() <= tol[order], (pw.phases[k], order, lv, rv)


# --- the default step ------------------------------------------------------------------------

@pytest.mark.parametrize("profile", ["rest", "smooth"])
def test_default_cycle_layout_and_closure(profile):
    stride = np.array([GAIT.stride, 0.0])
    pw = continuous_step_cycle(CENTER, stride, shape(profile), GAIT.stance_time)
    assert pw.phases == ("lift", "arc", "lower", "stance")
    prof = PROFILES[profile]
    t_w = GAIT.swing_time
    want = [prof.lift_fraction * t_w, prof.arc_fraction * t_w, prof.lower_fraction * t_w,
            GAIT.stance_time]
    np.testing.assert_allclose(pw.durations, want, rtol=1e-12)
    a = CENTER - np.array([GAIT.stride / 2, 0.0, 0.0])
    e = CENTER + np.array([GAIT.stride / 2, 0.0, 0.0])
    np.testing.assert_allclose(one_sided(pw, 0, False)[0], a, atol=1e-15)
    np.testing.assert_allclose(one_sided(pw, 2, True)[0], e, atol=1e-15)
    np.testing.assert_allclose(one_sided(pw, 3, True)[0], a, atol=1e-15)  # closed cycle
    assert_c2(pw, CENTER, GAIT.stride, GAIT.lift + GAIT.arc)


def test_stance_is_constant_velocity_and_matches_touch_down():
    stride = np.array([GAIT.stride, 0.0])
    t_s = GAIT.stance_time
    pw = continuous_step_cycle(CENTER, stride, shape(), t_s)
    v_s = np.array([-GAIT.stride / t_s, 0.0, 0.0])
    t = np.linspace(pw.breaks[3], pw.breaks[4], 101)
    pos, vel, acc = pw.evaluate(t)
    np.testing.assert_allclose(vel, np.broadcast_to(v_s, vel.shape), rtol=0, atol=1e-15)
    np.testing.assert_allclose(acc, 0.0, atol=1e-15)
    np.testing.assert_allclose(pos[:, 2], CENTER[2], atol=1e-15)  # on the ground
    np.testing.assert_allclose(stance_velocity(stride, t_s), v_s, rtol=1e-15)
    np.testing.assert_allclose(body_velocity(stride, t_s), -v_s, rtol=1e-15)
    # Touch-down (end of lower) and lift-off (start of lift): zero velocity over the ground.
    body = np.array([GAIT.stride / t_s, 0.0, 0.0])
    for k, at_end in ((2, True), (0, False)):
        _, vel_k, acc_k = one_sided(pw, k, at_end)
        np.testing.assert_allclose(vel_k + body, 0.0, atol=1e-12)
        np.testing.assert_allclose(acc_k, 0.0, atol=1e-9)


def test_vertical_rows_are_the_profile_and_horizontal_is_one_sextic():
    stride = np.array([0.05, -0.02])
    t_s = 0.8
    sh = shape("smooth")
    pw = continuous_step_cycle(CENTER, stride, sh, t_s)
    ref = step_cycle(CENTER, stride, sh, t_s)
    for seg, ref_seg in zip(pw.segments[:3], ref.segments[:3], strict=True):
        np.testing.assert_array_equal(seg.coeffs[2], ref_seg.coeffs[2])
    # Independent: the sextic in absolute time meeting the documented 7 constraints.
    t_w = sh.swing_time
    a = CENTER[:2] - stride / 2
    e = CENTER[:2] + stride / 2
    v = -stride / t_s

    def row(t: float, order: int) -> list[float]:
        return [math.perm(i, order) * t ** (i - order) if i >= order else 0.0 for i in range(7)]

    # s(0), v(0), a(0), s(T), v(T), a(T), s(T/2)
    matrix = np.array([row(0.0, 0), row(0.0, 1), row(0.0, 2), row(t_w, 0), row(t_w, 1),
                       row(t_w, 2), row(t_w / 2, 0)])
    t = np.linspace(0.0, t_w, 997)
    pos, vel, _ = pw.evaluate(t)
    for dim in range(2):
        rhs = np.array([a[dim], v[dim], 0.0, e[dim], v[dim], 0.0, (a[dim] + e[dim]) / 2])
        c = np.linalg.solve(matrix, rhs)
        np.testing.assert_allclose(pos[:, dim], npoly.polyval(t, c), atol=1e-12)
        np.testing.assert_allclose(vel[:, dim], npoly.polyval(t, npoly.polyder(c)), atol=1e-11)


def test_overshoot_past_the_stride_ends_is_documented_fraction():
    pw = continuous_step_cycle(np.zeros(3), [GAIT.stride, 0.0], shape(), GAIT.swing_time)
    x = pw.evaluate(np.linspace(0.0, pw.t_end, 20001))[0][:, 0]
    over = (x.max() - GAIT.stride / 2) / GAIT.stride
    assert 0.096 < over < 0.098  # "about 9.7 %" for t_s = t_w
    assert abs(x.min() + x.max()) < 1e-12  # symmetric


def test_zero_stride_steps_in_place():
    pw = continuous_step_cycle(CENTER, [0.0, 0.0], shape(), 0.6)
    pos, vel, _ = pw.evaluate(np.linspace(0.0, pw.t_end, 501))
    np.testing.assert_allclose(pos[:, :2], np.broadcast_to(CENTER[:2], (501, 2)), atol=1e-15)
    np.testing.assert_allclose(vel[:, :2], 0.0, atol=1e-15)


@pytest.mark.parametrize("bad", [
    {"degree": 4}, {"stance_time": 0.0}, {"stance_time": -1.0}, {"stance_time": math.nan},
    {"stride": [math.inf, 0.0]}, {"stride": [0.1]}, {"center": [0.0, 0.0]},
    {"swing_time": 0.0}, {"lift": 0.0},
])
def test_invalid_input_is_a_trajectory_error(bad):
    args = {"center": CENTER, "stride": [0.06, 0.0], "stance_time": 0.6}
    sh = {"lift": GAIT.lift, "arc": GAIT.arc, "swing_time": 0.6, "degree": 6}
    for key, value in bad.items():
        (sh if key in sh else args)[key] = value
    swing = SwingShape(sh["lift"], sh["arc"], sh["swing_time"], PROFILES["smooth"],
                       degree=sh["degree"])
    with pytest.raises(TrajectoryError):
        continuous_step_cycle(args["center"], args["stride"], swing, args["stance_time"])


def test_swing_segments_refuse_the_quartic():
    sh = SwingShape(GAIT.lift, GAIT.arc, 0.6, PROFILES["rest"], degree=4)
    with pytest.raises(TrajectoryError, match="degree 6"):
        continuous_swing_segments(CENTER, CENTER + 0.01, sh, [0.0, 0.0])


# --- properties --------------------------------------------------------------------------------

@FAST
@given(d=cycles)
def test_c2_at_every_junction_including_lift_off_and_touch_down(d):
    pw, center, _ = build(d)
    assert_c2(pw, center, d["stride"], d["lift"] + d["arc"])


@FAST
@given(d=cycles)
def test_stance_velocity_constant_and_ground_velocity_zero_at_a_and_e(d):
    pw, center, stride = build(d)
    _, vel_s, acc_s = scales(pw, center, d["stride"], d["lift"] + d["arc"])
    v_s = np.array([*(-stride / d["stance"]), 0.0])
    t = np.linspace(pw.breaks[3], pw.breaks[4], 51)
    _, vel, acc = pw.evaluate(t)
    assert np.abs(vel - v_s).max() <= 1e-12 * vel_s
    assert np.abs(acc).max() <= 1e-12 * acc_s
    body = body_velocity(stride, d["stance"])
    for k, at_end in ((2, True), (0, False)):  # touch-down E, lift-off A
        _, v, a = one_sided(pw, k, at_end)
        assert np.abs(v + body).max() <= 1e-9 * vel_s
        assert np.abs(a).max() <= 1e-9 * acc_s


@FAST
@given(d=cycles)
def test_closed_cycle_ground_level_monotone_lift_and_lower(d):
    pw, center, _ = build(d)
    tol = scales(pw, center, d["stride"], d["lift"] + d["arc"])
    pos_s, vel_s, _ = tol
    start = one_sided(pw, 0, False)
    end = one_sided(pw, 3, True)
    for order in range(3):
        assert np.abs(start[order] - end[order]).max() <= 1e-9 * tol[order]
    ground = center[2]
    for k, phase in enumerate(pw.phases):
        t = np.linspace(pw.breaks[k], pw.breaks[k + 1], 201)
        pos, vel, _ = pw.evaluate(t)
        assert pos[:, 2].min() >= ground - 1e-12 * pos_s, phase
        if phase == "lift":
            assert vel[1:-1, 2].min() >= -1e-12 * vel_s
        elif phase == "lower":
            assert vel[1:-1, 2].max() <= 1e-12 * vel_s


@FAST
@given(d=cycles)
def test_foot_never_moves_backwards_over_the_ground(d):
    pw, center, stride = build(d)
    _, vel_s, _ = scales(pw, center, d["stride"], d["lift"] + d["arc"])
    t = np.linspace(0.0, pw.t_end, 1001)
    _, vel, _ = pw.evaluate(t)
    ground = vel + body_velocity(stride, d["stance"])
    norm = float(np.hypot(*stride))
    if norm == 0.0:
        assert np.abs(ground[:, :2]).max() <= 1e-12 * vel_s
        return
    along = ground[:, :2] @ (stride / norm)
    across = ground[:, :2] @ (np.array([-stride[1], stride[0]]) / norm)
    assert along.min() >= -1e-9 * vel_s
    assert np.abs(across).max() <= 1e-9 * vel_s
