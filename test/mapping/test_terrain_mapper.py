"""The mapper on synthetic scans: a box's obstacle cells, a flat noisy seabed, bad scans."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from crawler_motion.mapping.mapper import (
    MapperSettings,
    Pose,
    ScanFate,
    SkipReason,
    TerrainMapper,
)
from crawler_motion.mapping.obstacles import local_ground, step_threshold
from crawler_motion.mapping.odometry import OdometryVerdict
from crawler_motion.mapping.points import Mount
from crawler_motion.model.config import load_config

BODY_Z = 0.07
BOX = ((1.0, -0.15, 0.0), (1.3, 0.15, 0.04))  # 0.3 x 0.3 m, 4 cm high, 1 m ahead
APPROACH = np.linspace(0.0, 0.5, 51)  # from 1 m to 0.5 m before its face, 1 cm a scan


def look(mapper: TerrainMapper, scan_at: Callable, xs: np.ndarray, boxes: list,
         noise: float = 0.0) -> None:
    rng = np.random.default_rng(3)
    for k, x in enumerate(xs):
        t = 0.1 * k
        mapper.add_odometry(Pose(t, np.eye(3), np.array([x, 0.0, BODY_Z])))
        fate = mapper.add_scan(scan_at((x, 0.0, BODY_Z), boxes, noise, rng), t)
        assert fate is ScanFate.FUSED


def footprint_iou(mapper: TerrainMapper, box: tuple) -> float:
    xs, ys = mapper.grid.centres()
    (x0, y0, _), (x1, y1, _) = box
    truth = (xs > x0) & (xs < x1) & (ys > y0) & (ys < y1)
    marked = mapper.obstacles()
    return float((truth & marked).sum() / (truth | marked).sum())


def test_obstacle_cells_of_a_box_seen_from_1_m_cover_its_footprint(
        mount: Mount, scan_at: Callable) -> None:
    mapper = TerrainMapper(MapperSettings(), mount)
    look(mapper, scan_at, APPROACH, [BOX], noise=0.005)
    iou = footprint_iou(mapper, BOX)
    assert iou >= 0.7, iou
    assert not np.isnan(mapper.grid.height).any()


def test_without_the_box_there_is_nothing_to_cover(mount: Mount, scan_at: Callable) -> None:
    mapper = TerrainMapper(MapperSettings(), mount)
    look(mapper, scan_at, APPROACH, [])
    assert footprint_iou(mapper, BOX) == 0.0


@pytest.mark.parametrize("noise", [0.005, 0.01])  # the simulator: 0.005 m
def test_a_flat_noisy_seabed_has_no_obstacle_cell(mount: Mount, scan_at: Callable,
                                                  noise: float) -> None:
    mapper = TerrainMapper(MapperSettings(), mount)
    look(mapper, scan_at, np.linspace(0.0, 0.5, 11), [], noise=noise)
    assert mapper.grid.known.sum() > 300
    assert not mapper.obstacles().any()
    assert set(np.unique(mapper.occupancy())) == {-1, 0}


def test_the_threshold_is_the_smaller_of_foot_and_belly_clearance() -> None:
    cfg = load_config()
    assert step_threshold(cfg) == pytest.approx(min(cfg.gait.lift + cfg.gait.arc,
                                                    cfg.robot.body_height - 0.025))


@pytest.mark.parametrize("step, obstacle", [(0.019, False), (0.021, True)])
def test_a_step_just_below_or_above_the_threshold(step: float, obstacle: bool) -> None:
    mapper = TerrainMapper(MapperSettings(obstacle_height=0.02), Mount(np.eye(3), np.zeros(3)))
    g = mapper.grid
    g.known[:] = True
    g.variance[:] = 1e-8  # sigma 0.1 mm: the confidence term is negligible
    g.height[:, g.cells // 2:] = step
    assert bool(mapper.obstacles().any()) is obstacle


def test_local_ground_ignores_unknown_cells() -> None:
    h = np.array([[0.0, 0.5, 0.3], [0.2, 0.1, 0.4], [0.6, 0.7, 0.8]])
    known = np.ones_like(h, dtype=bool)
    known[0, 0] = False
    ground = local_ground(h, known, 1)
    assert ground[0, 0] == 0.1 and ground[2, 2] == 0.1 and ground[0, 2] == 0.1
    assert np.isinf(local_ground(h, np.zeros_like(known), 1)).all()


def test_bad_scans_are_skipped_with_counted_reasons(mount: Mount) -> None:
    mapper = TerrainMapper(MapperSettings(odom_window=1.0), mount)
    good = np.array([[0.5, 0.0, 0.0], [0.6, 0.1, 0.0]])
    assert mapper.add_scan(good, 0.0) is SkipReason.NO_ODOMETRY
    for k in range(21):
        mapper.add_odometry(Pose(0.1 * k, np.eye(3), np.array([0.0, 0.0, BODY_Z])))
    assert mapper.add_scan(np.zeros((0, 3)), 2.0) is SkipReason.EMPTY
    assert mapper.add_scan(np.full((3, 3), np.nan), 2.0) is SkipReason.ALL_NON_FINITE
    assert mapper.add_scan(good, 0.5) is SkipReason.STALE  # window is 1.0..2.0 s
    assert mapper.add_scan(good, 2.2) is SkipReason.AHEAD_OF_ODOMETRY
    mixed = np.vstack([good, [[np.inf, 0, 0], [np.nan, 1, 2]]])
    assert mapper.add_scan(mixed, 1.96) is ScanFate.FUSED
    assert mapper.add_odometry(Pose(1.0, np.eye(3), np.zeros(3))) is OdometryVerdict.ODOM_STALE
    bad_pose = Pose(3.0, np.full((3, 3), np.nan), np.zeros(3))
    assert mapper.add_odometry(bad_pose) is OdometryVerdict.BAD_POSE
    assert dict(mapper.skipped) == {
        SkipReason.NO_ODOMETRY: 1, SkipReason.EMPTY: 1, SkipReason.ALL_NON_FINITE: 1,
        SkipReason.NON_FINITE_POINTS: 5, SkipReason.STALE: 1,
        SkipReason.AHEAD_OF_ODOMETRY: 1}
    assert dict(mapper.odometry_refused) == {OdometryVerdict.ODOM_STALE: 1,
                                             OdometryVerdict.BAD_POSE: 1}
    assert mapper.scans_fused == 1 and mapper.grid.known.sum() == 2
    assert np.isfinite(mapper.grid.height).all()


def test_the_stamp_of_the_last_fused_scan_dates_the_content(mount: Mount) -> None:
    mapper = TerrainMapper(MapperSettings(odom_window=1.0), mount)
    good = np.array([[0.5, 0.0, 0.0], [0.6, 0.1, 0.0]])
    assert mapper.last_fused_stamp is None
    for k in range(11):
        mapper.add_odometry(Pose(0.1 * k, np.eye(3), np.array([0.0, 0.0, BODY_Z])))
    assert mapper.add_scan(good, 0.95) is ScanFate.FUSED
    assert mapper.add_scan(good, 5.0) is SkipReason.AHEAD_OF_ODOMETRY  # skipped: no change
    assert mapper.last_fused_stamp == 0.95
    for k in range(10):  # a restarted odometry: the map is cleared, nothing fused since
        mapper.add_odometry(Pose(0.05 * k, np.eye(3), np.array([0.0, 0.0, BODY_Z])))
    assert mapper.last_fused_stamp is None
