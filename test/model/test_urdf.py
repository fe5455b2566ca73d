"""The generated URDF: well-formed, names and limits from the config, and the same kinematics.

The URDF's foot positions are computed here by an independent forward kinematics that reads
nothing but the XML (joint origins xyz/rpy and axis-angle rotations), and compared with
`crawler_motion.model.kinematics.forward_kinematics`.
"""

from __future__ import annotations

import copy
import itertools
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.model.config import RobotConfig, config_path, load_config, parse_robot
from crawler_motion.model.kinematics import forward_kinematics, inverse_kinematics
from crawler_motion.model.urdf import generate_urdf

ROBOT = load_config().robot
RAW = yaml.safe_load(config_path("robot.yaml").read_text(encoding="utf-8"))["robot"]


def make_robot(**changes: object) -> RobotConfig:
    """The shipped robot section with ``changes`` ('links.l2': 0.08, ...) applied."""
    data = copy.deepcopy(RAW)
    for dotted, value in changes.items():
        *parents, key = dotted.split(".")
        node = data
        for part in parents:
            node = node[part]
        node[key] = value
    return parse_robot(data)


# ---------------------------------------------------------------- independent URDF FK

def _floats(text: str | None, default: str = "0 0 0") -> np.ndarray:
    return np.array([float(v) for v in (text or default).split()])


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _rpy(rpy: np.ndarray) -> np.ndarray:
    """URDF rpy: fixed-axis roll about x, then pitch about y, then yaw about z."""
    return _rot_z(rpy[2]) @ _rot_y(rpy[1]) @ _rot_x(rpy[0])


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula."""
    k = axis / np.linalg.norm(axis)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * cross + (1 - math.cos(angle)) * cross @ cross


def _frame(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = rotation
    t[:3, 3] = translation
    return t


class Urdf:
    """Just enough of a URDF model for the checks here."""

    def __init__(self, text: str) -> None:
        self.root = ET.fromstring(text)
        self.links = [link.get("name") for link in self.root.findall("link")]
        self.joints = self.root.findall("joint")
        self.by_child = {j.find("child").get("link"): j for j in self.joints}
        self.base = next(link for link in self.links if link not in self.by_child)

    def joint(self, name: str) -> ET.Element:
        return next(j for j in self.joints if j.get("name") == name)

    def pose(self, link: str, q: dict[str, float]) -> np.ndarray:
        """4x4 transform base <- link for joint positions ``q`` (missing joints at 0)."""
        chain = []
        while link != self.base:
            joint = self.by_child[link]
            chain.append(joint)
            link = joint.find("parent").get("link")
        t = np.eye(4)
        for joint in reversed(chain):
            origin = joint.find("origin")
            xyz = _floats(None if origin is None else origin.get("xyz"))
            rpy = _floats(None if origin is None else origin.get("rpy"))
            t = t @ _frame(_rpy(rpy), xyz)
            if joint.get("type") in ("revolute", "continuous"):
                axis = _floats(joint.find("axis").get("xyz"), "1 0 0")
                t = t @ _frame(_axis_angle(axis, q.get(joint.get("name"), 0.0)), np.zeros(3))
            else:
                assert joint.get("type") == "fixed"
        return t

    def feet(self, robot: RobotConfig, angles: np.ndarray) -> np.ndarray:
        """Foot link origins ``(n_legs, 3)`` for angles ``(n_legs, 3)`` in config order."""
        q = dict(zip(robot.joint_names, np.asarray(angles, dtype=float).ravel(), strict=True))
        return np.array([self.pose(f"{leg}_foot", q)[:3, 3] for leg in robot.legs])


MODEL = Urdf(generate_urdf(ROBOT))


def assert_urdf_matches_fk(robot: RobotConfig, model: Urdf, angles: np.ndarray) -> None:
    np.testing.assert_allclose(model.feet(robot, angles), forward_kinematics(robot, angles),
                               rtol=0, atol=1e-12)


# ---------------------------------------------------------------- structure

def test_well_formed_tree_with_one_root():
    text = generate_urdf(ROBOT)
    assert text.startswith('<?xml version="1.0"?>')
    model = MODEL
    assert model.root.tag == "robot" and model.root.get("name") == ROBOT.name
    assert len(model.links) == len(set(model.links))
    names = [j.get("name") for j in model.joints]
    assert len(names) == len(set(names))
    children = [j.find("child").get("link") for j in model.joints]
    assert len(children) == len(set(children)), "a link with two parents"
    for joint in model.joints:
        assert joint.find("parent").get("link") in model.links, joint.get("name")
        assert joint.find("child").get("link") in model.links, joint.get("name")
    roots = [link for link in model.links if link not in children]
    assert roots == ["base_link"]
    # every link reaches the root (so there is no cycle and no second tree)
    for link in model.links:
        seen = set()
        while link != "base_link":
            assert link not in seen, "cycle"
            seen.add(link)
            link = model.by_child[link].find("parent").get("link")
    expected = {"base_link", "base_inertia"} | {
        f"{leg}_{part}" for leg in ROBOT.legs for part in ("coxa", "femur", "tibia", "foot")}
    assert set(model.links) == expected


def test_visuals_materials_and_inertials_are_sane():
    model = MODEL
    materials = {m.get("name") for m in model.root.findall("material")}
    for link in model.root.findall("link"):
        for visual in link.findall("visual"):
            assert visual.find("material").get("name") in materials
            shape = next(iter(visual.find("geometry")))
            assert shape.tag in ("box", "cylinder", "sphere")
            for attribute in ("size", "radius", "length"):
                if shape.get(attribute) is not None:
                    assert np.all(_floats(shape.get(attribute)) > 0)
        inertial = link.find("inertial")
        if link.get("name") == "base_link":
            assert inertial is None  # KDL ignores and warns about inertia on the root link
            assert link.find("visual") is not None
            continue
        mass = float(inertial.find("mass").get("value"))
        assert 0 < mass < 5.0
        i = inertial.find("inertia")
        ixx, iyy, izz = (float(i.get(k)) for k in ("ixx", "iyy", "izz"))
        assert min(ixx, iyy, izz) > 0
        # principal moments of a real body satisfy the triangle inequality
        assert ixx + iyy >= izz and iyy + izz >= ixx and izz + ixx >= iyy
    body = float(model.root.find("link[@name='base_inertia']/inertial/mass").get("value"))
    legs = sum(float(m.get("value")) for m in model.root.findall("link/inertial/mass")) - body
    assert 0.1 < body < 5.0 and legs < body


def test_joint_names_order_types_axes_limits_from_config():
    model = MODEL
    movable = [j for j in model.joints if j.get("type") != "fixed"]
    assert [j.get("name") for j in movable] == list(ROBOT.joint_names)
    axes = {"root": [0, 0, 1], "shoulder": [0, -1, 0], "knee": [0, 1, 0]}
    for joint in movable:
        kind = joint.get("name").split("_")[-2]
        k = ["root", "shoulder", "knee"].index(kind)
        assert joint.get("type") == "revolute"
        np.testing.assert_array_equal(_floats(joint.find("axis").get("xyz")), axes[kind])
        limit = joint.find("limit")
        assert float(limit.get("lower")) == ROBOT.lower[k]
        assert float(limit.get("upper")) == ROBOT.upper[k]
        assert float(limit.get("velocity")) == ROBOT.velocity[k]
        assert float(limit.get("effort")) == ROBOT.effort[k]
    fixed = sorted(j.get("name") for j in model.joints if j.get("type") == "fixed")
    assert fixed == sorted(["base_inertia_joint", *(f"{leg}_foot_joint" for leg in ROBOT.legs)])


@pytest.mark.parametrize("leg", range(4))
def test_joint_origins_from_config(leg):
    model = MODEL
    name = ROBOT.legs[leg]
    root = model.joint(f"{name}_root_joint")
    assert root.find("parent").get("link") == "base_link"
    np.testing.assert_array_equal(_floats(root.find("origin").get("xyz")), ROBOT.hips[leg])
    np.testing.assert_array_equal(_floats(root.find("origin").get("rpy")),
                                  [0, 0, ROBOT.neutral_yaw[leg]])
    for joint, parent, child, length in [("shoulder", "coxa", "femur", ROBOT.l1),
                                         ("knee", "femur", "tibia", ROBOT.l2),
                                         ("foot", "tibia", "foot", ROBOT.l3)]:
        element = model.joint(f"{name}_{joint}_joint")
        assert element.find("parent").get("link") == f"{name}_{parent}"
        assert element.find("child").get("link") == f"{name}_{child}"
        np.testing.assert_array_equal(_floats(element.find("origin").get("xyz")), [length, 0, 0])
        np.testing.assert_array_equal(_floats(element.find("origin").get("rpy")), [0, 0, 0])


# ---------------------------------------------------------------- FK agreement

def _pose_table() -> dict[str, np.ndarray]:
    poses = {
        "zero": np.zeros((4, 3)),
        "standing": inverse_kinematics(ROBOT, ROBOT.standing_feet()),
        "standing low": inverse_kinematics(ROBOT, ROBOT.standing_feet(0.05)),
        "standing high": inverse_kinematics(ROBOT, ROBOT.standing_feet(0.09)),
        "lower limits": np.tile(ROBOT.lower, (4, 1)),
        "upper limits": np.tile(ROBOT.upper, (4, 1)),
    }
    corners = list(itertools.product(*zip(ROBOT.lower, ROBOT.upper, strict=True)))
    for i in range(0, len(corners), 4):  # every corner, four legs at a time
        poses[f"corners {i}-{i + 3}"] = np.array(corners[i:i + 4])
    return poses


POSES = _pose_table()


@pytest.mark.parametrize("name", list(POSES))
def test_foot_positions_match_fk_on_pose_table(name):
    assert_urdf_matches_fk(ROBOT, MODEL, POSES[name])


def test_standing_feet_are_where_the_config_puts_them():
    model = MODEL
    np.testing.assert_allclose(model.feet(ROBOT, POSES["standing"]), ROBOT.standing_feet(),
                               rtol=0, atol=1e-12)


def angles_within(robot: RobotConfig):
    columns = [st.floats(float(lo), float(hi)) for lo, hi in zip(robot.lower, robot.upper,
                                                                  strict=True)]
    return st.lists(st.tuples(*columns), min_size=4, max_size=4).map(np.array)


@settings(max_examples=100, deadline=None)
@given(angles=angles_within(ROBOT))
def test_foot_positions_match_fk_for_random_angles(angles):
    assert_urdf_matches_fk(ROBOT, MODEL, angles)


@settings(max_examples=40, deadline=None)
@given(angles=angles_within(ROBOT))
def test_every_link_frame_lies_on_the_fk_leg(angles):
    """Knee and shoulder frames too: the coxa/femur geometry, not only the end point, agrees."""
    model = MODEL
    q = dict(zip(ROBOT.joint_names, angles.ravel(), strict=True))
    for i, leg in enumerate(ROBOT.legs):
        root, shoulder, _ = angles[i]
        yaw = ROBOT.neutral_yaw[i] + root
        out = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        shoulder_at = ROBOT.hips[i] + ROBOT.l1 * out
        knee_at = shoulder_at + ROBOT.l2 * (math.cos(shoulder) * out
                                            + math.sin(shoulder) * np.array([0, 0, 1.0]))
        np.testing.assert_allclose(model.pose(f"{leg}_coxa", q)[:3, 3], ROBOT.hips[i], atol=1e-12)
        np.testing.assert_allclose(model.pose(f"{leg}_femur", q)[:3, 3], shoulder_at, atol=1e-12)
        np.testing.assert_allclose(model.pose(f"{leg}_tibia", q)[:3, 3], knee_at, atol=1e-12)


@pytest.mark.parametrize(("joint", "expect"), [
    ("root", lambda before, after, out: np.cross(out, after - before)[2] > 0),
    ("shoulder", lambda before, after, out: after[2] > before[2]),
    ("knee", lambda before, after, out: after[2] < before[2]),
])
def test_positive_joint_motion_matches_the_documented_signs(joint, expect):
    """From the XML alone: + root turns CCW seen from above, + shoulder raises, + knee lowers."""
    model = MODEL
    for i, leg in enumerate(ROBOT.legs):
        q = {f"{leg}_knee_joint": 0.5}
        before = model.pose(f"{leg}_foot", q)[:3, 3]
        q[f"{leg}_{joint}_joint"] = q.get(f"{leg}_{joint}_joint", 0.0) + 1e-3
        after = model.pose(f"{leg}_foot", q)[:3, 3]
        out = np.array([math.cos(ROBOT.neutral_yaw[i]), math.sin(ROBOT.neutral_yaw[i]), 0.0])
        assert expect(before, after, out), leg


# ---------------------------------------------------------------- generated from the config

VARIANTS = {
    "longer femur": {"links.l2": 0.08},
    "other coxa and tibia": {"links.l1": 0.045, "links.l3": 0.11, "stance.reach": 0.15},
    "moved hips": {"hips.lf": [0.13, 0.05, 0.01], "hips.lb": [-0.08, 0.07, -0.005],
                   "hips.rb": [-0.12, -0.04, 0.0], "hips.rf": [0.09, -0.065, 0.02]},
    "splayed legs": {"neutral_yaw.lf": 0.7853981633974483, "neutral_yaw.lb": 2.356194490192345,
                     "neutral_yaw.rb": -2.356194490192345, "neutral_yaw.rf": -0.7853981633974483},
    "knee-down legs": {"knee.lf": "down", "knee.rb": "down", "limits.knee.lower": -2.6,
                       "limits.knee.upper": 2.6, "limits.shoulder.lower": -1.6},
    "other limits": {"limits.root.lower": -0.5, "limits.shoulder.upper": 1.1,
                     "limits.knee.velocity": 3.5, "limits.root.effort": 2.25},
    "renamed": {"name": "crawler_b", "legs": ["fl", "bl", "br", "fr"],
                **{section: {new: RAW[section][old]
                             for old, new in zip(RAW["legs"], ["fl", "bl", "br", "fr"],
                                                 strict=True)}
                   for section in ("hips", "neutral_yaw", "knee")}},
}


def _variant(name: str) -> RobotConfig:
    return make_robot(**VARIANTS[name])


@pytest.mark.parametrize("name", list(VARIANTS))
def test_modified_config_still_agrees(name):
    robot = _variant(name)
    text = generate_urdf(robot)
    assert text != generate_urdf(ROBOT)
    model = Urdf(text)
    movable = [j for j in model.joints if j.get("type") != "fixed"]
    assert [j.get("name") for j in movable] == list(robot.joint_names)
    for k, joint in enumerate(movable):
        limit = joint.find("limit")
        assert float(limit.get("lower")) == robot.lower[k % 3]
        assert float(limit.get("upper")) == robot.upper[k % 3]
        assert float(limit.get("velocity")) == robot.velocity[k % 3]
        assert float(limit.get("effort")) == robot.effort[k % 3]
    standing = inverse_kinematics(robot, robot.standing_feet())
    np.testing.assert_array_equal(np.sign(standing[:, 2]), robot.knee_sign)
    np.testing.assert_allclose(model.feet(robot, standing), robot.standing_feet(), atol=1e-12)
    rng = np.random.default_rng(7)
    for angles in rng.uniform(robot.lower, robot.upper, size=(25, 4, 3)):
        assert_urdf_matches_fk(robot, model, angles)


def test_knee_down_leg_has_its_knee_below_the_shoulder_foot_line_in_the_urdf():
    robot = _variant("knee-down legs")
    model = Urdf(generate_urdf(robot))
    q = dict(zip(robot.joint_names, inverse_kinematics(robot, robot.standing_feet()).ravel(),
                 strict=True))
    for i, leg in enumerate(robot.legs):
        shoulder = model.pose(f"{leg}_femur", q)[:3, 3]
        knee = model.pose(f"{leg}_tibia", q)[:3, 3]
        foot = model.pose(f"{leg}_foot", q)[:3, 3]
        assert np.linalg.norm(foot[:2] - shoulder[:2]) > 0.05  # foot well out from the shoulder
        t = np.dot(knee - shoulder, foot - shoulder) / np.dot(foot - shoulder, foot - shoulder)
        closest = shoulder + t * (foot - shoulder)  # point of the shoulder-foot line nearest
        assert np.sign(knee[2] - closest[2]) == robot.knee_sign[i], leg


# ---------------------------------------------------------------- calibrated legs

@pytest.mark.parametrize("seed", [3, 11])
def test_calibrated_urdf_foot_positions_equal_the_calibrated_fk(seed):
    from crawler_motion.calibration.synthetic import perturbed_robot

    robot = perturbed_robot(ROBOT, seed)
    model = Urdf(generate_urdf(robot))
    rng = np.random.default_rng(seed)
    for angles in rng.uniform(robot.lower, robot.upper, size=(25, 4, 3)):
        assert_urdf_matches_fk(robot, model, angles)
        # the calibrated URDF is not the nominal one: the feet differ by assembly errors
        assert np.abs(model.feet(robot, angles) - forward_kinematics(ROBOT, angles)).max() > 5e-4
