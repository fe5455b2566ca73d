"""The pose of a scan: interpolated between the odometry samples around its stamp, a scan ahead
of the odometry held until the odometry reaches it, the rest skipped with counted reasons."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.mapping.mapper import (
    MapperSettings,
    Pose,
    ScanFate,
    SkipReason,
    TerrainMapper,
    interpolate_pose,
)
from crawler_motion.mapping.points import Mount, returns_in_map
from crawler_motion.model.rotations import rpy_matrix

BODY_Z = 0.07
POINTS = np.array([[0.5, 0.0, 0.0], [0.6, 0.1, 0.0]])
# dyadic stamps [s] (exact in binary): a gap of 0.5 s between 0.5 and 1.0
STAMPS = (0.0, 0.25, 0.5, 1.0)
TOL = 0.125  # pose_tolerance [s]: pairs up to 0.25 s apart are interpolated


def sample(stamp: float) -> Pose:
    """A distinct pose per stamp: x = stamp, pitch = 0.2 stamp [rad]."""
    return Pose(stamp, rpy_matrix(np.array([0.0, 0.2 * stamp, 0.0])),
                np.array([stamp, 0.0, BODY_Z]))


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Angle [rad] of the rotation taking ``a`` to ``b``."""
    return math.acos(max(-1.0, min(1.0, (np.trace(a.T @ b) - 1.0) / 2.0)))


def mapper_with(stamps: tuple[float, ...] = STAMPS, **kw: float) -> TerrainMapper:
    mapper = TerrainMapper(MapperSettings(pose_tolerance=TOL, odom_window=2.0, **kw),
                           Mount(np.eye(3), np.zeros(3)))
    for t in stamps:
        assert mapper.add_odometry(sample(t)) is None
    return mapper


@pytest.mark.parametrize("stamp, outcome, pose", [
    (0.0, ScanFate.FUSED, 0),  # the oldest sample's stamp: that sample
    (0.25, ScanFate.FUSED, 1),  # exactly at a sample: that sample, not an interpolation
    (0.125, ScanFate.FUSED, (0, 1)),  # between two: interpolated
    (0.5, ScanFate.FUSED, 2),  # at a sample next to a gap: that sample
    (0.75, SkipReason.ODOMETRY_GAP, SkipReason.ODOMETRY_GAP),  # pair 0.5 s > 2 tol apart
    (1.0, ScanFate.FUSED, 3),  # the newest
    (-0.001, SkipReason.STALE, SkipReason.STALE),  # older than the odometry kept
    (1.0001, ScanFate.HELD, SkipReason.AHEAD_OF_ODOMETRY),  # just ahead of the newest
    (1.125, ScanFate.HELD, SkipReason.AHEAD_OF_ODOMETRY),  # ahead by exactly the tolerance
    (1.1251, SkipReason.AHEAD_OF_ODOMETRY, SkipReason.AHEAD_OF_ODOMETRY),  # ahead by more
    (math.nan, SkipReason.BAD_STAMP, SkipReason.BAD_STAMP),  # never held: it would block
    (math.inf, SkipReason.BAD_STAMP, SkipReason.BAD_STAMP),
])
def test_a_scan_s_pose_by_its_stamp(stamp: float, outcome: ScanFate | SkipReason,
                                    pose: int | tuple[int, int] | SkipReason) -> None:
    mapper = mapper_with()
    assert mapper.add_scan(POINTS, stamp) is outcome
    fused = outcome is ScanFate.FUSED
    assert mapper.scans_fused == int(fused)
    assert mapper.held == int(outcome is ScanFate.HELD)
    assert dict(mapper.skipped) == ({outcome: 1} if isinstance(outcome, SkipReason) else {})
    found = mapper.pose_at(stamp)
    if isinstance(pose, int):
        assert found is mapper._poses[pose]
    elif isinstance(pose, tuple):
        a, b = (sample(STAMPS[i]) for i in pose)
        assert isinstance(found, Pose) and found.stamp == stamp
        np.testing.assert_allclose(found.position, (a.position + b.position) / 2, atol=1e-12)
        np.testing.assert_allclose(found.rotation, sample(stamp).rotation,
                                   atol=1e-12)  # about one axis the angle is linear in time
    else:
        assert found is pose


def test_no_odometry_yet() -> None:
    mapper = mapper_with(())
    assert mapper.add_scan(POINTS, 0.0) is SkipReason.NO_ODOMETRY
    assert mapper.pose_at(0.0) is SkipReason.NO_ODOMETRY and mapper.held == 0


def test_a_held_scan_is_released_by_odometry_at_or_after_its_stamp() -> None:
    mapper = mapper_with()
    assert mapper.add_scan(POINTS, 1.1) is ScanFate.HELD
    assert mapper.add_odometry(sample(1.0625)) is None  # before its stamp: still held
    assert mapper.held == 1 and mapper.scans_fused == 0
    assert mapper.add_odometry(sample(1.25)) is None  # after it: fused
    assert mapper.held == 0 and mapper.scans_fused == 1 and not mapper.skipped
    # the same map as if the odometry had come first (the arrival order does not matter)
    first = mapper_with((*STAMPS, 1.0625, 1.25))
    assert first.add_scan(POINTS, 1.1) is ScanFate.FUSED
    np.testing.assert_array_equal(mapper.grid.height, first.grid.height)
    np.testing.assert_array_equal(mapper.grid.variance, first.grid.variance)
    assert mapper.grid.known.sum() == 2


def test_held_scans_are_released_in_stamp_order_and_at_an_exact_stamp() -> None:
    mapper = mapper_with()
    assert mapper.add_scan(POINTS, 1.125) is ScanFate.HELD
    assert mapper.add_scan(POINTS, 1.0625) is ScanFate.HELD  # arrives after a newer one
    assert mapper.add_odometry(sample(1.0625)) is None  # reaches the second one exactly
    assert mapper.held == 1 and mapper.scans_fused == 1
    assert mapper.add_odometry(sample(1.125)) is None
    assert mapper.held == 0 and mapper.scans_fused == 2 and not mapper.skipped


def test_queue_overflow_drops_the_oldest_held_scan_and_counts_it() -> None:
    mapper = mapper_with(scan_queue=2)
    assert mapper.add_scan(POINTS, 1.03125) is ScanFate.HELD
    assert mapper.add_scan(POINTS, 1.0625) is ScanFate.HELD
    assert mapper.add_scan(POINTS, 1.09375) is ScanFate.HELD  # drops the one at 1.03125
    assert mapper.held == 2 and dict(mapper.skipped) == {SkipReason.QUEUE_FULL: 1}
    assert mapper.add_scan(POINTS, 1.015625) is SkipReason.QUEUE_FULL  # older than those held
    assert mapper.add_odometry(sample(1.125)) is None
    assert mapper.scans_fused == 2 and mapper.held == 0
    assert dict(mapper.skipped) == {SkipReason.QUEUE_FULL: 2}


def test_without_a_queue_a_scan_ahead_is_dropped() -> None:
    mapper = mapper_with(scan_queue=0)
    assert mapper.add_scan(POINTS, 1.0625) is SkipReason.QUEUE_FULL
    assert mapper.held == 0


def test_a_held_scan_across_an_odometry_outage_is_skipped_when_the_odometry_returns() -> None:
    mapper = mapper_with()
    assert mapper.add_scan(POINTS, 1.0625) is ScanFate.HELD
    assert mapper.add_odometry(sample(1.5)) is None  # 0.5 s later: not interpolated across
    assert mapper.held == 0 and mapper.scans_fused == 0
    assert dict(mapper.skipped) == {SkipReason.ODOMETRY_GAP: 1}


def test_a_held_scan_older_than_the_window_when_released_is_stale() -> None:
    mapper = mapper_with()
    assert mapper.add_scan(POINTS, 1.0625) is ScanFate.HELD
    assert mapper.add_odometry(sample(3.5)) is None  # the window (2 s) drops 1.0
    assert dict(mapper.skipped) == {SkipReason.STALE: 1} and mapper.held == 0


events = st.lists(st.tuples(st.booleans(), st.integers(0, 40)), max_size=60)


@given(events)
@settings(max_examples=100, deadline=None)
def test_every_scan_ends_fused_skipped_or_held(seq: list[tuple[bool, int]]) -> None:
    mapper = mapper_with((), scan_queue=3)
    scans = 0
    for is_scan, tick in seq:  # stamps on a 1/64 s grid, odometry and scans interleaved
        t = tick / 64.0
        if is_scan:
            scans += 1
            mapper.add_scan(POINTS, t)
        else:
            mapper.add_odometry(sample(t))  # refusals counted apart (odometry_refused)
        assert mapper.held <= 3
    scan_skips = sum(mapper.skipped.values()) - mapper.skipped[SkipReason.NON_FINITE_POINTS]
    assert mapper.scans_fused + scan_skips + mapper.held == scans


poses = st.tuples(*[st.floats(-3.0, 3.0)] * 3, *[st.floats(-1.0, 1.0)] * 3)


@given(poses, poses, st.floats(0.0, 1.0), st.floats(0.001, 0.1))
def test_the_interpolated_pose_lies_between_its_neighbours(a: tuple, b: tuple, f: float,
                                                           gap: float) -> None:
    p0 = Pose(5.0, rpy_matrix(np.array(a[:3])), np.array(a[3:]))
    p1 = Pose(5.0 + gap, rpy_matrix(np.array(b[:3])), np.array(b[3:]))
    stamp = min(p0.stamp + f * gap, p1.stamp)
    mid = interpolate_pose(p0, p1, stamp)
    assert interpolate_pose(p0, p1, p0.stamp) is p0
    assert interpolate_pose(p0, p1, p1.stamp) is p1
    frac = (stamp - p0.stamp) / gap
    np.testing.assert_allclose(mid.position, p0.position + frac * (p1.position - p0.position),
                               atol=1e-9)
    assert np.all(mid.position >= np.minimum(p0.position, p1.position) - 1e-9)
    assert np.all(mid.position <= np.maximum(p0.position, p1.position) + 1e-9)
    whole = angle_between(p0.rotation, p1.rotation)  # on the shorter arc, at its fraction
    to_mid, from_mid = angle_between(p0.rotation, mid.rotation), angle_between(mid.rotation,
                                                                             p1.rotation)
    assert to_mid + from_mid == pytest.approx(whole, abs=1e-6)
    assert to_mid == pytest.approx(frac * whole, abs=1e-6)
    np.testing.assert_allclose(mid.rotation @ mid.rotation.T, np.eye(3), atol=1e-9)


# The original failure: the body pitches (peak 30°/s, as in a walk) and a scan, stamped between
# two 50 Hz odometry samples, arrives while the newest sample is 45 ms older than it (a loaded
# machine; within the 50 ms tolerance).
PITCH_AMPLITUDE = 0.1  # [rad]
PITCH_RATE = math.radians(30.0)  # peak [rad/s]


def walking_body(t: float) -> tuple[np.ndarray, np.ndarray]:
    pitch = PITCH_AMPLITUDE * math.sin(PITCH_RATE / PITCH_AMPLITUDE * t)
    return rpy_matrix(np.array([0.0, pitch, 0.0])), np.array([0.05 * t, 0.0, BODY_Z])


def pitching_walk(mount: Mount, scan_at: Callable, interpolated: bool) -> TerrainMapper:
    """Scans at 10 Hz of the flat seabed, each 45 ms newer than the newest odometry when it
    arrives; fused by the mapper's rule, or (not ``interpolated``) with that older pose."""
    mapper = TerrainMapper(MapperSettings(), mount)
    odometry = iter(0.02 * k for k in range(1000))
    t_odom = next(odometry)
    for k in range(1, 60):
        stamp = 0.1 * k + 0.005
        while t_odom <= stamp - 0.04:  # the samples delivered before the scan
            mapper.add_odometry(Pose(t_odom, *walking_body(t_odom)))
            t_odom = next(odometry)
        rot, pos = walking_body(stamp)
        points = scan_at(tuple(pos), [], rotation=rot)
        newest = mapper.latest_pose
        assert newest is not None and stamp - newest.stamp == pytest.approx(0.045)
        fate = mapper.add_scan(points, stamp if interpolated else newest.stamp)
        assert fate is (ScanFate.HELD if interpolated else ScanFate.FUSED)
    return mapper


def test_a_pitching_body_maps_flat_ground_flat(mount: Mount, scan_at: Callable) -> None:
    limit = MapperSettings().obstacle_height
    rot, pos = walking_body(0.605)  # pitching at 30°/s
    points = scan_at(tuple(pos), [], rotation=rot)
    old = Pose(0.56, *walking_body(0.56))  # the newest sample when the scan arrives
    heights = returns_in_map(points, mount, old.rotation, old.position,
                             MapperSettings().noise)[0][:, 2]
    assert np.abs(heights).max() > limit  # one scan: flat ground more than the threshold off
    nearest = pitching_walk(mount, scan_at, interpolated=False)
    assert np.abs(nearest.grid.height[nearest.grid.known]).max() > limit
    assert nearest.obstacles().any()  # the flaky system test's obstacle cells
    mapper = pitching_walk(mount, scan_at, interpolated=True)
    mapper.add_odometry(Pose(5.92, *walking_body(5.92)))  # releases the last held scan
    assert mapper.scans_fused == 59 and mapper.held == 0 and not mapper.skipped
    assert np.abs(mapper.grid.height[mapper.grid.known]).max() < 0.001
    assert mapper.grid.known.sum() > 300 and not mapper.obstacles().any()
