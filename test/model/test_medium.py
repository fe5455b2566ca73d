"""Tests of crawler_motion.model.medium: the ``medium`` section of robot.yaml, the pendulum's
frequency and the buoyancy's ZMP shift."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import config_path, load_config
from crawler_motion.model.medium import GRAVITY, MediumConfig, parse_medium

RAW = yaml.safe_load(config_path("robot.yaml").read_text(encoding="utf-8"))


def test_the_shipped_medium_is_the_simulated_water():
    medium = load_config().medium
    assert medium.net_weight == 0.3  # the seabed simulator's default net weight
    assert medium.added_mass == 0.0  # MuJoCo models no added mass
    np.testing.assert_array_equal(medium.buoyancy_offset, 0.0)


def test_a_config_without_the_section_takes_the_defaults(tmp_path):
    data = copy.deepcopy(RAW)
    del data["medium"]
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    medium = load_config(path).medium
    assert (medium.net_weight, medium.added_mass) == (MediumConfig().net_weight,
                                                     MediumConfig().added_mass)


@pytest.mark.parametrize(("net", "added", "height", "expected"), [
    (1.0, 0.0, 0.07, GRAVITY / 0.07),  # land
    (0.3, 0.0, 0.07, 0.3 * GRAVITY / 0.07),  # water, no added mass
    (0.3, 0.5, 0.07, 0.3 * GRAVITY / (1.5 * 0.07)),  # added mass slows it
    (0.3, 0.0, 0.09, 0.3 * GRAVITY / 0.09),  # a higher body too
])
def test_omega2(net, added, height, expected):
    assert MediumConfig(net, added).omega2(height) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("height", [0.0, -0.01, math.nan, math.inf])
def test_omega2_refuses_a_height_that_is_not_a_length(height):
    with pytest.raises(ConfigError, match="pendulum height"):
        MediumConfig().omega2(height)


def test_the_buoyancy_offset_shifts_the_zmp_against_it():
    # buoyancy (1 - net) of the weight pulls up at the offset; the net load (net) moves away
    medium = MediumConfig(0.25, 0.0, np.array([0.002, -0.001, 0.03]))
    np.testing.assert_allclose(medium.zmp_shift, [-0.006, 0.003], atol=1e-15)
    assert np.all(MediumConfig(1.0, 0.0, np.array([0.01, 0.01, 0.0])).zmp_shift == 0.0)
    land = medium.on_land()
    assert (land.net_weight, land.added_mass) == (1.0, 0.0)


@pytest.mark.parametrize(("data", "expected"), [
    ({"net_weight": 0.0}, "medium.net_weight must be a number in (0, 1]"),
    ({"net_weight": -0.3}, "medium.net_weight must be a number in (0, 1]"),
    ({"net_weight": 1.01}, "got 1.01"),
    ({"net_weight": "heavy"}, "medium.net_weight"),
    ({"net_weight": math.nan}, "medium.net_weight"),
    ({"added_mass": -0.1}, "medium.added_mass must be a number in [0, 10]"),
    ({"added_mass": 11.0}, "medium.added_mass"),
    ({"buoyancy_offset": [0.0, 0.0]}, "medium.buoyancy_offset must be [x, y, z] in m"),
    ({"buoyancy_offset": [0.0, 0.2, 0.0]}, "within [-0.1, 0.1] m per axis"),
    ({"buoyancy_offset": [0.0, "up", 0.0]}, "medium.buoyancy_offset must be a number"),
    ({"density": 1000}, "unknown keys ['density']"),
    ([0.3], "medium must be a mapping"),
])
def test_a_bad_medium_is_refused_with_the_key_the_value_and_the_range(data, expected):
    with pytest.raises(ConfigError) as err:
        parse_medium(data)
    assert expected in str(err.value)


@pytest.mark.parametrize("data", [{"net_weight": 1.0}, {"net_weight": 1e-3},
                                  {"added_mass": 0.0}, {"added_mass": 10.0},
                                  {"buoyancy_offset": [0.1, -0.1, 0.0]}])
def test_boundary_values_load(data):
    parse_medium(data)


def test_a_bad_medium_in_a_file_names_the_file(tmp_path):
    data = copy.deepcopy(RAW)
    data["medium"]["net_weight"] = 0
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert str(path) in str(err.value) and "net_weight" in str(err.value)
