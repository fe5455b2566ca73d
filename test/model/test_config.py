"""Configuration loading and validation: the shipped file, its plausibility, bad input."""

from __future__ import annotations

import copy
import math
from functools import partial
from pathlib import Path

import numpy as np
import pytest
import yaml

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import (
    DEFAULT_LEGS,
    config_path,
    joint_names,
    load_config,
    parse_gait,
    parse_robot,
)
from crawler_motion.model.kinematics import inverse_kinematics
from crawler_motion.model.pose_limits import BodyPoseConfig

SHIPPED = config_path("robot.yaml")
RAW = yaml.safe_load(SHIPPED.read_text(encoding="utf-8"))
DELETE = object()


def mutated(changes: dict[str, object]) -> dict:
    """Deep copy of the shipped YAML data with ``changes`` ('robot.links.l2': value | DELETE)."""
    data = copy.deepcopy(RAW)
    for dotted, value in changes.items():
        *parents, key = dotted.split(".")
        node = data
        for part in parents:
            node = node[part]
        if value is DELETE:
            del node[key]
        else:
            node[key] = value
    return data


def write(tmp_path: Path, data: object, name: str = "robot.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


# ---------------------------------------------------------------- the shipped file

def test_shipped_file_loads():
    cfg = load_config()
    assert cfg.source == str(SHIPPED)
    assert cfg.robot.legs == DEFAULT_LEGS == ("lf", "lb", "rb", "rf")
    assert cfg.robot.joint_names == joint_names() and len(joint_names()) == 12
    assert joint_names()[:3] == ("lf_root_joint", "lf_shoulder_joint", "lf_knee_joint")
    assert (cfg.robot.l1, cfg.robot.l2, cfg.robot.l3) == (0.03, 0.06, 0.09)
    assert cfg.gait.gaits["diagonal"] == (("rf", "lb"), ("lf", "rb"))  # RF+LB swing first
    assert set(cfg.gait.profiles) >= {"rest", "smooth"}
    assert cfg.robot.lower.shape == cfg.robot.upper.shape == (3,)
    assert cfg.robot.lower_limits().shape == (4, 3)


@pytest.mark.parametrize("as_type", [str, Path])
def test_load_config_takes_str_and_path(as_type, tmp_path):
    path = write(tmp_path, RAW)
    cfg = load_config(as_type(path))
    assert cfg.source == str(path)
    assert cfg.robot.reach == load_config().robot.reach


def test_hips_and_neutral_directions_follow_rep103():
    robot = load_config().robot
    for leg, hip, yaw in zip(robot.legs, robot.hips, robot.neutral_yaw, strict=True):
        assert math.copysign(1, hip[0]) == (1 if leg[1] == "f" else -1), leg  # front: +x
        assert math.copysign(1, hip[1]) == (1 if leg[0] == "l" else -1), leg  # left: +y
        assert yaw == pytest.approx(math.copysign(math.pi / 2, hip[1]), abs=1e-15)


def test_standing_foot_is_013_out_and_007_below_the_hip():
    robot = load_config().robot
    offset = robot.standing_feet() - robot.hips
    np.testing.assert_allclose(np.hypot(offset[:, 0], offset[:, 1]), 0.13, atol=1e-15)
    np.testing.assert_allclose(offset[:, 2], -0.07, atol=1e-15)
    # out along the leg's neutral direction (sideways from the body)
    direction = np.stack([np.cos(robot.neutral_yaw), np.sin(robot.neutral_yaw)], axis=-1)
    np.testing.assert_allclose(offset[:, :2], 0.13 * direction, atol=1e-15)


def _stride_box(height: float | None = None) -> np.ndarray:
    """Foot targets covering a whole default step: x in ±stride/2, z from 0 to the clearance."""
    cfg = load_config()
    half = cfg.gait.stride / 2
    dx = np.linspace(-half, half, 13)
    dz = np.linspace(0.0, cfg.gait.lift + cfg.gait.arc, 9)
    grid = np.stack(np.meshgrid(dx, dz, indexing="ij"), axis=-1).reshape(-1, 2)
    offsets = np.zeros((len(grid), 1, 3))
    offsets[:, 0, 0], offsets[:, 0, 2] = grid[:, 0], grid[:, 1]
    return cfg.robot.standing_feet(height) + offsets


def _margins(q: np.ndarray) -> np.ndarray:
    """Smallest distance of each joint kind to its nearest limit over all samples and legs."""
    robot = load_config().robot
    return np.minimum(q - robot.lower, robot.upper - q).reshape(-1, 3).min(axis=0)


def test_default_step_dimensions():
    gait = load_config().gait
    assert gait.stride == pytest.approx(0.06)
    assert gait.lift + gait.arc == pytest.approx(0.02)
    assert abs(gait.stride) <= gait.max_stride
    assert gait.lift + gait.arc <= gait.max_clearance
    assert gait.swing_time_range[0] <= gait.swing_time <= gait.swing_time_range[1]


@pytest.mark.parametrize("what", ["standing", "whole stride and clearance"])
def test_default_poses_keep_005_rad_from_every_limit(what):
    robot = load_config().robot
    feet = robot.standing_feet() if what == "standing" else _stride_box()
    q = inverse_kinematics(robot, feet, check=False)  # margins, not just "inside"
    margins = _margins(q)
    assert np.all(margins >= 0.05), f"{what}: margins root/shoulder/knee = {margins} rad"


@pytest.mark.parametrize("height", [0.05, 0.06, 0.08, 0.09])
def test_whole_body_height_range_keeps_the_step_reachable(height):
    q = inverse_kinematics(load_config().robot, _stride_box(height), check=False)
    margins = _margins(q)
    assert np.all(margins >= 0.05), f"height {height}: margins {margins} rad"


@pytest.mark.parametrize("height", [0.049, 0.0901, math.nan, math.inf])
def test_standing_feet_refuses_a_body_height_outside_the_range(height):
    with pytest.raises(ConfigError, match="body height"):
        load_config().robot.standing_feet(height)


# ---------------------------------------------------------------- malformed input (table)

GROUPS = "gait.gaits.diagonal.groups"
SMOOTH_LIFT = RAW["gait"]["profiles"]["smooth"]["lift"]
# (id, changes, substrings the message must contain). Each row is run through
# parse_robot/parse_gait on the data and through load_config on a file.
BAD = [
    # missing sections and fields
    ("no robot", {"robot": DELETE}, ["missing section 'robot'"]),
    ("no gait", {"gait": DELETE}, ["missing section 'gait'"]),
    ("no hips", {"robot.hips": DELETE}, ["robot", "missing section 'hips'"]),
    ("no neutral_yaw", {"robot.neutral_yaw": DELETE}, ["missing section 'neutral_yaw'"]),
    ("no knee", {"robot.knee": DELETE}, ["missing section 'knee'"]),
    ("no links", {"robot.links": DELETE}, ["missing section 'links'"]),
    ("no limits", {"robot.limits": DELETE}, ["missing section 'limits'"]),
    ("no stance", {"robot.stance": DELETE}, ["missing section 'stance'"]),
    ("no knee limits", {"robot.limits.knee": DELETE}, ["robot.limits.knee"]),
    ("no l3", {"robot.links.l3": DELETE}, ["robot.links.l3"]),
    ("no reach", {"robot.stance.reach": DELETE}, ["robot.stance.reach"]),
    ("no gaits", {"gait.gaits": DELETE}, ["gait", "missing section 'gaits'"]),
    ("no profiles", {"gait.profiles": DELETE}, ["missing section 'profiles'"]),
    ("no rest profile", {"gait.profiles.rest": DELETE}, ["gait.profiles", "'rest'"]),
    ("no stride", {"gait.stride": DELETE}, ["gait.stride"]),
    ("no upper", {"robot.limits.root.upper": DELETE}, ["robot.limits.root.upper"]),
    # wrong types
    ("l2 as text", {"robot.links.l2": "0.06"}, ["robot.links.l2", "number"]),
    ("l1 as bool", {"robot.links.l1": True}, ["robot.links.l1", "number"]),
    ("hip of 2", {"robot.hips.lf": [0.1, 0.06]}, ["robot.hips.lf", "[x, y, z]"]),
    ("hip as text", {"robot.hips.lb": "front"}, ["robot.hips.lb"]),
    ("hip with text", {"robot.hips.rb": [0.1, "y", 0.0]}, ["robot.hips.rb", "number"]),
    ("yaw as text", {"robot.neutral_yaw.rf": "left"}, ["robot.neutral_yaw", "number"]),
    ("knee sideways", {"robot.knee.lf": "sideways"}, ["robot.knee.lf", "'up' or 'down'"]),
    ("legs as text", {"robot.legs": "lf lb rb rf"}, ["robot.legs"]),
    ("three legs", {"robot.legs": ["lf", "lb", "rb"]}, ["robot.legs", "4 distinct"]),
    ("leg twice", {"robot.legs": ["lf", "lf", "rb", "rf"]}, ["robot.legs", "4 distinct"]),
    ("limit as text", {"robot.limits.root": "wide"}, ["robot.limits.root"]),
    ("velocity as text", {"robot.limits.knee.velocity": "fast"},
     ["robot.limits.knee.velocity"]),
    ("zero effort", {"robot.limits.shoulder.effort": 0}, ["robot.limits.shoulder.effort", "> 0"]),
    ("negative l3", {"robot.links.l3": -0.09}, ["robot.links.l3", "> 0"]),
    ("height range scalar", {"robot.body_height_range": 0.07}, ["robot.body_height_range"]),
    ("reach inside coxa", {"robot.stance.reach": 0.02}, ["robot.stance.reach", "l1"]),
    ("lift as text", {"gait.lift": "high"}, ["gait.lift"]),
    ("zero swing time", {"gait.swing_time": 0}, ["gait.swing_time", "> 0"]),
    ("swing range scalar", {"gait.swing_time_range": 2}, ["gait.swing_time_range"]),
    ("swing range of 1", {"gait.swing_time_range": [0.5]}, ["gait.swing_time_range"]),
    ("swing range reversed", {"gait.swing_time_range": [5.0, 0.1]},
     ["gait.swing_time_range", "min <= max"]),
    ("groups of numbers", {GROUPS: [1, 2]}, [GROUPS]),
    ("nested group", {GROUPS: [["rf", ["lb"]], ["lf", "rb"]]}, [GROUPS]),
    ("empty group", {GROUPS: [[], ["rf", "lb", "lf", "rb"]]}, [GROUPS]),
    ("gait as text", {"gait.gaits.wave": "lb lf rb rf"}, ["gait.gaits.wave"]),
    ("profile as number", {"gait.profiles.smooth": 0.5}, ["gait.profiles.smooth"]),
    ("v_b as text", {"gait.profiles.smooth.v_b": "fast"}, ["gait.profiles.smooth.v_b"]),
    ("negative v_d", {"gait.profiles.smooth.v_d": -1.0}, ["gait.profiles.smooth", "v_d"]),
    ("negative transfer", {"gait.gaits.diagonal.transfer_time": -0.1},
     ["gait.gaits.diagonal.transfer_time", ">= 0"]),
    ("transfer as text", {"gait.gaits.wave.transfer_time": "long"},
     ["gait.gaits.wave.transfer_time"]),
    ("negative sway weight", {"gait.gaits.diagonal_sway.sway_weight": -0.01},
     ["gait.gaits.diagonal_sway.sway_weight", ">= 0"]),
    ("sway weight as text", {"gait.gaits.diagonal_sway.sway_weight": "some"},
     ["gait.gaits.diagonal_sway.sway_weight"]),
    ("sway weight of a crawl", {"gait.gaits.wave.sway_weight": 0.02},
     ["gait.gaits.wave.sway_weight", "two feet on the ground", "remove it"]),
    ("sway weight with a three-foot swing", {GROUPS: [["rf"], ["lb"], ["lf", "rb"]],
                                             "gait.gaits.diagonal.sway_weight": 0.02},
     ["gait.gaits.diagonal.sway_weight", "support line"]),
    ("gait swing time below range", {"gait.gaits.diagonal_sway.swing_time": 0.09},
     ["gait.gaits.diagonal_sway.swing_time", "swing_time_range", "0.09"]),
    ("gait swing time above range", {"gait.gaits.wave.swing_time": 5.01},
     ["gait.gaits.wave.swing_time", "swing_time_range [0.1, 5.0]"]),
    ("gait swing time of 0", {"gait.gaits.diagonal.swing_time": 0},
     ["gait.gaits.diagonal.swing_time", "swing_time_range"]),
    ("gait swing time as text", {"gait.gaits.wave.swing_time": "quick"},
     ["gait.gaits.wave.swing_time"]),
    ("unknown gait", {"gait.gait": "gallop"}, ["gait.gait", "gallop", "diagonal"]),
    ("unknown profile", {"gait.profile": "jerky"}, ["gait.profile", "jerky", "smooth"]),
    # NaN and infinity
    ("NaN l2", {"robot.links.l2": math.nan}, ["robot.links.l2", "finite"]),
    ("NaN hip", {"robot.hips.rf": [0.1, math.nan, 0.0]}, ["robot.hips.rf", "finite"]),
    ("inf yaw", {"robot.neutral_yaw.lb": math.inf}, ["robot.neutral_yaw", "finite"]),
    ("NaN limit", {"robot.limits.root.upper": math.nan}, ["robot.limits.root.upper", "finite"]),
    ("NaN height", {"robot.stance.body_height": math.nan},
     ["robot.stance.body_height", "finite"]),
    ("NaN stride", {"gait.stride": math.nan}, ["gait.stride", "finite"]),
    ("-inf swing", {"gait.swing_time": -math.inf}, ["gait.swing_time", "finite"]),
    ("NaN fraction", {"gait.profiles.rest.arc": math.nan}, ["gait.profiles.rest.arc", "finite"]),
    # limits
    ("knee lower = upper", {"robot.limits.knee.lower": 1.0, "robot.limits.knee.upper": 1.0},
     ["robot.limits.knee", "lower < upper", "[1.0, 1.0]"]),
    ("shoulder lower > upper", {"robot.limits.shoulder.lower": 1.5},
     ["robot.limits.shoulder", "[1.5, 1.4]"]),
    ("root beyond pi", {"robot.limits.root.upper": 3.2}, ["robot.limits.root", "pi"]),
    ("knee down, knee limits > 0", {"robot.knee.rb": "down"},
     ["robot.knee.rb", "'down'", "robot.limits.knee"]),
    ("knee up, knee limits < 0", {"robot.limits.knee.lower": -2.6,
                                  "robot.limits.knee.upper": -0.1},
     ["robot.knee.lf", "'up'", "robot.limits.knee"]),
    # unknown and missing legs
    ("unknown hip", {"robot.hips.lm": [0.0, 0.06, 0.0]}, ["robot.hips", "unknown ['lm']"]),
    ("unknown knee", {"robot.knee.xx": "up"}, ["robot.knee", "unknown ['xx']"]),
    ("missing yaw", {"robot.neutral_yaw.rb": DELETE}, ["robot.neutral_yaw", "missing ['rb']"]),
    ("leg renamed", {"robot.legs": ["lf", "lb", "rb", "lm"]},
     ["robot.hips", "missing ['lm']", "unknown ['rf']"]),
    ("unknown leg in group", {GROUPS: [["rf", "lb"], ["lf", "xx"]]},
     ["gait.gaits.diagonal", "xx"]),
    # gait groups not covering every leg exactly once
    ("group misses a leg", {GROUPS: [["rf", "lb"], ["lf"]]}, ["gait.gaits.diagonal", "once"]),
    ("leg in two groups", {GROUPS: [["rf", "lb"], ["lf", "rb", "lb"]]},
     ["gait.gaits.diagonal", "once"]),
    ("one group", {GROUPS: [["rf", "lb", "lf", "rb"]]}, [GROUPS, ">= 2"]),
    # profile fractions
    ("fractions sum 1.08", {"gait.profiles.smooth.lift": 0.3},
     ["gait.profiles.smooth", "summing to 1"]),
    ("fractions sum 0.9", {"gait.profiles.rest.arc": 0.4}, ["gait.profiles.rest", "summing to 1"]),
    ("fractions sum 1 + 1e-6", {"gait.profiles.rest.arc": 0.500001},
     ["gait.profiles.rest", "summing to 1"]),
    ("zero fraction", {"gait.profiles.rest.lift": 0.0, "gait.profiles.rest.arc": 0.75},
     ["gait.profiles.rest", "positive"]),
    ("negative fraction", {"gait.profiles.smooth.lower": -0.1,  # the sum is still 1
                           "gait.profiles.smooth.arc": 1.1 - SMOOTH_LIFT},
     ["gait.profiles.smooth", "positive"]),
    # body height
    ("height above range", {"robot.stance.body_height": 0.1},
     ["robot.stance.body_height", "body_height_range"]),
    ("height below range", {"robot.stance.body_height": 0.04},
     ["robot.stance.body_height", "body_height_range"]),
    ("range reversed", {"robot.body_height_range": [0.08, 0.06]},
     ["robot.stance.body_height", "body_height_range"]),
    ("range not positive", {"robot.body_height_range": [0.0, 0.09]}, ["robot.body_height_range"]),
    # a table's own keys
    ("zmp body on a crawl", {"gait.gaits.wave.body": "zmp"},
     ["gait.gaits.wave.body: zmp", "two feet on the ground"]),
    ("unknown body plan", {"gait.gaits.diagonal.body": "fast"},
     ["gait.gaits.diagonal.body must be one of ['plan', 'zmp']", "'fast'"]),
    ("unknown table stance profile", {"gait.gaits.diagonal.stance_profile": "glide"},
     ["gait.gaits.diagonal.stance_profile must be one of"]),
    ("table stride beyond max_stride", {"gait.gaits.diagonal.stride": 0.09},
     ["gait.gaits.diagonal.stride must be within [0, max_stride = 0.08] m", "0.09"]),
    ("negative table stride", {"gait.gaits.diagonal.stride": -0.01},
     ["gait.gaits.diagonal.stride must be >= 0"]),
]


def _parse(data: dict) -> None:
    """parse_robot + parse_gait on already-loaded data (top-level sections must exist)."""
    robot = parse_robot(data["robot"])
    parse_gait(data["gait"], robot.legs)


# a missing top-level section is only load_config's to report
BAD_CASES = [pytest.param(via, changes, expected, id=f"{name}-{via}")
             for name, changes, expected in BAD for via in ("parse", "load_config")
             if via == "load_config" or not {"robot", "gait"} & set(changes)]


@pytest.mark.parametrize(("via", "changes", "expected"), BAD_CASES)
def test_malformed_input_raises_config_error_naming_the_field(via, changes, expected, tmp_path):
    data = mutated(changes)
    if via == "parse":
        call = partial(_parse, data)
    else:
        call = partial(load_config, write(tmp_path, data))
    with pytest.raises(ConfigError) as err:
        call()
    message = str(err.value)
    for part in expected:
        assert part in message, f"{part!r} not in {message!r}"
    if via == "load_config":
        assert str(tmp_path) in message  # says which file


GOOD = [
    ("shipped", {}),
    ("height at range bottom", {"robot.stance.body_height": 0.05}),
    ("height at range top", {"robot.stance.body_height": 0.09}),
    ("no height range: fixed height", {"robot.body_height_range": DELETE}),
    ("fractions summing to 1 up to rounding",
     {"gait.profiles.smooth.lift": 0.7, "gait.profiles.smooth.arc": 0.2,  # sum 1 - 1.1e-16
      "gait.profiles.smooth.lower": 0.1}),
    ("knee down with negative knee limits",
     {"robot.knee.rb": "down", "robot.limits.knee.lower": -2.6}),
    ("limits at ±pi", {"robot.limits.root.lower": -math.pi, "robot.limits.root.upper": math.pi}),
    ("integer values", {"robot.neutral_yaw.lf": 2, "gait.swing_time": 2,
                        "robot.hips.lf": [0, 1, 0]}),
    ("no legs list: default order", {"robot.legs": DELETE}),
    ("three groups", {GROUPS: [["rf"], ["lb"], ["lf", "rb"]]}),
    ("a diagonal transfer", {"gait.gaits.diagonal.transfer_time": 0.3}),
    ("no diagonal transfer", {"gait.gaits.diagonal.transfer_time": 0.0}),
    ("a diagonal sway weight of 0", {"gait.gaits.diagonal.sway_weight": 0.0}),
    ("a gait swing time at the range's bottom", {"gait.gaits.wave.swing_time": 0.1}),
    ("a gait swing time at the range's top", {"gait.gaits.wave.swing_time": 5.0}),
    ("a zmp diagonal with the rest stance", {"gait.gaits.diagonal.body": "zmp",
                                             "gait.gaits.diagonal.stance_profile": "rest"}),
    ("a table stride at max_stride", {"gait.gaits.diagonal.stride": 0.08}),
]


@pytest.mark.parametrize("changes", [row[1] for row in GOOD], ids=[row[0] for row in GOOD])
def test_valid_variants_load(changes, tmp_path):
    data = mutated(changes)
    cfg = load_config(write(tmp_path, data))
    _parse(data)
    if "robot.stance.body_height" in changes:
        assert cfg.robot.body_height == changes["robot.stance.body_height"]
    if "robot.body_height_range" in changes:
        assert cfg.robot.body_height_range == (cfg.robot.body_height,) * 2
    if "robot.knee.rb" in changes:
        np.testing.assert_array_equal(cfg.robot.knee_sign, [1, 1, -1, 1])
    if GROUPS in changes:
        assert cfg.gait.gaits["diagonal"] == (("rf",), ("lb",), ("lf", "rb"))
    key = "gait.gaits.diagonal.transfer_time"
    shipped = {"diagonal_sway": 0.525}  # the shipped config's swaying diagonal gait
    assert cfg.gait.transfers == ({**shipped, "diagonal": changes[key]} if key in changes
                                  else shipped)
    key = "gait.gaits.diagonal.sway_weight"
    shipped = {"diagonal_sway": 0.025}
    assert cfg.gait.sway_weights == ({**shipped, "diagonal": changes[key]} if key in changes
                                     else shipped)
    key = "gait.gaits.wave.swing_time"
    shipped = {"diagonal_sway": 0.4, "diagonal_zmp": 0.5}
    assert cfg.gait.swings == ({**shipped, "wave": changes[key]} if key in changes
                               else shipped)
    assert cfg.gait.swing_time_of("wave") == changes.get(key, cfg.gait.swing_time)
    key = "gait.gaits.diagonal.stride"
    shipped = {"diagonal_zmp": 0.05}
    assert cfg.gait.strides == ({**shipped, "diagonal": changes[key]} if key in changes
                                else shipped)
    assert cfg.gait.stride_of("wave") == cfg.gait.stride
    zmp = {"diagonal_zmp"} | ({"diagonal"} if "gait.gaits.diagonal.body" in changes else set())
    assert cfg.gait.zmp_gaits == zmp
    profiles = {"diagonal_zmp": "continuous"}
    key = "gait.gaits.diagonal.stance_profile"
    assert cfg.gait.stance_profiles == ({**profiles, "diagonal": changes[key]}
                                        if key in changes else profiles)


def test_the_body_pose_limits_load():
    assert load_config().body_pose == BodyPoseConfig(max_shift=0.03, max_tilt=0.2, max_yaw=0.2,
                                                     speed=0.03, turn_rate=0.3)


@pytest.mark.parametrize(("changes", "expected"), [
    ({"body_pose": DELETE}, "missing section 'body_pose'"),
    ({"body_pose.max_tilt": DELETE}, "body_pose.max_tilt must be a number, got None"),
    ({"body_pose.speed": 0}, "body_pose.speed must be > 0"),
    ({"body_pose.max_shift": "wide"}, "body_pose.max_shift must be a number"),
    ({"body_pose.turn_rate": math.inf}, "body_pose.turn_rate must be finite"),
])
def test_bad_body_pose_limits_name_the_field(changes, expected, tmp_path):
    path = write(tmp_path, mutated(changes))
    with pytest.raises(ConfigError, match=expected) as err:
        load_config(path)
    assert str(path) in str(err.value)


# ---------------------------------------------------------------- unreadable files

def test_missing_file(tmp_path):
    path = tmp_path / "nope.yaml"
    with pytest.raises(ConfigError, match="cannot read config file") as err:
        load_config(path)
    assert str(path) in str(err.value)


def test_directory_instead_of_file(tmp_path):
    with pytest.raises(ConfigError, match="cannot read config file"):
        load_config(tmp_path)


def test_binary_file(tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_bytes(b"\xff\xfe\x00robot: 1\n")
    with pytest.raises(ConfigError, match=r"cannot read config file .*UTF-8"):
        load_config(path)


@pytest.mark.parametrize(("text", "expected"), [
    ("robot: [unclosed\n", "not valid YAML"),
    ("robot:\n\tlinks: 1\n", "not valid YAML"),  # tab indentation
    ("robot: {a: 1\ngait: 2\n", "not valid YAML"),
    ("", "must hold a mapping"),
    ("- robot\n- gait\n", "must hold a mapping"),
    ("just text\n", "must hold a mapping"),
])
def test_invalid_yaml(text, expected, tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match=expected) as err:
        load_config(path)
    assert str(path) in str(err.value)


@pytest.mark.parametrize("section, expected", [
    (None, 0.16), ({"width": 0.16}, 0.16), ({"width": 1.0}, 1.0), ({"width": 0.001}, 0.001),
])
def test_the_tool_width(section, expected):
    from crawler_motion.model.config import parse_tool_width

    assert parse_tool_width(section, "robot.yaml: tool") == expected


@pytest.mark.parametrize("section, words", [
    ({"width": 0.0}, "tool.width must be a number in (0, 1] m"),
    ({"width": 1.5}, "in (0, 1] m, got 1.5"), ({"width": "wide"}, "got 'wide'"),
    ({"width": 0.1, "depth": 2}, "the one key width"), (0.2, "the one key width"),
])
def test_a_bad_tool_width_is_refused_with_the_key(section, words):
    from crawler_motion.errors import ConfigError
    from crawler_motion.model.config import parse_tool_width

    with pytest.raises(ConfigError) as exc:
        parse_tool_width(section, "robot.yaml: tool")
    assert words in str(exc.value)


def test_the_shipped_tool_is_as_wide_as_the_hull():
    assert load_config().tool_width == 0.16
