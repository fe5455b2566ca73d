"""Tests of crawler_motion.motion.trajectory: sextic/quartic solver, evaluation, one leg's step.

Expected values are computed independently of the module: constraints are checked with
``numpy.polynomial`` evaluation and hand-written derivatives, the step's key points A..E from
the spec's geometry, the junction speeds from the documented rule (``v_b`` / ``v_d`` times the
mean vertical speed of the lift / lower segment) and the time split from the config fractions.
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.polynomial import polynomial as npoly

from crawler_motion.errors import TrajectoryError
from crawler_motion.model.config import load_config
from crawler_motion.motion.trajectory import (
    PHASES,
    Piecewise,
    Segment,
    SwingShape,
    evaluate_polynomial,
    quartic_coefficients,
    rest_segment,
    sextic_coefficients,
    step_cycle,
    swing_segments,
)

CFG = load_config()
GAIT = CFG.gait
PROFILES = GAIT.profiles
CENTER = CFG.robot.standing_feet()[0]  # the lf standing foot: a realistic, off-origin centre
FAST = settings(max_examples=60, deadline=None)

# Value strategies: zero, negative and positive values; durations from 0.1 ms to 1000 s.
values = st.one_of(st.just(0.0), st.floats(-1e3, 1e3, allow_nan=False, allow_subnormal=False))
durations = st.one_of(st.sampled_from([1e-4, 1e-3, 0.6, 1e3]),
                      st.floats(1e-4, 1e3, allow_nan=False, allow_subnormal=False))


def independent_eval(coeffs: np.ndarray, duration: float, tau: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity, acceleration of a normalised-time polynomial, via numpy.polynomial."""
    c = np.atleast_2d(np.asarray(coeffs, dtype=float))
    u = tau / duration
    pos = np.array([npoly.polyval(u, row) for row in c])
    vel = np.array([npoly.polyval(u, npoly.polyder(row)) for row in c]) / duration
    acc = np.array([npoly.polyval(u, npoly.polyder(row, 2)) for row in c]) / duration**2
    return pos, vel, acc


# --- sextic / quartic solver ---------------------------------------------------------------

@FAST
@given(t=durations, s0=values, v0=values, a0=values, s1=values, v1=values, a1=values,
       s_mid=values)
def test_sextic_meets_all_seven_constraints(t, s0, v0, a0, s1, v1, a1, s_mid):
    c = sextic_coefficients(t, s0, v0, a0, s1, v1, a1, s_mid)
    assert c.shape == (7,)
    assert np.all(np.isfinite(c))
    # Compare in normalised units (positions; v * T; a * T^2) relative to the problem's scale.
    scale = max(abs(s0), abs(s1), abs(s_mid), abs(v0 * t), abs(v1 * t), abs(a0 * t * t),
                abs(a1 * t * t), 1e-300)
    p0, vel0, acc0 = independent_eval(c, t, 0.0)
    p1, vel1, acc1 = independent_eval(c, t, t)
    pm, _, _ = independent_eval(c, t, t / 2)
    got = [p0[0], vel0[0] * t, acc0[0] * t * t, p1[0], vel1[0] * t, acc1[0] * t * t, pm[0]]
    want = [s0, v0 * t, a0 * t * t, s1, v1 * t, a1 * t * t, s_mid]
    for name, g, w in zip(("s0", "v0", "a0", "s1", "v1", "a1", "s_mid"), got, want, strict=True):
        assert abs(g - w) <= 1e-9 * scale, (name, g, w, scale)


def test_sextic_broadcasts_over_coordinates():
    s0 = np.array([0.0, 1.0, -2.0])
    c = sextic_coefficients(0.5, s0, 0.0, 0.0, s0 + 1.0, 0.0, 0.0, s0 + 0.5)
    assert c.shape == (3, 7)
    for row, start in zip(c, s0, strict=True):
        np.testing.assert_allclose(row, [start, 0, 0, 10, -15, 6, 0], atol=1e-12)


@pytest.mark.parametrize("t", [1e-4, 0.15, 0.6, 1.0, 1e3])
def test_rest_segment_is_the_quintic_smoothstep(t):
    # s(u) = 10u^3 - 15u^4 + 6u^5: the unique polynomial with v = a = 0 at both ends that
    # is point-symmetric about the midpoint, so the sextic term vanishes.
    seg = rest_segment(np.array([0.0]), np.array([1.0]), t)
    np.testing.assert_allclose(seg.coeffs[0], [0, 0, 0, 10, -15, 6, 0], atol=1e-12)
    for u in (0.0, 0.1, 0.25, 0.5, 0.8, 1.0):
        pos, vel, acc = seg.evaluate(u * t)
        assert pos[0] == pytest.approx(10 * u**3 - 15 * u**4 + 6 * u**5, abs=1e-12)
        assert vel[0] * t == pytest.approx(30 * u**2 - 60 * u**3 + 30 * u**4, abs=1e-11)
        assert acc[0] * t * t == pytest.approx(60 * u - 180 * u**2 + 120 * u**3, abs=1e-10)


@FAST
@given(t=durations, s0=values, s1=values, v=values, a=values)
def test_sextic_term_vanishes_for_point_symmetric_conditions(t, s0, s1, v, a):
    # s(1-u) - m = -(s(u) - m) needs v0 = v1, a0 = -a1, s_mid = mean: an odd polynomial about
    # u = 1/2, so the (even) u^6 term is zero.
    c = sextic_coefficients(t, s0, v, a, s1, v, -a, (s0 + s1) / 2)
    scale = max(abs(s0), abs(s1), abs(v * t), abs(a * t * t), 1e-300)
    assert abs(c[6]) <= 1e-9 * scale


def test_sextic_term_present_for_the_arc_apex():
    # The apex above the mean breaks the symmetry: c6 = 64 * (apex excess) - ... != 0.
    c = sextic_coefficients(0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01)
    # Closed form: s = 0.01 * 64 u^3 (1 - u)^3 = 0.64 (u^3 - 3u^4 + 3u^5 - u^6).
    np.testing.assert_allclose(c, 0.64 * np.array([0, 0, 0, 1, -3, 3, -1]), atol=1e-12)


@pytest.mark.parametrize("duration", [0.0, -0.0, -1.0, -1e-9, math.nan, math.inf, -math.inf])
def test_bad_duration_raises(duration):
    with pytest.raises(TrajectoryError, match="duration"):
        sextic_coefficients(duration, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.5)
    with pytest.raises(TrajectoryError, match="duration"):
        quartic_coefficients(duration, 0.0, 0.0, 1.0, 0.0, 0.5)
    with pytest.raises(TrajectoryError):
        rest_segment(np.zeros(3), np.ones(3), duration)


@FAST
@given(t=durations, s0=values, v0=values, s1=values, v1=values, s_mid=values)
def test_quartic_meets_its_five_constraints(t, s0, v0, s1, v1, s_mid):
    c = quartic_coefficients(t, s0, v0, s1, v1, s_mid)
    assert c.shape == (5,)
    scale = max(abs(s0), abs(s1), abs(s_mid), abs(v0 * t), abs(v1 * t), 1e-300)
    p0, vel0, _ = independent_eval(c, t, 0.0)
    p1, vel1, _ = independent_eval(c, t, t)
    pm, _, _ = independent_eval(c, t, t / 2)
    got = [p0[0], vel0[0] * t, p1[0], vel1[0] * t, pm[0]]
    want = [s0, v0 * t, s1, v1 * t, s_mid]
    for g, w in zip(got, want, strict=True):
        assert abs(g - w) <= 1e-9 * scale


def test_quartic_leaves_nonzero_end_accelerations_in_the_studys_setting():
    # The study's first design (foot stops at every junction) with a quartic: on the lift
    # A->B (rise h in T, v = 0 at both ends, midpoint at h/2) the quartic degenerates to the
    # cubic 3u^2 - 2u^3, whose end accelerations are +-6 h / T^2 -- not zero.
    prof = PROFILES["rest"]
    h, t_w = GAIT.lift, GAIT.swing_time
    t_lift = prof.lift_fraction * t_w
    c = quartic_coefficients(t_lift, 0.0, 0.0, h, 0.0, h / 2)
    np.testing.assert_allclose(c, h * np.array([0, 0, 3, -2, 0]), atol=1e-15)
    _, _, a = evaluate_polynomial(c, t_lift, np.array([0.0, t_lift]))
    np.testing.assert_allclose(a, [6 * h / t_lift**2, -6 * h / t_lift**2], rtol=1e-9)
    # Whole swing: the acceleration jumps at B and D (the leg shake); the sextic's does not.
    half = np.array([GAIT.stride / 2, 0.0, 0.0])
    a_pt, e_pt = CENTER - half, CENTER + half
    for degree, jumps in ((4, True), (6, False)):
        shape = SwingShape(GAIT.lift, GAIT.arc, t_w, prof, degree=degree)
        segs = swing_segments(a_pt, e_pt, shape)
        assert [s.coeffs.shape[-1] for s in segs] == [degree + 1] * 3
        for left, right in pairwise(segs):
            a_left = left.evaluate(left.duration)[2]
            a_right = right.evaluate(0.0)[2]
            assert (np.abs(a_left[2] - a_right[2]) > 1.0) == jumps
            assert (np.abs(a_left[2]) > 1.0) == jumps


def test_unknown_degree_raises():
    shape = SwingShape(0.01, 0.01, 0.6, PROFILES["rest"], degree=5)
    with pytest.raises(TrajectoryError, match="degree"):
        swing_segments(np.zeros(3), np.array([0.06, 0, 0]), shape)


@pytest.mark.parametrize(("lift", "arc"), [(0.0, 0.01), (-0.01, 0.01), (0.01, -1e-6)])
def test_bad_heights_raise(lift, arc):
    shape = SwingShape(lift, arc, 0.6, PROFILES["smooth"])
    with pytest.raises(TrajectoryError):
        swing_segments(np.zeros(3), np.array([0.06, 0, 0]), shape)


# --- evaluation -------------------------------------------------------------------------------

@FAST
@given(t=st.floats(0.05, 5.0), coeffs=st.lists(st.floats(-10, 10), min_size=7, max_size=7),
       u=st.floats(0.05, 0.95))
def test_evaluate_polynomial_derivatives_match_finite_differences(t, coeffs, u):
    c = np.array(coeffs)
    tau = u * t
    h = 1e-4 * t
    pos, vel, acc = evaluate_polynomial(c, t, np.array([tau - h, tau, tau + h]))
    scale = np.abs(c).sum() + 1.0
    # Central differences: error O(h^2) times the next derivatives (<= 6^4 scale / t^4 ...).
    assert vel[1] == pytest.approx((pos[2] - pos[0]) / (2 * h), abs=1e-5 * scale / t)
    assert acc[1] == pytest.approx((vel[2] - vel[0]) / (2 * h), abs=1e-5 * scale / t**2)
    assert acc[1] == pytest.approx((pos[2] - 2 * pos[1] + pos[0]) / h**2,
                                   abs=1e-3 * scale / t**2)
    # And exactly (to rounding) the independent evaluation.
    want = independent_eval(c, t, tau)
    for got, ref in zip((pos[1], vel[1], acc[1]), want, strict=True):
        assert got == pytest.approx(ref[0], rel=1e-9, abs=1e-9 * scale / t**2)


def test_evaluate_polynomial_shapes():
    c2 = np.arange(14.0).reshape(2, 7)
    pos, vel, acc = evaluate_polynomial(c2, 2.0, np.linspace(0, 2, 5))
    assert pos.shape == vel.shape == acc.shape == (5, 2)
    pos1, _, _ = evaluate_polynomial(c2[0], 2.0, np.linspace(0, 2, 5))
    assert pos1.shape == (5,)
    np.testing.assert_allclose(pos1, pos[:, 0])
    np.testing.assert_allclose(pos[-1], c2.sum(axis=-1))  # u = 1: sum of the coefficients


def make_piecewise(t0: float = 1.0) -> Piecewise:
    rng = np.random.default_rng(7)
    segs = [Segment(rng.normal(size=(2, 7)), d, ph)
            for d, ph in ((0.2, "lift"), (0.5, "arc"), (0.3, "lower"))]
    return Piecewise(segs, t0)


def test_piecewise_span_and_breaks():
    pw = make_piecewise(1.0)
    np.testing.assert_allclose(pw.breaks, [1.0, 1.2, 1.7, 2.0])
    assert pw.t0 == 1.0
    assert pw.t_end == pytest.approx(2.0)
    assert pw.duration == pytest.approx(1.0)
    shifted = pw.shifted(0.5)
    np.testing.assert_allclose(shifted.breaks, pw.breaks + 0.5)


@pytest.mark.parametrize(("t", "index"), [
    (-5.0, 0),          # before the span: first segment
    (1.0, 0),           # t0
    (1.2 - 1e-12, 0),   # just before the first break
    (1.2, 1),           # on a break: the segment that starts there
    (1.2 + 1e-12, 1),
    (1.7, 2),
    (2.0, 2),           # t_end: the last segment
    (9.0, 2),           # after the span: last segment
])
def test_piecewise_index_at_breakpoints(t, index):
    pw = make_piecewise(1.0)
    assert int(pw.index(t)) == index
    assert pw.phase_at(t) == [("lift", "arc", "lower")[index]]


def test_piecewise_evaluate_matches_segments_and_holds_outside():
    pw = make_piecewise(1.0)
    for seg, start in zip(pw.segments, pw.breaks[:-1], strict=True):
        for u in (0.0, 0.3, 0.99):
            got = pw.evaluate(start + u * seg.duration)
            want = independent_eval(seg.coeffs, seg.duration, u * seg.duration)
            for g, w in zip(got, want, strict=True):
                np.testing.assert_allclose(g[0], w, rtol=1e-12, atol=1e-12)
    last = pw.segments[-1]
    end_state = independent_eval(last.coeffs, last.duration, last.duration)
    start_state = independent_eval(pw.segments[0].coeffs, 0.2, 0.0)
    for g, w in zip(pw.evaluate(50.0), end_state, strict=True):
        np.testing.assert_allclose(g[0], w, rtol=1e-12)
    for g, w in zip(pw.evaluate(-50.0), start_state, strict=True):
        np.testing.assert_allclose(g[0], w, rtol=1e-12)


@FAST
@given(t=st.floats(1.0, 2.0))
def test_piecewise_derivatives_match_finite_differences(t):
    pw = make_piecewise(1.0)
    h = 1e-6
    seg = int(pw.index(t))
    lo, hi = pw.breaks[seg], pw.breaks[seg + 1]
    tt = np.clip(t, lo + 2 * h, hi - 2 * h)  # stay inside one segment
    pos, vel, acc = pw.evaluate(np.array([tt - h, tt, tt + h]))
    np.testing.assert_allclose(vel[1], (pos[2] - pos[0]) / (2 * h), rtol=1e-5, atol=1e-3)
    np.testing.assert_allclose(acc[1], (vel[2] - vel[0]) / (2 * h), rtol=1e-5, atol=1e-2)


def test_piecewise_refuses_empty_and_mixed_dimensions():
    with pytest.raises(TrajectoryError):
        Piecewise([])
    with pytest.raises(TrajectoryError, match="dimension"):
        Piecewise([Segment(np.zeros((3, 7)), 1.0), Segment(np.zeros((2, 7)), 1.0)])


# --- one leg's step ---------------------------------------------------------------------------

class Step:
    """Independently computed key points, times and tolerances of one step cycle."""

    def __init__(self, profile: str, stride: float, heading: float, lift: float, arc: float,
                 swing: float, stance: float, center: np.ndarray = CENTER) -> None:
        self.prof = PROFILES[profile]
        self.dir = np.array([math.cos(heading), math.sin(heading), 0.0])
        self.perp = np.array([-math.sin(heading), math.cos(heading), 0.0])
        self.center = np.asarray(center, dtype=float)
        self.stride, self.lift, self.arc = stride, lift, arc
        up = np.array([0.0, 0.0, 1.0])
        self.A = self.center - stride / 2 * self.dir
        self.E = self.center + stride / 2 * self.dir
        self.B = self.A + lift * up
        self.D = self.E + lift * up
        self.C = (self.B + self.D) / 2 + arc * up
        self.t = (self.prof.lift_fraction * swing, self.prof.arc_fraction * swing,
                  self.prof.lower_fraction * swing, stance)
        shape = SwingShape(lift, arc, swing, self.prof)
        self.pw = step_cycle(self.center, stride * self.dir[:2], shape, stance)
        length = max(stride, lift + arc, 1e-3)
        self.tol_p = 1e-9 * max(length, float(np.abs(self.center).max()))
        t_min = min(self.t)
        self.tol_v = 1e-9 * length / t_min
        self.tol_a = 1e-9 * length / t_min**2
        # The documented junction speeds: ratio x mean vertical speed of the segment.
        self.v_b = self.prof.v_b * lift / self.t[0]
        self.v_d = -self.prof.v_d * lift / self.t[2]

    def ends(self, k: int) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        seg = self.pw.segments[k]
        start = tuple(x[0] for x in seg.evaluate(np.array([0.0])))
        end = tuple(x[0] for x in seg.evaluate(np.array([seg.duration])))
        return start, end

    def dense(self, k: int, n: int = 401) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        seg = self.pw.segments[k]
        return seg.evaluate(np.linspace(0.0, seg.duration, n))


HEADINGS = [0.0, math.pi / 4, math.pi / 2, math.pi, -2.5]
DEFAULT = {"stride": GAIT.stride, "lift": GAIT.lift, "arc": GAIT.arc, "swing": GAIT.swing_time,
           "stance": GAIT.swing_time}  # diagonal gait: stance = swing


def test_config_defaults_are_the_studys_step():
    assert (GAIT.stride, GAIT.lift, GAIT.arc, GAIT.swing_time) == (0.06, 0.01, 0.01, 0.6)


@pytest.mark.parametrize("profile", ["rest", "smooth"])
@pytest.mark.parametrize("heading", HEADINGS)
def test_step_cycle_key_points_and_time_split(profile, heading):
    s = Step(profile, heading=heading, **DEFAULT)
    assert s.pw.phases == PHASES
    np.testing.assert_allclose(s.pw.durations, s.t, rtol=1e-12)
    np.testing.assert_allclose(s.pw.breaks, np.concatenate(([0.0], np.cumsum(s.t))), rtol=1e-12)
    assert s.pw.t0 == 0.0
    points = (s.A, s.B, s.D, s.E, s.A)
    for k in range(4):
        start, end = s.ends(k)
        np.testing.assert_allclose(start[0], points[k], atol=s.tol_p)
        np.testing.assert_allclose(end[0], points[k + 1], atol=s.tol_p)
        np.testing.assert_allclose(s.pw.segments[k].start, points[k], atol=s.tol_p)
        np.testing.assert_allclose(s.pw.segments[k].end, points[k + 1], atol=s.tol_p)
    arc = s.pw.segments[1]
    np.testing.assert_allclose(arc.evaluate(np.array([arc.duration / 2]))[0][0], s.C,
                               atol=s.tol_p)
    # Closed cycle with the foot at rest at A and E.
    p0, v0, a0 = (x[0] for x in s.pw.evaluate(0.0))
    p1, v1, a1 = (x[0] for x in s.pw.evaluate(s.pw.t_end))
    np.testing.assert_allclose(p1, p0, atol=s.tol_p)
    np.testing.assert_allclose(p0, s.A, atol=s.tol_p)
    for v in (v0, v1, s.ends(2)[1][1], s.ends(3)[0][1]):
        np.testing.assert_allclose(v, 0.0, atol=s.tol_v)
    for a in (a0, a1, s.ends(2)[1][2], s.ends(3)[0][2]):
        np.testing.assert_allclose(a, 0.0, atol=s.tol_a)


def test_time_split_lift_fast_put_down_slowly():
    rest, smooth = PROFILES["rest"], PROFILES["smooth"]
    assert (rest.lift_fraction, rest.arc_fraction, rest.lower_fraction) == (0.25, 0.5, 0.25)
    assert (rest.v_b, rest.v_d) == (0.0, 0.0)
    assert smooth.lift_fraction < smooth.lower_fraction
    assert smooth.v_b > 0 and smooth.v_d > 0
    assert smooth.lift_fraction + smooth.arc_fraction + smooth.lower_fraction == pytest.approx(
        1.0, abs=1e-12)


@pytest.mark.parametrize("heading", HEADINGS)
def test_rest_profile_stops_at_every_junction(heading):
    s = Step("rest", heading=heading, **DEFAULT)
    for k in range(4):
        for _, v, a in s.ends(k):
            np.testing.assert_allclose(v, 0.0, atol=s.tol_v)
            np.testing.assert_allclose(a, 0.0, atol=s.tol_a)


def check_smooth_shape(s: Step) -> None:
    """The smooth profile's shape invariants (spec section 3)."""
    # C0, C1, C2 at every junction, including A (cycle closure) and E.
    for k in range(4):
        left = s.ends(k)[1]
        right = s.ends((k + 1) % 4)[0]
        for x, y, tol in zip(left, right, (s.tol_p, s.tol_v, s.tol_a), strict=True):
            np.testing.assert_allclose(x, y, atol=tol, err_msg=f"junction after segment {k}")
    # At B and D: the foot keeps moving vertically, horizontally still, a = 0.
    _, (b_pos, b_vel, b_acc) = s.ends(0)
    (d_pos, d_vel, d_acc), _ = s.ends(2)
    np.testing.assert_allclose(b_pos, s.B, atol=s.tol_p)
    np.testing.assert_allclose(d_pos, s.D, atol=s.tol_p)
    np.testing.assert_allclose(b_vel, [0.0, 0.0, s.v_b], atol=s.tol_v)
    np.testing.assert_allclose(d_vel, [0.0, 0.0, s.v_d], atol=s.tol_v)
    assert b_vel[2] > 0.0 and d_vel[2] < 0.0  # never stops at B or D
    assert abs(b_vel[2]) > 1e3 * s.tol_v and abs(d_vel[2]) > 1e3 * s.tol_v
    np.testing.assert_allclose(b_acc, 0.0, atol=s.tol_a)
    np.testing.assert_allclose(d_acc, 0.0, atol=s.tol_a)
    # z monotone on lift (up) and lower (down); z >= z_B on the arc.
    lift_p, lift_v, _ = s.dense(0)
    arc_p, arc_v, _ = s.dense(1)
    low_p, low_v, _ = s.dense(2)
    st_p, st_v, _ = s.dense(3)
    assert lift_v[:, 2].min() >= -s.tol_v
    assert np.diff(lift_p[:, 2]).min() >= -s.tol_p
    assert low_v[:, 2].max() <= s.tol_v
    assert np.diff(low_p[:, 2]).max() <= s.tol_p
    assert arc_p[:, 2].min() >= s.B[2] - s.tol_p, f"arc dips {s.B[2] - arc_p[:, 2].min():.3g} m"
    # Horizontal progress along the stride: monotone forward on the arc, backward on stance.
    assert (arc_v @ s.dir).min() >= -s.tol_v
    assert (st_v @ s.dir).max() <= s.tol_v
    # Lift and lower are vertical; the lateral coordinate never changes.
    for p in (lift_p, low_p):
        np.testing.assert_allclose(p[:, :2], np.broadcast_to(p[0, :2], p[:, :2].shape),
                                   atol=s.tol_p)
    for p in (lift_p, arc_p, low_p, st_p):
        np.testing.assert_allclose((p - s.center) @ s.perp, 0.0, atol=s.tol_p)
    # Stance on the ground.
    np.testing.assert_allclose(st_p[:, 2], s.center[2], atol=s.tol_p)


@pytest.mark.parametrize("heading", HEADINGS)
def test_smooth_profile_shape_at_defaults(heading):
    check_smooth_shape(Step("smooth", heading=heading, **DEFAULT))


def test_smooth_profile_is_smoother_than_rest():
    # The reason for the smooth profile: no stop at B/D, lower peak acceleration.
    peaks = {}
    for profile in ("rest", "smooth"):
        s = Step(profile, heading=0.0, **DEFAULT)
        acc = np.concatenate([s.dense(k)[2] for k in range(3)])
        peaks[profile] = np.linalg.norm(acc, axis=1).max()
    assert peaks["smooth"] < peaks["rest"]


# The smooth profile keeps z >= z_B on the arc only while the apex is high enough compared
# with the lift: the foot arrives at B moving up (v_b) and must pass the apex C at mid-arc, so
# with arc -> 0 it overshoots and comes back below z_B. For the configured profile
# (lift 0.213 / arc 0.521 / lower 0.266, v_b 0.5, v_d 1.377) the threshold is
# arc / lift ~= 0.0245; the property test below covers arc >= ARC_RATIO_MIN x lift.
ARC_RATIO_MIN = 0.05


@settings(max_examples=80, deadline=None)
@given(stride=st.floats(0.005, 0.08), lift=st.floats(0.003, 0.02), arc=st.floats(0.0, 0.02),
       swing=st.floats(0.2, 3.0), heading=st.floats(-math.pi, math.pi),
       stance_factor=st.sampled_from([1.0, 3.0, 0.5]))
def test_smooth_profile_shape_over_the_parameter_space(stride, lift, arc, swing, heading,
                                                       stance_factor):
    arc = max(arc, ARC_RATIO_MIN * lift)  # the documented valid region (see above)
    check_smooth_shape(Step("smooth", stride, heading, lift, arc, swing, stance_factor * swing))


@pytest.mark.xfail(strict=True, reason="known: with arc = 0 (allowed by validate_params) the "
                   "smooth arc dips below z_B by ~2.3 % of the lift")
def test_smooth_arc_without_apex_stays_above_b():
    check_smooth_shape(Step("smooth", 0.06, 0.0, 0.01, 0.0, 0.6, 0.6))


@FAST
@given(stride=st.floats(0.0, 0.08), heading=st.floats(-math.pi, math.pi),
       lift=st.floats(0.003, 0.02), arc=st.floats(0.0, 0.02), swing=st.floats(0.2, 3.0))
def test_rest_profile_shape_over_the_parameter_space(stride, heading, lift, arc, swing):
    s = Step("rest", stride, heading, lift, arc, swing, swing)
    for k in range(4):
        start, end = s.ends(k)
        for state in (start, end):
            np.testing.assert_allclose(state[1], 0.0, atol=s.tol_v)
            np.testing.assert_allclose(state[2], 0.0, atol=s.tol_a)
    lift_p = s.dense(0)[0]
    arc_p = s.dense(1)[0]
    low_p = s.dense(2)[0]
    assert np.diff(lift_p[:, 2]).min() >= -s.tol_p
    assert np.diff(low_p[:, 2]).max() <= s.tol_p
    assert arc_p[:, 2].min() >= s.B[2] - s.tol_p  # v = 0 at B and D: no dip, for any arc >= 0
    np.testing.assert_allclose(s.ends(1)[0][0], s.B, atol=s.tol_p)
    np.testing.assert_allclose(s.ends(2)[0][0], s.D, atol=s.tol_p)


def test_step_cycle_accepts_3d_stride_and_ignores_its_z():
    shape = SwingShape(0.01, 0.01, 0.6, PROFILES["smooth"])
    flat = step_cycle(CENTER, np.array([0.06, 0.01]), shape, 0.6)
    tilted = step_cycle(CENTER, np.array([0.06, 0.01, 0.5]), shape, 0.6)
    np.testing.assert_allclose(flat.coeffs, tilted.coeffs)
    np.testing.assert_allclose(flat.segments[3].end, CENTER - [0.03, 0.005, 0.0], atol=1e-12)


def test_zero_stride_is_a_step_in_place():
    s = Step("smooth", 0.0, 0.0, 0.01, 0.01, 0.6, 0.6)
    for k in range(4):
        p = s.dense(k)[0]
        np.testing.assert_allclose(p[:, :2], np.broadcast_to(CENTER[:2], p[:, :2].shape),
                                   atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.05, 2.0), st.lists(st.floats(0.01, 1.0), min_size=1, max_size=4),
       st.integers(0, 2**31 - 1))
def test_minus_path_is_the_difference_of_the_two_paths(duration, shares, seed):
    from crawler_motion.motion.trajectory import minus_path, rest_segment

    rng = np.random.default_rng(seed)
    path = rest_segment(rng.normal(size=3), rng.normal(size=3), duration)
    widths = np.array(shares) / sum(shares) * duration
    segments = [rest_segment(rng.normal(size=3), rng.normal(size=3), w) for w in widths]
    out = minus_path(segments, path)
    t0 = 0.0
    for seg, diff in zip(segments, out, strict=True):
        tau = np.linspace(0.0, seg.duration, 7)
        for k in range(3):  # position, velocity, acceleration
            expected = seg.evaluate(tau)[k] - path.evaluate(t0 + tau)[k]
            np.testing.assert_allclose(diff.evaluate(tau)[k], expected, atol=1e-9 / seg.duration
                                       ** k)
        t0 += seg.duration
