"""Which odometry the terrain map follows (crawler_motion.mapping.odometry, through the mapper):
one future-stamped, absurd or jumping sample no longer freezes or corrupts the map; a restarted
odometry stream is adopted with the map cleared to unknown (never to free)."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.mapping.mapper import MapperSettings, Pose, ScanFate, TerrainMapper
from crawler_motion.mapping.odometry import OdometryGate, OdometryLimits, OdometryVerdict
from crawler_motion.mapping.points import Mount

BODY_Z = 0.07
#: Returns on the ground 0.5-0.6 m ahead of the scanner (scanner_link at the body).
POINTS = np.array([[0.5, 0.0, -BODY_Z], [0.6, 0.1, -BODY_Z]])
RATE = 50.0  # odometry [Hz]


def pose(t: float, x: float = 0.0) -> Pose:
    return Pose(t, np.eye(3), np.array([x, 0.0, BODY_Z]))


def mapper() -> TerrainMapper:
    return TerrainMapper(MapperSettings(), Mount(np.eye(3), np.zeros(3)))


def walk(m: TerrainMapper, t0: float, t1: float, now_offset: float | None = 0.0,
         x0: float = 0.0, speed: float = 0.1) -> list:
    """Odometry at RATE from ``t0`` to ``t1`` [s] (x moving at ``speed``) with a scan per
    sample; the receiver's clock is the stamp plus ``now_offset`` (None: no clock). The
    scans' fates."""
    fates = []
    for t in np.arange(t0, t1, 1.0 / RATE):
        now = None if now_offset is None else t + now_offset
        m.add_odometry(pose(float(t), x0 + speed * (t - t0)), now)
        fates.append(m.add_scan(POINTS, float(t)))
    return fates


def test_one_future_stamped_sample_is_refused_and_the_map_keeps_following():
    m = mapper()
    walk(m, 0.0, 1.0)
    assert m.add_odometry(pose(1.0 + 3600.0), now=1.0) is OdometryVerdict.FUTURE
    fates = walk(m, 1.0, 3.0)
    assert all(f is ScanFate.FUSED for f in fates)  # nothing frozen
    assert m.odometry_refused == {OdometryVerdict.FUTURE: 1}


def test_without_a_clock_a_future_sample_is_outlived_by_a_reset_of_the_stream():
    m = mapper()
    walk(m, 0.0, 1.0, now_offset=None)
    assert m.grid.known.any()
    assert m.add_odometry(pose(3600.0)) is None  # no clock to compare: plausible, accepted
    verdicts = [m.add_odometry(pose(1.0 + k / RATE)) for k in range(12)]
    limit = m.settings.odometry.reset_samples
    assert verdicts[:limit - 1] == [OdometryVerdict.ODOM_STALE] * (limit - 1)
    assert verdicts[limit - 1] is OdometryVerdict.RESET
    assert verdicts[limit:] == [None, None]  # following the new stream
    # the map was cleared to unknown (not free), then fills again
    fates = walk(m, 1.3, 2.0, now_offset=None)
    assert all(f is ScanFate.FUSED for f in fates) and m.grid.known.any()


@pytest.mark.parametrize("x", [1e300, -4.7e17, 1e5 + 1.0, float("nan"), float("inf")])
def test_an_absurd_position_is_refused_and_leaves_the_map_alone(x):
    m = mapper()
    walk(m, 0.0, 1.0)
    origin, known = m.grid.origin.copy(), m.grid.known.copy()
    assert m.add_odometry(pose(1.0, x), now=1.0) is OdometryVerdict.BAD_POSE
    np.testing.assert_array_equal(m.grid.origin, origin)
    np.testing.assert_array_equal(m.grid.known, known)
    assert all(f is ScanFate.FUSED for f in walk(m, 1.02, 2.0, x0=0.1))


def test_a_single_jump_is_refused_and_a_lasting_one_resets_the_map():
    m = mapper()
    walk(m, 0.0, 1.0)
    assert m.add_odometry(pose(1.0, 100.0), now=1.0) is OdometryVerdict.JUMP
    assert m.grid.known.any()  # not wiped
    assert m.add_odometry(pose(1.02, 0.1), now=1.02) is None  # the real odometry goes on
    verdicts = [m.add_odometry(pose(1.04 + k / RATE, 100.0), now=1.04 + k / RATE)
                for k in range(10)]
    assert verdicts[-1] is OdometryVerdict.RESET and not m.grid.known.any()
    assert m.add_odometry(pose(1.3, 100.0), now=1.3) is None


@pytest.mark.parametrize(("stamp", "now", "verdict"), [
    (1.5, 1.0, OdometryVerdict.ACCEPT),  # exactly future_tolerance ahead
    (1.5 + 1e-9, 1.0, OdometryVerdict.FUTURE),
    (0.5, None, OdometryVerdict.ODOM_STALE),  # no later than the latest (0.5)
    (0.52, None, OdometryVerdict.ACCEPT),
])
def test_gate_boundaries(stamp, now, verdict):
    gate = OdometryGate(OdometryLimits())
    assert gate.check(pose(0.5), None) is OdometryVerdict.ACCEPT
    assert gate.check(pose(stamp), now) is verdict


@pytest.mark.parametrize(("dx", "verdict"), [
    (2.0 * 0.1 + 0.2, OdometryVerdict.ACCEPT),  # max_speed x dt + allowance
    (2.0 * 0.1 + 0.2 + 1e-6, OdometryVerdict.JUMP),
])
def test_gate_jump_boundary(dx, verdict):
    gate = OdometryGate(OdometryLimits())
    gate.check(pose(0.0), None)
    assert gate.check(pose(0.1, dx), None) is verdict


def test_scattered_bad_samples_never_reset():
    # refused samples that do not agree with each other are not a new stream
    gate = OdometryGate(OdometryLimits())
    gate.check(pose(10.0), None)
    for k in range(30):
        bad = pose(10.0 - k * 0.1, 50.0 * (-1) ** k)  # stale and jumping about
        assert gate.check(bad, None) is not OdometryVerdict.RESET
