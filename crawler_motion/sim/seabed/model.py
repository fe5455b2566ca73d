"""MJCF model of the crawler on a seabed, generated from `RobotConfig` plus a world file.

Bodies and joints follow the URDF (`crawler_motion.model.urdf`) and the kinematics exactly:
``base_link`` (free joint, hull box) carries per leg ``<leg>_coxa`` (root hinge at the hip,
turned by the neutral yaw, axis +z), ``<leg>_femur`` (shoulder hinge at (l1, 0, 0), axis
(0, -1, 0)) and ``<leg>_tibia`` (knee hinge at (l2, 0, 0), axis (0, +1, 0)) with the foot sphere
and the site ``<leg>_foot`` at (l3, 0, 0), the point the IK places. Links are capsules and the
foot a sphere with the URDF's radii. Robot geoms are in geom group ``robot_group`` and collide
with the world but not with each other. Every joint has a position servo (kp, kv, force range =
the joint's effort limit) in joint order, so ``data.ctrl`` is the flattened ``(n_legs, 3)``
joint target [rad].
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from crawler_motion.errors import ConfigError
from crawler_motion.model.config import JOINT_KINDS, RobotConfig
from crawler_motion.model.kinematics import inverse_kinematics
from crawler_motion.model.urdf import JOINT_AXES, calibrated_frames, generate_urdf
from crawler_motion.sim.seabed.water import WaterSettings, check_range
from crawler_motion.sim.seabed.world import World, load_world

INTEGRATORS = ("euler", "implicit", "implicitfast", "RK4")
CONES = ("elliptic", "pyramidal")
GRAVITY = 9.81  # [m/s²]
_LINKS = {"root": "coxa", "shoulder": "femur", "knee": "tibia"}
#: Sensors of the site ``imu`` at the base_link origin, after the feet's 6 values per leg:
#: angular velocity [rad/s] and specific force [m/s²] in base_link, orientation (w, x, y, z).
IMU_SENSORS = ("imu_gyro", "imu_accelerometer", "imu_framequat")


@dataclass(frozen=True)
class SimSettings:
    """Physics settings of the seabed model (SI units); defaults are the measured ones."""

    timestep: float = 0.0005  # [s]
    integrator: str = "implicitfast"
    cone: str = "elliptic"
    impratio: float = 10.0
    friction: float = 0.8  # sliding friction coefficient, robot and seabed
    solref: tuple[float, float] = (0.005, 1.0)  # contact time constant [s], damping ratio
    kp: float = 100.0  # servo stiffness [N m/rad]
    kv: float = 1.0  # servo damping [N m s/rad]
    armature: float = 0.005  # joint armature [kg m²]
    hull_size: tuple[float, float, float] = (0.24, 0.16, 0.05)  # hull box [m]
    mass: float = 3.0  # dry mass of the whole robot [kg]
    leg_density: float = 1000.0  # density of the leg solids [kg/m³]
    robot_group: int = 2  # geom group of the robot's own geoms (ignored by the scanner)
    spawn_clearance: float = 0.002  # feet above z = 0 at the start [m]
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)  # x [m], y [m], yaw [rad]
    water: WaterSettings = field(default_factory=WaterSettings)

    def __post_init__(self) -> None:
        if self.integrator not in INTEGRATORS:
            raise ConfigError(f"integrator must be one of {list(INTEGRATORS)}, "
                              f"got {self.integrator!r}")
        if self.cone not in CONES:
            raise ConfigError(f"cone must be one of {list(CONES)}, got {self.cone!r}")
        check_range("timestep", self.timestep, 1e-5, 0.0025, "s")
        if len(self.solref) != 2:
            raise ConfigError(f"solref must be [time constant, damping ratio], got "
                              f"{self.solref!r}")
        check_range("solref time constant", self.solref[0], 2 * self.timestep, 1.0, "s")
        check_range("solref damping ratio", self.solref[1], 0.1, 10.0, "")
        check_range("impratio", self.impratio, 1.0, 100.0, "")
        check_range("friction", self.friction, 0.01, 5.0, "")
        check_range("kp", self.kp, 1e-3, 1e5, "N m/rad")
        check_range("kv", self.kv, 0.0, 1e3, "N m s/rad")
        check_range("armature", self.armature, 0.0, 1.0, "kg m²")
        check_range("mass", self.mass, 0.01, 1000.0, "kg")
        check_range("leg_density", self.leg_density, 1.0, 20000.0, "kg/m³")
        check_range("spawn_clearance", self.spawn_clearance, 0.0, 0.5, "m")
        if len(self.hull_size) != 3 or len(self.start_pose) != 3:
            raise ConfigError("hull_size must be [x, y, z] in m and start_pose [x, y, yaw]")
        for value in self.hull_size:
            check_range("hull_size", value, 1e-3, 10.0, "m")
        for value in self.start_pose:
            check_range("start_pose", value, -1e3, 1e3, "m or rad")
        if isinstance(self.robot_group, bool) or self.robot_group not in range(6):
            raise ConfigError(f"robot_group must be an integer in [0, 5], got "
                              f"{self.robot_group!r}")


def link_radii(robot: RobotConfig) -> tuple[float, float]:
    """Link (capsule) and foot (sphere) radii [m], read from the package URDF."""
    root = ET.fromstring(generate_urdf(robot))
    link = root.find(f"link[@name='{robot.legs[0]}_tibia']/collision/geometry/cylinder")
    foot = root.find(f"link[@name='{robot.legs[0]}_foot']/collision/geometry/sphere")
    assert link is not None and foot is not None, "URDF lost its tibia or foot geometry"
    return float(link.get("radius", "nan")), float(foot.get("radius", "nan"))


def _num(value: float) -> str:
    return repr(float(value) + 0.0)


def _vec(values: object) -> str:
    return " ".join(_num(v) for v in np.asarray(values, dtype=float).ravel())


def _capsule_volume(radius: float, length: float) -> float:
    return math.pi * radius**2 * length + 4.0 / 3.0 * math.pi * radius**3


def _leg(parent: ET.Element, robot: RobotConfig, i: int, s: SimSettings,
         radii: tuple[float, float]) -> None:
    """The three bodies, joints and geoms of leg ``i`` under ``parent``."""
    leg, (radius, foot_radius) = robot.legs[i], radii
    robot_geom = {"group": str(s.robot_group), "contype": "2", "conaffinity": "1",
                  "density": _num(s.leg_density)}
    gravcomp = _num(s.water.buoyancy_fraction)
    lengths = {"coxa": robot.l1, "femur": robot.l2, "tibia": robot.l3}
    body = parent
    frames = calibrated_frames(robot, i)
    tip = (robot.l3, 0, 0) if frames is None else frames.foot_tip
    for j, kind in enumerate(JOINT_KINDS):
        link = _LINKS[kind]
        if frames is not None:  # calibrated leg: its joint frames (columns x, y as xyaxes)
            pose = {"pos": _vec(frames.origins[j]),
                    "xyaxes": _vec(frames.rotations[j][:, :2].T)}
        elif kind == "root":
            pose = {"pos": _vec(robot.hips[i]), "euler": _vec((0.0, 0.0, robot.neutral_yaw[i]))}
        else:
            pose = {"pos": _vec((lengths["coxa" if kind == "shoulder" else "femur"], 0, 0)),
                    "euler": _vec((0, 0, 0))}
        body = ET.SubElement(body, "body", name=f"{leg}_{link}", **pose, gravcomp=gravcomp)
        ET.SubElement(body, "joint", name=f"{leg}_{kind}_joint", type="hinge",
                      axis=_vec(JOINT_AXES[kind]), armature=_num(s.armature),
                      range=_vec((robot.lower[j], robot.upper[j])))
        ET.SubElement(body, "geom", name=f"{leg}_{link}", type="capsule",
                      fromto=_vec((0, 0, 0, lengths[link], 0, 0)), size=_num(radius),
                      rgba="0.95 0.55 0.1 1", **robot_geom)
    ET.SubElement(body, "geom", name=f"{leg}_foot", type="sphere", pos=_vec(tip),
                  size=_num(foot_radius), rgba="0.1 0.1 0.1 1", **robot_geom)
    ET.SubElement(body, "site", name=f"{leg}_foot", pos=_vec(tip),
                  size=_num(0.5 * foot_radius), group=str(s.robot_group))


def _hull_mass(robot: RobotConfig, s: SimSettings, radii: tuple[float, float]) -> float:
    radius, foot_radius = radii
    legs = sum(_capsule_volume(radius, length) for length in (robot.l1, robot.l2, robot.l3))
    legs += 4.0 / 3.0 * math.pi * foot_radius**3
    hull = s.mass - robot.n_legs * s.leg_density * legs
    if hull <= 0.0:
        raise ConfigError(f"mass = {s.mass} kg does not exceed the legs' "
                          f"{s.mass - hull:.3f} kg; raise mass or lower leg_density")
    return hull


def _robot_body(worldbody: ET.Element, robot: RobotConfig, s: SimSettings) -> None:
    radii = link_radii(robot)
    x, y, yaw = s.start_pose
    z = -float(robot.standing_feet()[:, 2].min()) + radii[1] + s.spawn_clearance
    base = ET.SubElement(worldbody, "body", name="base_link", pos=_vec((x, y, z)),
                         euler=_vec((0, 0, yaw)), gravcomp=_num(s.water.buoyancy_fraction))
    ET.SubElement(base, "freejoint", name="base")
    ET.SubElement(base, "geom", name="hull", type="box", size=_vec(np.array(s.hull_size) / 2),
                  mass=_num(_hull_mass(robot, s, radii)), group=str(s.robot_group),
                  contype="2", conaffinity="1", rgba="0.35 0.4 0.45 1")
    ET.SubElement(base, "site", name="imu", group=str(s.robot_group))
    for i in range(robot.n_legs):
        _leg(base, robot, i, s, radii)


def build_mjcf(robot: RobotConfig, settings: SimSettings | None = None,
               world: World | None = None) -> str:
    """MJCF text of the robot (standing at ``settings.start_pose``) merged with ``world``."""
    s = settings or SimSettings()
    world = world or load_world()
    root = ET.Element("mujoco", model=robot.name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    ET.SubElement(root, "option", timestep=_num(s.timestep), integrator=s.integrator,
                  cone=s.cone, impratio=_num(s.impratio), gravity=_vec((0, 0, -GRAVITY)),
                  **s.water.option_attributes())
    ET.SubElement(ET.SubElement(root, "visual"), "global", offwidth="1280", offheight="960")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", friction=_vec((s.friction, 0.005, 0.0001)),
                  solref=_vec(s.solref))
    asset = ET.SubElement(root, "asset")
    asset.extend(world.assets)
    worldbody = ET.SubElement(root, "worldbody")
    ET.SubElement(worldbody, "light", name="sun", pos="0 0 3", dir="0 0 -1", directional="true",
                  castshadow="false")
    worldbody.extend(world.bodies)
    for geom in worldbody.iter("geom"):
        if geom.get("group") == str(s.robot_group):
            raise ConfigError(f"world file {world.source}: geom '{geom.get('name', '?')}' uses "
                              f"group {s.robot_group}, reserved for the robot")
    _robot_body(worldbody, robot, s)
    actuator = ET.SubElement(root, "actuator")
    sensor = ET.SubElement(root, "sensor")
    for leg in robot.legs:
        for j, kind in enumerate(JOINT_KINDS):
            effort = float(robot.effort[j])
            ET.SubElement(actuator, "position", name=f"{leg}_{kind}", joint=f"{leg}_{kind}_joint",
                          kp=_num(s.kp), kv=_num(s.kv), forcerange=_vec((-effort, effort)),
                          ctrlrange=_vec((robot.lower[j], robot.upper[j])))
        for kind in ("framelinvel", "frameangvel"):
            ET.SubElement(sensor, kind, name=f"{leg}_foot_{kind[5:]}", objtype="site",
                          objname=f"{leg}_foot")
    ET.SubElement(sensor, "gyro", name=IMU_SENSORS[0], site="imu")  # after the feet
    ET.SubElement(sensor, "accelerometer", name=IMU_SENSORS[1], site="imu")
    ET.SubElement(sensor, "framequat", name=IMU_SENSORS[2], objtype="site", objname="imu")
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode")


#: Height above the highest foot [m] from which the start probes the ground under each foot.
SPAWN_PROBE = 1.0
#: The robot is raised at the start only where the ground needs more than this [m].
SPAWN_TOLERANCE = 1e-6


class SeabedModel:
    """A compiled seabed model and the indices of the robot's parts in it."""

    def __init__(self, robot: RobotConfig, settings: SimSettings | None = None,
                 world: str | Path | World | None = None) -> None:
        self.robot = robot
        self.settings = settings or SimSettings()
        self.world = world if isinstance(world, World) else load_world(world)
        self.xml = build_mjcf(robot, self.settings, self.world)
        try:
            self.model = mujoco.MjModel.from_xml_string(self.xml)
        except ValueError as exc:
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else repr(exc)
            raise ConfigError(f"world file {self.world.source}: not valid MJCF ({first})") from exc
        m, name = self.model, mujoco.mjtObj
        self.base_body = mujoco.mj_name2id(m, name.mjOBJ_BODY, "base_link")
        self._base_z = int(m.jnt_qposadr[mujoco.mj_name2id(m, name.mjOBJ_JOINT, "base")]) + 2
        joints = [mujoco.mj_name2id(m, name.mjOBJ_JOINT, j) for j in robot.joint_names]
        self.qpos_index = np.array([m.jnt_qposadr[j] for j in joints])
        self.dof_index = np.array([m.jnt_dofadr[j] for j in joints])
        self.foot_sites = np.array([mujoco.mj_name2id(m, name.mjOBJ_SITE, f"{leg}_foot")
                                    for leg in robot.legs])
        self.foot_geoms = np.array([mujoco.mj_name2id(m, name.mjOBJ_GEOM, f"{leg}_foot")
                                    for leg in robot.legs])
        self.robot_geoms = np.flatnonzero(m.geom_group == self.settings.robot_group)
        self.body_geoms = np.setdiff1d(self.robot_geoms, self.foot_geoms)
        self.seabed_geom = mujoco.mj_name2id(m, name.mjOBJ_GEOM, "seabed")
        self.foot_radius = float(m.geom_size[self.foot_geoms[0], 0])

    @property
    def timestep(self) -> float:
        """Physics time step [s]."""
        return float(self.model.opt.timestep)

    def settle(self, data: mujoco.MjData, duration: float) -> None:
        """Run the physics of ``data`` for ``duration`` [s] (at least one step), controls as
        they are."""
        mujoco.mj_step(self.model, data, nstep=max(1, round(duration / self.timestep)))

    @property
    def dry_weight(self) -> float:
        """Weight of the robot in air [N]."""
        return float(self.model.body_subtreemass[self.base_body]) * GRAVITY

    def make_data(self, q: np.ndarray | None = None) -> mujoco.MjData:
        """New state: the robot at its start pose with joints (and servo targets) at ``q``
        (``(n_legs, 3)`` [rad]; default: the standing pose)."""
        data = mujoco.MjData(self.model)
        self.set_joints(data, self.standing_pose() if q is None else q)
        self._clear_ground(data)
        return data

    def world_groups(self) -> np.ndarray:
        """The geom groups of the world, not the robot's: a ray filter (``mj_ray``)."""
        groups = np.ones(6, dtype=np.uint8)
        groups[self.settings.robot_group] = 0
        return groups

    def _clear_ground(self, data: mujoco.MjData) -> None:
        """Raise the robot where the world's ground under a foot is above z = 0, so that every
        foot starts ``spawn_clearance`` above it (a foot started inside a heightfield or a rock
        is thrown out by a contact force of kilonewtons)."""
        groups = self.world_groups()
        feet = data.site_xpos[self.foot_sites]
        top = float(feet[:, 2].max()) + SPAWN_PROBE
        geom = np.zeros(1, dtype=np.int32)
        lift = 0.0
        for x, y, z in feet:
            dist = mujoco.mj_ray(self.model, data, np.array([x, y, top]),
                                 np.array([0.0, 0.0, -1.0]), groups, 1, -1, geom)
            if dist >= 0.0:  # -1: no ground below the foot
                ground = top - dist
                lift = max(lift, ground + self.foot_radius + self.settings.spawn_clearance - z)
        if lift > SPAWN_TOLERANCE:
            data.qpos[self._base_z] += lift
            mujoco.mj_forward(self.model, data)

    def standing_pose(self) -> np.ndarray:
        """The configured standing joint angles ``(n_legs, 3)`` [rad]."""
        return inverse_kinematics(self.robot, self.robot.standing_feet())

    def set_joints(self, data: mujoco.MjData, q: np.ndarray) -> None:
        """Put the joints and their servo targets at ``q`` [rad] and recompute positions."""
        flat = np.asarray(q, dtype=float).reshape(-1)
        data.qpos[self.qpos_index] = flat
        data.ctrl[:] = flat
        mujoco.mj_forward(self.model, data)

    def feet_in_base(self, data: mujoco.MjData) -> np.ndarray:
        """Foot site positions in base_link ``(n_legs, 3)`` [m]."""
        rot = data.xmat[self.base_body].reshape(3, 3)
        return (data.site_xpos[self.foot_sites] - data.xpos[self.base_body]) @ rot
