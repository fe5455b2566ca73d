"""URDF of the crawler, generated from the same `RobotConfig` as the kinematics (pure, no rclpy).

``generate_urdf(robot)`` returns the URDF text for ``robot_state_publisher`` (parameter
``robot_description``), RViz and URDF parsers. Nothing is hand-written: hips, neutral yaws,
link lengths and joint limits all come from ``config/robot.yaml``, so the model cannot drift from
the IK.

Tree (one root, ``base_link``; ``<leg>`` is each name of ``robot.legs``)::

    base_link ─ base_inertia_joint (fixed) ─ base_inertia
              ─ <leg>_root_joint     (revolute, at the hip, rpy = (0, 0, neutral yaw), axis +z)
                ─ <leg>_coxa ─ <leg>_shoulder_joint (revolute, at (l1, 0, 0), axis (0, -1, 0))
                  ─ <leg>_femur ─ <leg>_knee_joint  (revolute, at (l2, 0, 0), axis (0, +1, 0))
                    ─ <leg>_tibia ─ <leg>_foot_joint (fixed, at (l3, 0, 0))
                      ─ <leg>_foot  (origin = foot tip, the point the IK places)

Joint conventions, identical to `crawler_motion.model.kinematics` (and so to the driver):

- zero: every leg stretched straight out and horizontal along its neutral yaw; every child
  frame then has x along the leg, z up;
- root: + is yaw counter-clockwise seen from above (rotation about +z of the hip frame, which is
  already turned by the neutral yaw), so the leg's heading is ``neutral_yaw + root``;
- shoulder: + raises the femur. A rotation by +θ about (0, -1, 0) takes the leg's x axis to
  (cos θ, 0, sin θ), i.e. upwards;
- knee: + bends the tibia down relative to the femur. A rotation by +θ about (0, +1, 0) takes
  x to (cos θ, 0, -sin θ), so the tibia's elevation is ``shoulder - knee`` as in the FK.

Calibrated legs (``robot.geometry``, `crawler_motion.model.leg_geometry`): each joint's origin
and rpy are its frame from `leg_geometry.joint_frames` (hip error, axis tilts and joint zero
offsets folded in), the foot joint sits at the chain's foot tip; axes stay the ones above.

Knee "down" legs (``knee_sign = -1``) need nothing special here: the knee configuration is
only the IK's choice of branch, the joint is the same and the same angle means the same pose;
a knee-down leg simply runs at negative knee angles (the config refuses knee limits that do not
allow them). Joint limits, velocities and efforts are the config's, identical for every leg.

Geometry for display: the body is a box spanning the hips; links are cylinders along x, the foot
a sphere. Masses and inertias are those of these solids at the density of water (the robot is
close to neutrally buoyant), so they are small and plausible rather than measured. The body's
inertia sits on ``base_inertia`` (fixed to ``base_link``) because KDL, used by
``robot_state_publisher``, ignores and warns about an inertia on the root link.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

from crawler_motion.model.config import JOINT_KINDS, RobotConfig
from crawler_motion.model.leg_geometry import JointFrames, joint_frames

#: Density of every solid [kg/m³] (water: an underwater robot is about neutrally buoyant).
DENSITY = 1000.0
#: Axis of each joint kind in its own (parent-side) frame.
JOINT_AXES: dict[str, tuple[int, int, int]] = {
    "root": (0, 0, 1),
    "shoulder": (0, -1, 0),
    "knee": (0, 1, 0),
}
_COLOURS = {
    "body": (0.35, 0.40, 0.45, 1.0),
    "leg": (0.95, 0.55, 0.10, 1.0),
    "foot": (0.10, 0.10, 0.10, 1.0),
}


def _num(value: float) -> str:
    """Shortest text that reads back as exactly the same float (and never ``-0.0``)."""
    return repr(float(value) + 0.0)


def _vec(values: tuple[float, ...] | np.ndarray) -> str:
    return " ".join(_num(v) for v in values)


def _origin(parent: ET.Element, xyz: tuple[float, ...] | np.ndarray = (0.0, 0.0, 0.0),
            rpy: tuple[float, ...] = (0.0, 0.0, 0.0)) -> None:
    ET.SubElement(parent, "origin", xyz=_vec(xyz), rpy=_vec(rpy))


def _shape(link: ET.Element, geometry: tuple[str, dict[str, str]], material: str,
           xyz: tuple[float, ...], rpy: tuple[float, ...]) -> None:
    """Add a visual (with material) and an identical collision element."""
    for tag in ("visual", "collision"):
        element = ET.SubElement(link, tag)
        _origin(element, xyz, rpy)
        geom = ET.SubElement(element, "geometry")
        ET.SubElement(geom, geometry[0], geometry[1])
        if tag == "visual":
            ET.SubElement(element, "material", name=material)


def _inertial(link: ET.Element, mass: float, diagonal: tuple[float, float, float],
              xyz: tuple[float, ...]) -> None:
    inertial = ET.SubElement(link, "inertial")
    _origin(inertial, xyz)
    ET.SubElement(inertial, "mass", value=_num(mass))
    ixx, iyy, izz = diagonal
    ET.SubElement(inertial, "inertia", ixx=_num(ixx), ixy="0.0", ixz="0.0", iyy=_num(iyy),
                  iyz="0.0", izz=_num(izz))


def _rod(robot_el: ET.Element, name: str, length: float, radius: float) -> None:
    """A link drawn as a solid cylinder from its origin along +x."""
    link = ET.SubElement(robot_el, "link", name=name)
    centre = (length / 2, 0.0, 0.0)
    along_x = (0.0, math.pi / 2, 0.0)  # URDF cylinders lie along z
    _shape(link, ("cylinder", {"radius": _num(radius), "length": _num(length)}), "leg",
           centre, along_x)
    mass = DENSITY * math.pi * radius**2 * length
    axial = mass * radius**2 / 2
    transverse = mass * (3 * radius**2 + length**2) / 12
    _inertial(link, mass, (axial, transverse, transverse), centre)


def _joint(robot_el: ET.Element, name: str, kind: str, parent: str, child: str,
           xyz: tuple[float, ...] | np.ndarray, rpy: tuple[float, ...] = (0.0, 0.0, 0.0)
           ) -> ET.Element:
    joint = ET.SubElement(robot_el, "joint", name=name, type=kind)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    _origin(joint, xyz, rpy)
    return joint


def _rpy(rotation: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw [rad] (R = Rz(yaw) Ry(pitch) Rx(roll)) of a rotation matrix."""
    pitch = math.asin(max(-1.0, min(1.0, -float(rotation[2, 0]))))
    return (math.atan2(float(rotation[2, 1]), float(rotation[2, 2])), pitch,
            math.atan2(float(rotation[1, 0]), float(rotation[0, 0])))


def calibrated_frames(robot: RobotConfig, leg: int) -> JointFrames | None:
    """The joint frames of a calibrated leg (`leg_geometry.joint_frames`), None for a leg
    with the nominal geometry (whose frames are the exact numbers of robot.yaml)."""
    geometry = robot.geometry
    if geometry is None or geometry.nominal_legs[leg]:
        return None
    return joint_frames(geometry.params[leg], robot.hips[leg], float(robot.neutral_yaw[leg]))


def link_radius(robot: RobotConfig) -> float:
    """Radius of the links [m]: 4 % of the leg length (the simulator reads it from the URDF)."""
    return 0.04 * (robot.l1 + robot.l2 + robot.l3)


def foot_sphere_radius(robot: RobotConfig) -> float:
    """Radius of the foot sphere [m], 1.2 link radii, centred on the point the IK places; the
    planner's contact model (`crawler_motion.motion.contact`) uses the same."""
    return 1.2 * link_radius(robot)


def generate_urdf(robot: RobotConfig) -> str:
    """URDF (XML text) of ``robot``; see the module docstring for frames and conventions."""
    hips = np.asarray(robot.hips, dtype=float)
    radius = link_radius(robot)  # links: 7.2 mm for the shipped 0.18 m leg
    foot_radius = foot_sphere_radius(robot)

    root = ET.Element("robot", name=robot.name)
    root.append(ET.Comment(" Generated by crawler_motion.model.urdf from the robot configuration. "
                           "Do not edit: edit config/robot.yaml. "))
    for material, rgba in _COLOURS.items():
        ET.SubElement(ET.SubElement(root, "material", name=material), "color", rgba=_vec(rgba))

    # Body: a box spanning the hips (at least a few leg radii in every direction).
    size = (max(2 * float(np.max(np.abs(hips[:, 0]))), 4 * radius),
            max(2 * float(np.max(np.abs(hips[:, 1]))), 4 * radius))
    size = (*size, max(0.25 * min(size), 2 * radius))
    base = ET.SubElement(root, "link", name="base_link")
    _shape(base, ("box", {"size": _vec(size)}), "body", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    body_inertia = ET.SubElement(root, "link", name="base_inertia")
    mass = DENSITY * size[0] * size[1] * size[2]
    sx, sy, sz = (s**2 for s in size)
    _inertial(body_inertia, mass, (mass * (sy + sz) / 12, mass * (sx + sz) / 12,
                                   mass * (sx + sy) / 12), (0.0, 0.0, 0.0))
    _joint(root, "base_inertia_joint", "fixed", "base_link", "base_inertia", (0.0, 0.0, 0.0))

    links = {"root": "coxa", "shoulder": "femur", "knee": "tibia"}
    offsets = {"root": None, "shoulder": robot.l1, "knee": robot.l2}
    lengths = {"coxa": robot.l1, "femur": robot.l2, "tibia": robot.l3}
    for i, leg in enumerate(robot.legs):
        parent = "base_link"
        frames = calibrated_frames(robot, i)
        foot_xyz = (robot.l3, 0.0, 0.0) if frames is None else frames.foot_tip
        for j, kind in enumerate(JOINT_KINDS):
            child = f"{leg}_{links[kind]}"
            offset = offsets[kind]
            if frames is not None:  # calibrated leg: its joint frames, zero offsets included
                xyz, rpy = frames.origins[j], _rpy(frames.rotations[j])
            elif offset is None:  # root joint: at the hip, turned to the leg's neutral direction
                xyz, rpy = hips[i], (0.0, 0.0, float(robot.neutral_yaw[i]))
            else:
                xyz, rpy = (offset, 0.0, 0.0), (0.0, 0.0, 0.0)
            joint = _joint(root, f"{leg}_{kind}_joint", "revolute", parent, child, xyz, rpy)
            ET.SubElement(joint, "axis", xyz=" ".join(str(a) for a in JOINT_AXES[kind]))
            ET.SubElement(joint, "limit", lower=_num(robot.lower[j]), upper=_num(robot.upper[j]),
                          effort=_num(robot.effort[j]), velocity=_num(robot.velocity[j]))
            _rod(root, child, lengths[links[kind]], radius)
            parent = child
        foot = ET.SubElement(root, "link", name=f"{leg}_foot")
        _shape(foot, ("sphere", {"radius": _num(foot_radius)}), "foot", (0.0, 0.0, 0.0),
               (0.0, 0.0, 0.0))
        foot_mass = DENSITY * 4 / 3 * math.pi * foot_radius**3
        foot_i = 0.4 * foot_mass * foot_radius**2
        _inertial(foot, foot_mass, (foot_i, foot_i, foot_i), (0.0, 0.0, 0.0))
        _joint(root, f"{leg}_foot_joint", "fixed", parent, f"{leg}_foot", foot_xyz)

    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
