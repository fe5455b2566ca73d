"""Foot contact estimation from joint efforts: the hysteresis table, the statics, the drive
inertia, unknown inputs, and agreement with the seabed simulator's true contacts on recorded
effort traces (test/motion/data, written by
``python -m crawler_motion.sim.seabed.effort_trace``)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import foot_jacobians, inverse_kinematics
from crawler_motion.motion.contact_estimation import (
    MAX_GAP_PERIODS,
    SIDE_CONTACT_FACTOR,
    ContactEstimator,
    ContactSettings,
    FootContact,
    contact_state,
    foot_forces,
    mean_acceleration,
)
from crawler_motion.sim.seabed.effort_trace import load_trace

ROBOT = load_config().robot
STAND = inverse_kinematics(ROBOT, ROBOT.standing_feet())
DATA = Path(__file__).parent / "data"
#: A foot counts as truly loaded above this share of its part of the net weight (the
#: evaluator's LOAD_THRESHOLD, crawler_motion.sim.seabed.evaluate).
TRUE_LOAD_SHARE = 0.1
YES, NO, UNKNOWN = FootContact.YES, FootContact.NO, FootContact.UNKNOWN
S = ContactSettings(threshold=1.0, hysteresis=0.4)


@pytest.mark.parametrize(("previous", "force", "expected"), [
    (NO, 0.0, NO),
    (NO, 0.999, NO),
    (NO, 1.0, YES),  # touch-down exactly at the threshold
    (NO, 5.0, YES),
    (UNKNOWN, 0.999, NO),
    (UNKNOWN, 1.0, YES),
    (YES, 1.0, YES),
    (YES, 0.6, YES),  # lift-off level threshold - hysteresis still in contact
    (YES, 0.5999, NO),
    (YES, -3.0, NO),
    (NO, 0.6, NO),  # inside the band: the previous state holds
    (YES, 0.8, YES),
    (YES, math.nan, UNKNOWN),
    (NO, math.inf, UNKNOWN),
])
def test_hysteresis_table(previous, force, expected):
    assert contact_state(previous, force, S) is expected


@pytest.mark.parametrize(("kwargs", "ok"), [
    ({"threshold": 1e-6, "hysteresis": 0.0}, True),
    ({"threshold": 0.0}, False),
    ({"threshold": -1.0}, False),
    ({"threshold": math.nan}, False),
    ({"threshold": True}, False),
    ({"threshold": 1.0, "hysteresis": 1.0}, True),  # lift-off at 0 N
    ({"threshold": 1.0, "hysteresis": 1.0001}, False),
    ({"hysteresis": -0.1}, False),
    ({"drive_inertia": 0.0}, True),
    ({"drive_inertia": -1e-9}, False),
    ({"period": 1e-4}, True),
    ({"period": 0.0}, False),
])
def test_settings_are_checked(kwargs, ok):
    if ok:
        ContactSettings(**kwargs)
    else:
        with pytest.raises(ConfigError, match="contact"):
            ContactSettings(**kwargs)


def test_a_force_on_the_foot_is_recovered_from_the_drive_torques():
    force = np.array([[0.3, -0.2, 2.0], [0.0, 0.0, 4.0], [-1.0, 0.5, 1.0], [0.0, 0.0, 0.0]])
    tau = -np.einsum("lji,lj->li", foot_jacobians(ROBOT, STAND), force)  # tau = -J^T F
    np.testing.assert_allclose(foot_forces(ROBOT, STAND, tau), force, atol=1e-12)


def test_a_singular_leg_has_no_force():
    q = STAND.copy()
    q[2, 2] = 0.0  # rb knee straight: the Jacobian is singular
    forces = foot_forces(ROBOT, q, np.ones((4, 3)))
    assert np.isnan(forces[2]).all() and np.isfinite(np.delete(forces, 2, axis=0)).all()


@settings(max_examples=50, deadline=None)
@given(a=st.floats(-50, 50), b=st.floats(-5, 5), t0=st.floats(0, 100))
def test_the_mean_acceleration_of_a_parabola_is_exact(a, b, t0):
    t = t0 + 0.01 * np.arange(4)
    q = 0.5 * a * (t - t0) ** 2 + b * (t - t0)
    assert mean_acceleration(t, q) == pytest.approx(a, abs=1e-6 * (1 + abs(a)))


def feed(est: ContactEstimator, stamps, angles, efforts):
    return [est.update(t, q, e) for t, q, e in zip(stamps, angles, efforts, strict=True)]


def standing_effort(force_z: float) -> np.ndarray:
    """Drive torques holding ``force_z`` [N] up on every foot of the standing pose."""
    force = np.zeros((4, 3))
    force[:, 2] = force_z
    return -np.einsum("lji,lj->li", foot_jacobians(ROBOT, STAND), force).reshape(-1)


def test_an_estimate_describes_the_sample_before_the_newest():
    est = ContactEstimator(ROBOT)
    stamps = 0.01 * np.arange(6)
    out = feed(est, stamps, [STAND] * 6, [standing_effort(2.0)] * 6)
    assert [o.states for o in out[:3]] == [(UNKNOWN,) * 4] * 3  # four samples needed
    assert out[3].stamp == pytest.approx(stamps[2])
    assert out[5].states == (YES,) * 4
    np.testing.assert_allclose(out[5].normal_forces, 2.0, atol=1e-9)
    assert out[5].reason == ""


def test_missing_efforts_make_every_contact_unknown_never_zero():
    est = ContactEstimator(ROBOT)
    efforts = [standing_effort(2.0)] * 4 + [np.empty(0), None, np.empty(0)] + [
        standing_effort(2.0)] * 2
    out = feed(est, 0.01 * np.arange(9), [STAND] * 9, efforts)
    assert out[3].states == (YES,) * 4
    for o in out[5:8]:  # the samples 4..6 without efforts
        assert o.states == (UNKNOWN,) * 4 and np.isnan(o.normal_forces).all()
        assert "no effort" in o.reason
    assert out[8].states == (YES,) * 4  # back as soon as efforts are


def test_a_nan_effort_makes_only_its_leg_unknown():
    est = ContactEstimator(ROBOT)
    tau = standing_effort(2.0)
    bad = tau.copy()
    bad[4] = np.nan  # lb shoulder
    out = feed(est, 0.01 * np.arange(4), [STAND] * 4, [tau, tau, bad, tau])
    assert out[3].states == (YES, UNKNOWN, YES, YES)
    assert "lb" in out[3].reason


@pytest.mark.parametrize(("gap_periods", "restarts"), [
    (1, False), (2, False), (MAX_GAP_PERIODS, False), (MAX_GAP_PERIODS + 1, True),
    (0, True), (-1, True),
])
def test_a_gap_in_the_samples_restarts_the_history(gap_periods, restarts):
    est = ContactEstimator(ROBOT)
    stamps = [*(0.01 * np.arange(4)), 0.03 + 0.01 * gap_periods]
    out = feed(est, stamps, [STAND] * 5, [standing_effort(2.0)] * 5)
    assert (out[4].states == (UNKNOWN,) * 4) == restarts


def test_stamp_jitter_is_taken_out_by_the_period():
    est = ContactEstimator(ROBOT)
    n = 8
    stamps = 0.01 * np.arange(n) + np.array([0, 0.002, -0.002, 0.003, 0, -0.003, 0.001, 0])
    t = 0.01 * np.arange(n)
    q = np.repeat(STAND[None], n, axis=0)
    q[:, 0, 1] += 0.5 * 40.0 * t**2  # lf shoulder accelerating at 40 rad/s²
    tau = np.array([standing_effort(2.0)] * n)
    tau[:, 1] += 0.005 * 40.0  # the drive accelerating its rotor
    out = feed(est, stamps, q, tau)
    np.testing.assert_allclose(out[-1].forces[0, 2], foot_forces(ROBOT, q[-2], tau[-2].reshape(
        4, 3) - np.array([0, 0.2, 0]))[0, 2], atol=1e-9)
    assert out[-1].normal_forces[1:] == pytest.approx([2.0] * 3, abs=1e-9)


def test_the_drive_inertia_is_removed_before_the_foot_force():
    n = 6
    t = 0.01 * np.arange(n)
    q = np.repeat(STAND[None], n, axis=0)
    q[:, :, 2] += 0.5 * 30.0 * t[:, None] ** 2  # every knee accelerating at 30 rad/s²
    tau = np.zeros((n, 12))
    tau[:, 2::3] = 0.005 * 30.0  # only the rotors: no ground force
    free = feed(ContactEstimator(ROBOT), t, q, tau)[-1]
    assert free.states == (NO,) * 4
    np.testing.assert_allclose(free.forces, 0.0, atol=1e-9)
    blind = feed(ContactEstimator(ROBOT, ContactSettings(drive_inertia=0.0)), t, q, tau)[-1]
    assert np.abs(blind.forces).max() > 1.0  # the rotor torque read as a foot force


def test_a_sideways_push_is_contact():
    jac = foot_jacobians(ROBOT, STAND)
    side = SIDE_CONTACT_FACTOR * 0.75
    force = np.array([[side, 0.0, 0.0], [side * 0.99, 0.0, 0.0], [0, 0, 0.75], [0, 0, 0.74]])
    tau = -np.einsum("lji,lj->li", jac, force).reshape(-1)
    out = feed(ContactEstimator(ROBOT), 0.01 * np.arange(4), [STAND] * 4, [tau] * 4)[-1]
    assert out.states == (YES, NO, YES, NO)
    np.testing.assert_allclose(out.normal_forces, [0, 0, 0.75, 0.74], atol=1e-9)


def estimate_trace(path: Path, contact: ContactSettings | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(estimated, true) contact flags of the known samples of a recorded trace."""
    trace = load_trace(path)
    est = ContactEstimator(ROBOT, contact)
    index = {round(float(t) / 0.01): k for k, t in enumerate(trace.time)}
    truth = trace.loads > TRUE_LOAD_SHARE * trace.net_weight / ROBOT.n_legs
    got, want = [], []
    for t, q, tau in zip(trace.time, trace.positions, trace.efforts, strict=True):
        out = est.update(float(t), q, tau)
        if FootContact.UNKNOWN in out.states:
            continue
        got.append([s is YES for s in out.states])
        want.append(truth[index[round(out.stamp / 0.01)]])
    return np.array(got), np.array(want)


TRACES = sorted(DATA.glob("effort_*.npz"))


def test_the_traces_are_there():
    assert {p.stem for p in TRACES} >= {"effort_diagonal_flat", "effort_wave_flat",
                                        "effort_diagonal_step", "effort_wave_step"}
    assert sum(p.stat().st_size for p in TRACES) < 400_000


@pytest.mark.parametrize("path", TRACES, ids=lambda p: p.stem)
def test_contacts_agree_with_the_simulator_on_recorded_traces(path):
    got, want = estimate_trace(path)
    assert len(got) >= len(load_trace(path).time) - 3  # only the first samples unknown
    agreement = (got == want).mean()
    print(f"{path.stem}: contact agreement {agreement:.4f} over {got.size} foot samples")
    assert agreement >= 0.95
    assert want.mean() > 0.5 and (~want).mean() > 0.1  # the trace has stance and swing


def test_the_agreement_check_can_fail():
    got, want = estimate_trace(TRACES[0], ContactSettings(threshold=20.0, hysteresis=0.0))
    assert (got == want).mean() < 0.95  # a threshold above every foot load: never contact
