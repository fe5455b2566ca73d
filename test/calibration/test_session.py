"""A session's identification against an independent truth: the package's URDF with every
joint frame perturbed in all six components and every joint zero offset, evaluated here by
homogeneous transforms of the URDF's own numbers (not the model's chain). Body frame, the
tracker's frame (its pose recovered), outliers, identifiability refusals.

``RIGID_DRAWS`` (environment, default 2) sets the random robots per case; ``make
calibration-figures`` runs 50 and prints the figures (``-s``)."""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from crawler_motion.calibration import session
from crawler_motion.calibration.readings import Readings
from crawler_motion.errors import CalibrationError
from crawler_motion.model.calibration_file import nominal_calibration, write_calibration
from crawler_motion.model.config import load_config
from crawler_motion.model.leg_geometry import nominal_params
from crawler_motion.model.urdf import generate_urdf
from crawler_motion.tools import cli

ROBOT = load_config().robot
NOMINAL = np.tile(nominal_params(ROBOT.l1, ROBOT.l2, ROBOT.l3), (ROBOT.n_legs, 1))
DRAWS = int(os.environ.get("RIGID_DRAWS", "2"))
KINDS = ("root", "shoulder", "knee", "foot")


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx


def _frame(xyz: np.ndarray, rpy: np.ndarray) -> np.ndarray:
    """URDF origin: translation xyz, rotation Rz(yaw) Ry(pitch) Rx(roll)."""
    out = np.eye(4)
    out[:3, :3] = (_rot([0, 0, 1], rpy[2]) @ _rot([0, 1, 0], rpy[1])
                   @ _rot([1, 0, 0], rpy[0]))
    out[:3, 3] = xyz
    return out


@dataclass
class UrdfLeg:
    """One leg's joints as the URDF states them: origins xyz, rpy ``(4, 3)``, axes ``(3, 3)``
    of the revolute ones, and joint zero offsets ``(3,)`` [rad] added to the commands."""

    xyz: np.ndarray
    rpy: np.ndarray
    axes: np.ndarray
    zeros: np.ndarray

    def fixed(self, j: int) -> np.ndarray:
        return _frame(self.xyz[j], self.rpy[j])

    def frames(self, q: np.ndarray) -> list[np.ndarray]:
        """World transforms of the joint frames (after their rotation) and the foot at the
        commanded angles ``q`` ``(3,)``."""
        out, world = [], np.eye(4)
        for j in range(4):
            world = world @ self.fixed(j)
            if j < 3:
                turn = np.eye(4)
                turn[:3, :3] = _rot(self.axes[j], q[j] + self.zeros[j])
                world = world @ turn
            out.append(world)
        return out

    def feet(self, q: np.ndarray) -> np.ndarray:
        return np.array([self.frames(row)[3][:3, 3] for row in q])


def urdf_legs(text: str | None = None) -> dict[str, UrdfLeg]:
    """The legs of the URDF ``text`` (default: the nominal robot's)."""
    root = ET.fromstring(text if text is not None else generate_urdf(ROBOT))
    legs = {}
    for leg in ROBOT.legs:
        joints = [root.find(f"joint[@name='{leg}_{kind}_joint']") for kind in KINDS]
        xyz = np.array([[float(v) for v in j.find("origin").get("xyz").split()] for j in joints])
        rpy = np.array([[float(v) for v in j.find("origin").get("rpy").split()] for j in joints])
        axes = np.array([[float(v) for v in j.find("axis").get("xyz").split()]
                         for j in joints[:3]])
        legs[leg] = UrdfLeg(xyz, rpy, axes, np.zeros(3))
    return legs


def perturbed(rng: np.random.Generator) -> dict[str, UrdfLeg]:
    """Every joint frame: xyz by 0.5-1 mm, rpy by 0.2-0.5 deg (each component, random sign);
    every joint zero by 0.3-0.8 deg."""
    def signed(low: float, high: float, shape: tuple[int, ...]) -> np.ndarray:
        return rng.choice((-1.0, 1.0), shape) * rng.uniform(low, high, shape)
    out = {}
    for name, leg in urdf_legs().items():
        out[name] = UrdfLeg(leg.xyz + signed(0.5e-3, 1e-3, (4, 3)),
                            leg.rpy + signed(math.radians(0.2), math.radians(0.5), (4, 3)),
                            leg.axes, signed(math.radians(0.3), math.radians(0.8), (3,)))
    return out


def _poses(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform(ROBOT.lower, ROBOT.upper, (n, 3))


def readings_of(truth: dict[str, UrdfLeg], legs: tuple[int, ...], n: int,
                rng: np.random.Generator, noise: float,
                tracker: np.ndarray | None = None) -> Readings:
    """``n`` readings per leg at uniform poses; in the tracker's frame when its pose (4x4, in
    base_link) is given."""
    index = np.repeat(np.array(legs), n)
    q = _poses(rng, n * len(legs))
    points = np.concatenate([truth[ROBOT.legs[leg]].feet(q[index == leg]) for leg in legs])
    if tracker is not None:
        points = (points - tracker[:3, 3]) @ tracker[:3, :3]
    points = points + rng.normal(0.0, noise, points.shape)
    return Readings(index, q, points, np.arange(2, len(q) + 2))


def datum(leg: UrdfLeg) -> np.ndarray:
    """The frame (4x4) the model's root parameters describe: origin where the common normal of
    the root and shoulder axes meets the root axis, z along the root axis, x along the normal
    (at the commanded zero)."""
    root = leg.frames(np.zeros(3))[0]
    shoulder = root @ leg.fixed(1)
    a, o = root[:3, :3] @ leg.axes[0], root[:3, 3]
    b, s = shoulder[:3, :3] @ leg.axes[1], shoulder[:3, 3]
    c, w = a @ b, o - s
    lam = (c * (b @ w) - a @ w) / (1 - c * c)
    mu = ((b @ w) - c * (a @ w)) / (1 - c * c)
    p, x = o + lam * a, s + mu * b - (o + lam * a)
    out = np.eye(4)
    x = x / np.linalg.norm(x)
    out[:3, :3] = np.column_stack((x, np.cross(a, x), a))
    out[:3, 3] = p
    return out


def root_parameters(frame: np.ndarray, nominal: np.ndarray) -> np.ndarray:
    """hip_x, hip_y, hip_z, root_tilt_x, root_tilt_y, root_offset of a `datum` frame (4x4,
    base_link) relative to its nominal one: ``nominal^-1 frame = Trans(hip) Rx Ry Rz``."""
    local = np.linalg.inv(nominal) @ frame
    r = local[:3, :3]
    return np.array([*local[:3, 3], math.atan2(-r[1, 2], r[2, 2]), math.asin(r[0, 2]),
                     math.atan2(-r[0, 1], r[0, 0])])


def gauge_of(truth: dict[str, UrdfLeg]) -> np.ndarray:
    """The transform (4x4) from the true base_link to the frame the tracker session defines:
    the one whose root parameters of all legs satisfy `session.gauge_constraints` (Newton on
    the six components of a small rigid motion, numerical derivatives)."""
    nominal = urdf_legs()
    constraint = session.gauge_constraints(ROBOT, tuple(range(ROBOT.n_legs)))
    frames = [(datum(truth[leg]), datum(nominal[leg])) for leg in ROBOT.legs]

    def residual(g: np.ndarray) -> np.ndarray:
        return constraint @ np.concatenate([root_parameters(g @ f, n) for f, n in frames])

    def moved(g: np.ndarray, twist: np.ndarray) -> np.ndarray:
        step = np.eye(4)
        step[:3, :3] = _rot(twist[:3], np.linalg.norm(twist[:3])) if twist[:3].any() else step[
            :3, :3]
        step[:3, 3] = twist[3:]
        return step @ g

    g = np.eye(4)
    for _ in range(8):
        f0 = residual(g)
        jac = np.column_stack([(residual(moved(g, 1e-7 * e)) - f0) / 1e-7 for e in np.eye(6)])
        g = moved(g, -np.linalg.solve(jac, f0))
    assert np.abs(residual(g)).max() < 1e-12
    return g


def validate(state: session.State, truth: dict[str, UrdfLeg], legs: tuple[int, ...],
             rng: np.random.Generator, gauge: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    """Foot errors [m] on 100 unseen poses per leg: identified and nominal legs."""
    from crawler_motion.calibration.jacobian import leg_feet
    after, before = [], []
    for leg in legs:
        q = _poses(rng, 100)
        feet = truth[ROBOT.legs[leg]].feet(q)
        if gauge is not None:
            feet = feet @ gauge[:3, :3].T + gauge[:3, 3]
        after.append(np.linalg.norm(leg_feet(ROBOT, leg, state.params[leg], q) - feet, axis=-1))
        before.append(np.linalg.norm(leg_feet(ROBOT, leg, NOMINAL[leg], q) - feet, axis=-1))
    return np.concatenate(after), np.concatenate(before)


def _tracker_pose(rng: np.random.Generator) -> np.ndarray:
    """A tracker 1-3 m from the body at an arbitrary orientation (4x4, in base_link)."""
    out = np.eye(4)
    out[:3, :3] = _rot(rng.normal(size=3), rng.uniform(0.0, math.pi))
    d = rng.normal(size=3)
    out[:3, 3] = d / np.linalg.norm(d) * rng.uniform(1.0, 3.0)
    return out


def _report(name: str, values: list[float]) -> str:
    return f"{name}: mean {np.mean(values):.3g}, max {np.max(values):.3g}"


@pytest.mark.parametrize(("noise", "mean_bound"), [(0.0, 1e-6), (2e-5, 3e-5)])
def test_body_frame_identification_absorbs_rigid_joint_frame_errors(noise: float,
                                                                    mean_bound: float) -> None:
    """Every leg, ``DRAWS`` random robots: 50 identification poses, 100 unseen ones."""
    means, maxes, gains = [], [], []
    for draw in range(DRAWS):
        for leg in range(ROBOT.n_legs):
            rng = np.random.default_rng(1000 * draw + leg)
            truth = perturbed(rng)
            fit = session.robust_fit(ROBOT, readings_of(truth, (leg,), 50, rng, noise), NOMINAL,
                                     np.zeros(3), tracker=False)
            after, before = validate(fit.state, truth, (leg,), rng)
            assert not fit.outliers.any()
            means.append(after.mean())
            maxes.append(after.max())
            gains.append(1.0 - after.mean() / before.mean())
            assert before.mean() > 1e-3  # millimetres before calibration
    print(f"\nbody frame, noise {noise * 1e3:g} mm, {DRAWS} draws x {ROBOT.n_legs} legs [mm]: "
          f"{_report('validation mean', [m * 1e3 for m in means])}; max "
          f"{np.max(maxes) * 1e3:.3g}; better than uncalibrated by at least "
          f"{min(gains):.2%}")
    assert np.mean(means) < mean_bound and min(gains) >= 0.98


@pytest.mark.parametrize(("noise", "mean_bound"), [(0.0, 1e-6), (2e-5, 3e-5)])
def test_tracker_frame_identifies_the_tracker_pose_with_every_leg(noise: float,
                                                                 mean_bound: float) -> None:
    """Four legs read in the tracker's frame. base_link is then defined by the legs' roots
    (`session.gauge_constraints`), so the truth is compared in that frame: ``gauge`` takes
    the true base_link to it (from the URDF's axis lines, not from the model's chain)."""
    means, moves, turns, gains = [], [], [], []
    for draw in range(DRAWS):
        rng = np.random.default_rng(500 + draw)
        truth, tracker = perturbed(rng), _tracker_pose(rng)
        fit = session.robust_fit(ROBOT, readings_of(truth, (0, 1, 2, 3), 50, rng, noise,
                                                    tracker), NOMINAL, np.zeros(3), tracker=True)
        gauge = gauge_of(truth)
        want = gauge @ tracker
        moves.append(float(np.linalg.norm(fit.state.translation - want[:3, 3])))
        cos = (np.trace(fit.state.rotation.T @ want[:3, :3]) - 1.0) / 2.0
        turns.append(math.degrees(math.acos(min(1.0, cos))))
        after, before = validate(fit.state, truth, (0, 1, 2, 3), rng, gauge)
        means.append(after.mean())
        gains.append(1.0 - after.mean() / before.mean())
        assert fit.layout.size == 6 + 4 * 15 - 6
    print(f"\ntracker frame, noise {noise * 1e3:g} mm, {DRAWS} draws [mm, deg]: "
          f"{_report('validation mean', [m * 1e3 for m in means])}; "
          f"{_report('tracker position error', [m * 1e3 for m in moves])}; "
          f"{_report('tracker angle error', turns)}; better than uncalibrated by at least "
          f"{min(gains):.2%}")
    assert np.mean(means) < mean_bound and min(gains) >= 0.98
    if noise == 0.0:
        assert max(moves) < 1e-5 and max(turns) < 1e-3


def test_outliers_are_flagged_by_row_and_do_not_move_the_result() -> None:
    """3 readings of 50 moved by 5-50 mm (``DRAWS`` robots, 0.02 mm noise): exactly those rows
    are flagged; the result is the least-squares one of the 47 good readings (the outliers
    have no influence left), and its validation error is on average within 10 % of the
    identification from all 50 readings uncorrupted (single draws scatter more: three fewer
    poses, e.g. 1.41 at most of 50 draws)."""
    ratios = []
    for draw in range(DRAWS):
        rng = np.random.default_rng(42 + draw)
        leg = draw % ROBOT.n_legs
        truth = perturbed(rng)
        clean = readings_of(truth, (leg,), 50, rng, 2e-5)
        bad = np.zeros(50, dtype=bool)
        bad[rng.choice(50, 3, replace=False)] = True
        points = clean.points.copy()
        for row, size in zip(np.flatnonzero(bad), rng.uniform(5e-3, 50e-3, 3), strict=True):
            direction = rng.normal(size=3)
            points[row] += size * direction / np.linalg.norm(direction)
        dirty = Readings(clean.legs, clean.q, points, clean.lines)
        fits = [session.robust_fit(ROBOT, readings, NOMINAL, np.zeros(3), tracker=False)
                for readings in (clean, dirty, clean.subset(~bad))]
        assert list(dirty.lines[fits[1].outliers]) == list(clean.lines[bad])
        np.testing.assert_allclose(fits[1].state.params, fits[2].state.params, atol=1e-12)
        errors = [validate(fit.state, truth, (leg,), np.random.default_rng(0))[0].mean()
                  for fit in fits[:2]]
        ratios.append(errors[1] / errors[0])
    print(f"\noutliers, {DRAWS} draws: validation mean with / without them: "
          f"{_report('ratio', ratios)}")
    assert np.mean(ratios) <= 1.1


@pytest.mark.parametrize(("poses", "message"), [
    ("knee fixed", "unidentifiable"),
    ("four", "4 poses, fewer than its 15 identifiable parameters need"),
])
def test_poses_that_leave_a_parameter_unidentifiable_are_refused(poses: str,
                                                                 message: str) -> None:
    rng = np.random.default_rng(3)
    readings = readings_of(perturbed(rng), (0,), 50 if poses == "knee fixed" else 4, rng, 0.0)
    if poses == "knee fixed":
        readings.q[:, 2] = 1.0
    with pytest.raises(CalibrationError, match=message):
        session.robust_fit(ROBOT, readings, NOMINAL, np.zeros(3), tracker=False)


def test_a_session_that_fits_no_single_tracker_pose_is_refused() -> None:
    """The tracker moved by 5 mm half-way through every leg's readings: refused, naming a
    row. (Had it moved between legs, their roots would absorb it: not detectable.)"""
    rng = np.random.default_rng(9)
    truth, tracker = perturbed(rng), _tracker_pose(rng)
    moved = tracker.copy()
    moved[:3, 3] += 5e-3
    parts = [readings_of(truth, (0, 1, 2, 3), 10, rng, 2e-5, pose) for pose in (tracker, moved)]
    both = Readings(*(np.concatenate((getattr(parts[0], f), getattr(parts[1], f)))
                      for f in ("legs", "q", "points")), np.arange(2, 82))
    fit = session.robust_fit(ROBOT, both, NOMINAL, np.zeros(3), tracker=True)
    with pytest.raises(CalibrationError, match=r"m\.csv line \d+: the readings do not fit"):
        session.check_fit(fit, both, 1e-4, "m.csv")
    good = session.robust_fit(ROBOT, parts[0], NOMINAL, np.zeros(3), tracker=True)
    session.check_fit(good, parts[0], 1e-4, "m.csv")


def test_urdf_of_the_identified_legs_is_the_true_robot(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """``crawler-motion urdf --calibration FILE`` of the identified legs, evaluated here like
    the truth, puts every foot where the perturbed URDF does (noise-free readings)."""
    rng = np.random.default_rng(77)
    truth = perturbed(rng)
    fit = session.robust_fit(ROBOT, readings_of(truth, (0, 1, 2, 3), 50, rng, 0.0), NOMINAL,
                             np.zeros(3), tracker=False)
    calib = nominal_calibration(ROBOT.legs, (ROBOT.l1, ROBOT.l2, ROBOT.l3))
    for leg in range(ROBOT.n_legs):
        calib = calib.with_leg(ROBOT.legs[leg], fit.state.params[leg])
    write_calibration(tmp_path / "legs.yaml", calib)
    capsys.readouterr()
    assert cli.main(["urdf", "--calibration", str(tmp_path / "legs.yaml")]) == 0
    identified = urdf_legs(capsys.readouterr().out)
    q = _poses(rng, 100)
    for leg in ROBOT.legs:
        assert np.abs(identified[leg].feet(q) - truth[leg].feet(q)).max() < 1e-9


@pytest.mark.parametrize("tracker", [False, True])
def test_target_offset_gives_the_foot_tip(tracker: bool) -> None:
    """Readings of a target beside the foot tip, identified with its offset, give the legs
    identified from readings of the foot tip itself (two legs; the truth is the model's chain
    here: this checks the offset's bookkeeping). The offset is in the frame whose x runs from
    the knee axis to the foot tip (foot_z = 0: the frame the identification keeps)."""
    from crawler_motion.calibration.jacobian import leg_feet
    from crawler_motion.calibration.synthetic import perturbed_robot
    from crawler_motion.model.leg_geometry import INDEX
    true = perturbed_robot(ROBOT, 12).geometry
    assert true is not None
    true.params[:, INDEX["foot_z"]] = 0.0
    offset = np.array([0.004, 0.008, -0.003])
    rng = np.random.default_rng(12)
    legs = np.repeat(np.array([0, 1]), 40)
    q = _poses(rng, 80)
    fits = []
    for shift in (offset, np.zeros(3)):
        params = true.params.copy()
        params[:, list(session.TIP)] += shift
        points = np.array([leg_feet(ROBOT, int(leg), params[leg], row)
                           for leg, row in zip(legs, q, strict=True)])
        if tracker:
            points = (points - np.array([1.0, -2.0, 0.5])) @ _rot([1, 2, 3], 2.0)
        fits.append(session.robust_fit(ROBOT, Readings(legs, q, points, np.arange(2, 82)),
                                       NOMINAL, shift, tracker=tracker))
    np.testing.assert_allclose(fits[0].state.params, fits[1].state.params, atol=1e-10)
    if not tracker:
        np.testing.assert_allclose(fits[1].state.params[:2, list(session.TIP)[:2]],
                                   true.params[:2, list(session.TIP)[:2]], atol=1e-10)
