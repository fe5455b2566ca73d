"""The range scanner sees the shipped wall at its true distance and never the robot."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import load_scanner
from crawler_motion.model.rotations import rpy_matrix
from crawler_motion.sim.seabed.model import SeabedModel
from crawler_motion.sim.seabed.scanner import RangeScanner, ScannerSettings

WALL_X = 0.60  # near face of the wall in config/worlds/wall.xml [m]


@pytest.fixture(scope="module")
def standing(cfg):
    sm = SeabedModel(cfg.robot, world="wall")
    data = sm.make_data()
    mujoco.mj_step(sm.model, data, nstep=int(0.3 / sm.timestep))
    return sm, data


def _world(scanner: RangeScanner, data, points: np.ndarray) -> np.ndarray:
    origin, rot = scanner.pose(data)
    return origin + points @ rot.T


@pytest.mark.parametrize("noise", [0.0, 0.003])
def test_scan_returns_the_wall_at_its_true_distance(standing, noise):
    sm, data = standing
    scanner = RangeScanner(sm, load_scanner(), ScannerSettings(range_noise=noise, seed=1))
    world = _world(scanner, data, scanner.points(data))
    wall = world[world[:, 2] > 0.01]
    seabed = world[world[:, 2] <= 0.01]
    assert len(wall) >= 10 and len(seabed) >= 10
    assert np.abs(wall[:, 0] - WALL_X).max() <= 4 * noise + 1e-9
    assert np.abs(seabed[:, 2]).max() <= 4 * noise + 1e-9
    assert (world[:, 0] > 0.12).all()  # nothing on the robot itself


def test_mount_is_pitched_down_ten_degrees():
    mount = load_scanner()
    central = rpy_matrix(mount.rpy) @ [1.0, 0.0, 0.0]
    assert np.degrees(np.arcsin(-central[2])) == pytest.approx(10.0)


def test_range_limit_and_dropouts(standing):
    sm, data = standing
    short = RangeScanner(sm, load_scanner(), ScannerSettings(max_range=0.2))
    assert len(short.points(data)) == 0  # the seabed is >= 0.23 m along every ray
    none = RangeScanner(sm, load_scanner(), ScannerSettings(dropout=1.0))
    assert len(none.points(data)) == 0
    half = RangeScanner(sm, load_scanner(), ScannerSettings(dropout=0.5, seed=4))
    full = RangeScanner(sm, load_scanner(), ScannerSettings(seed=4))
    assert 0.3 < len(half.points(data)) / len(full.points(data)) < 0.7


def test_scans_repeat_with_the_seed(standing):
    sm, data = standing
    a = RangeScanner(sm, load_scanner(), ScannerSettings(seed=9)).ranges(data)
    b = RangeScanner(sm, load_scanner(), ScannerSettings(seed=9)).ranges(data)
    assert np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("kwargs", [{"range_noise": -0.1}, {"dropout": 1.5},
                                    {"max_range": 0.0}, {"seed": 1.5}])
def test_bad_scanner_settings_are_refused(kwargs):
    with pytest.raises(ConfigError):
        ScannerSettings(**kwargs)


GOOD = {"position": [0.12, 0.0, 0.0], "rpy": [0.0, 0.1745, 0.0], "horizontal_fov": 1.5,
        "columns": 33, "vertical_fov": 0.35, "rows": 5, "max_range": 3.0, "rate": 10.0}


@pytest.mark.parametrize(("change", "problem"), [
    ({}, None), ({"rows": 1, "vertical_fov": 0.0}, None), ({"columns": 4096}, None),
    ({"columns": 0}, "columns"), ({"rows": 2.5}, "rows"), ({"columns": True}, "columns"),
    ({"position": [0.1, 0.0]}, "position"), ({"rpy": [0, "x", 0]}, "rpy"),
    ({"horizontal_fov": 3.2}, "horizontal_fov"), ({"vertical_fov": -0.1}, "vertical_fov"),
    ({"max_range": 0.0}, "max_range"), ({"rate": -1.0}, "rate"), (None, "scanner"),
])
def test_scanner_section_is_validated(tmp_path, change, problem):
    import yaml

    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump({} if change is None else {"scanner": {**GOOD, **change}}))
    if problem is None:
        mount = load_scanner(path)
        assert mount.columns == {**GOOD, **change}["columns"]
        return
    with pytest.raises(ConfigError, match=problem):
        load_scanner(path)
