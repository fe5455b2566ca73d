"""The generated MJCF model: kinematics cross-check, settings and world file checks."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.errors import ConfigError
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.sim.seabed.model import SeabedModel, SimSettings, link_radii
from crawler_motion.sim.seabed.water import WaterSettings
from crawler_motion.sim.seabed.world import load_world, worlds_dir

SHIPPED = ("flat", "relief", "rocks", "step", "wall", "u_trap")


@pytest.mark.parametrize("perturb_seed", [None, 7])
def test_foot_sites_equal_forward_kinematics(cfg, perturb_seed):
    robot = cfg.robot if perturb_seed is None else perturbed_robot(cfg.robot, perturb_seed)
    sm = SeabedModel(robot)
    data = sm.make_data()
    rng = np.random.default_rng(20261201)
    worst = nominal_gap = 0.0
    for _ in range(200):
        q = rng.uniform(robot.lower, robot.upper, (robot.n_legs, 3))
        sm.set_joints(data, q)
        feet = sm.feet_in_base(data)
        worst = max(worst, float(np.abs(feet - forward_kinematics(robot, q)).max()))
        nominal_gap = max(nominal_gap, float(np.abs(feet - forward_kinematics(cfg.robot,
                                                                              q)).max()))
    assert worst < 1e-6
    assert (nominal_gap > 5e-4) == (perturb_seed is not None)  # the model is the calibrated one


def test_urdf_loaded_by_mujoco_gives_the_same_feet(cfg):
    from crawler_motion.model.urdf import generate_urdf

    urdf = mujoco.MjModel.from_xml_string(generate_urdf(cfg.robot))
    sm = SeabedModel(cfg.robot)
    q = np.random.default_rng(3).uniform(cfg.robot.lower, cfg.robot.upper, (4, 3))
    data, udata = sm.make_data(q), mujoco.MjData(urdf)
    for name, value in zip(cfg.robot.joint_names, q.ravel(), strict=True):
        udata.qpos[urdf.jnt_qposadr[mujoco.mj_name2id(urdf, mujoco.mjtObj.mjOBJ_JOINT, name)]] \
            = value
    mujoco.mj_kinematics(urdf, udata)
    # URDF fixed links are merged into their parents: compare the tibia tip (foot) frames.
    for i, leg in enumerate(cfg.robot.legs):
        tibia = mujoco.mj_name2id(urdf, mujoco.mjtObj.mjOBJ_BODY, f"{leg}_tibia")
        tip = udata.xpos[tibia] + udata.xmat[tibia].reshape(3, 3) @ [cfg.robot.l3, 0, 0]
        assert np.allclose(tip, sm.feet_in_base(data)[i], atol=1e-9)


def test_geometry_comes_from_the_config(cfg):
    sm = SeabedModel(cfg.robot)
    link, foot = link_radii(cfg.robot)
    assert sm.foot_radius == pytest.approx(foot)
    assert sm.model.geom_size[sm.body_geoms[1:], 0] == pytest.approx(link)
    assert sm.model.nu == 3 * cfg.robot.n_legs
    assert np.allclose(sm.model.actuator_forcerange[:, 1], np.tile(cfg.robot.effort, 4))
    assert np.allclose(sm.model.jnt_range[sm.model.jnt_qposadr >= 7],
                       np.tile(np.stack((cfg.robot.lower, cfg.robot.upper), 1), (4, 1)))
    assert sm.dry_weight == pytest.approx(3.0 * 9.81)
    assert sm.model.opt.timestep == 0.0005
    assert sm.model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert len(sm.body_geoms) == 1 + 3 * cfg.robot.n_legs
    assert sm.model.geom_group[sm.seabed_geom] != sm.settings.robot_group


@pytest.mark.parametrize("world", SHIPPED)
def test_shipped_worlds_compile(cfg, world):
    sm = SeabedModel(cfg.robot, world=world)
    assert sm.seabed_geom >= 0


@pytest.mark.parametrize(("text", "problem"), [
    ("<mujoco><worldbody>", "not valid XML"),
    ("<robot/>", "not MJCF"),
    ("<mujoco/>", "no <worldbody>"),
    ('<mujoco><worldbody><geom name="floor" type="plane" size="1 1 1"/></worldbody></mujoco>',
     "exactly one geom named 'seabed'"),
    ('<mujoco><worldbody><geom name="seabed" type="sphere" size="1"/></worldbody></mujoco>',
     "must be one of"),
    ('<mujoco><asset><hfield name="h" file="gone.png"/></asset><worldbody>'
     '<geom name="seabed" type="plane" size="1 1 1"/></worldbody></mujoco>',
     "missing file 'gone.png'"),
    ('<mujoco><worldbody><geom name="seabed" type="plane" size="1 1 1" bogus="1"/>'
     '</worldbody></mujoco>', "not valid MJCF"),
    ('<mujoco><worldbody><geom name="seabed" type="plane" size="1 1 1" group="2"/>'
     '</worldbody></mujoco>', "reserved for the robot"),
])
def test_bad_world_files_are_refused(cfg, tmp_path: Path, text, problem):
    path = tmp_path / "bad.xml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=problem) as info:
        SeabedModel(cfg.robot, world=path)
    assert str(path) in str(info.value)


def test_missing_world_file_is_refused(tmp_path: Path):
    with pytest.raises(ConfigError, match="cannot read it"):
        load_world(tmp_path / "none.xml")


def test_shipped_names_resolve():
    assert load_world("wall").source == str(worlds_dir() / "wall.xml")
    assert load_world(None).source == str(worlds_dir() / "flat.xml")


@pytest.mark.parametrize(("field", "value", "ok"), [
    ("timestep", 0.0025, True), ("timestep", 0.0026, False), ("timestep", 0.0, False),
    ("timestep", float("nan"), False), ("integrator", "RK4", True),
    ("integrator", "verlet", False), ("cone", "pyramidal", True), ("cone", "round", False),
    ("impratio", 1.0, True), ("impratio", 0.5, False), ("friction", 0.0, False),
    ("kp", 0.0, False), ("kv", 0.0, True), ("kv", -1.0, False), ("mass", 0.1, False),
    ("robot_group", 5, True), ("robot_group", 6, False), ("robot_group", True, False),
    ("solref", (0.001, 1.0), True), ("solref", (0.0009, 1.0), False),
    ("hull_size", (0.2, 0.1), False), ("start_pose", (1.0, 2.0, 3.0), True),
])
def test_settings_are_validated(cfg, field, value, ok):
    if not ok:
        with pytest.raises(ConfigError, match=field.split("_")[0]):
            SeabedModel(cfg.robot, SimSettings(**{field: value}))
        return
    SeabedModel(cfg.robot, SimSettings(**{field: value}))


@pytest.mark.parametrize(("kwargs", "ok"), [
    ({"net_weight_fraction": 1.0}, True), ({"net_weight_fraction": 1.01}, False),
    ({"net_weight_fraction": 0.0}, False), ({"medium": "land"}, True),
    ({"medium": "air"}, False), ({"current": (0.5, 0.0, 0.0)}, True),
    ({"current": (0.5, 0.0)}, False), ({"medium": "land", "current": (0.5, 0, 0)}, False),
    ({"viscosity": -1e-3}, False),
])
def test_water_settings_are_validated(kwargs, ok):
    if ok:
        WaterSettings(**kwargs)
    else:
        with pytest.raises(ConfigError):
            WaterSettings(**kwargs)


@pytest.mark.parametrize(("world", "start", "raised"), [
    ("flat", (0.0, 0.0, 0.0), False),
    ("flat", (0.3, -0.2, 0.5), False),
    ("step", (0.0, 0.0, 0.0), False),  # the step is ahead of the feet
    ("relief_2cm", (0.0, 0.0, 0.0), True),
    ("relief_2cm", (0.1, 0.05, 0.0), True),  # a foot started 11 mm inside: thrown by 3 kN
    ("rocks", (0.3, -0.2, 0.5), True),
])
def test_the_robot_starts_with_every_foot_above_the_ground(cfg, world, start, raised):
    flat = SeabedModel(cfg.robot, SimSettings(start_pose=start), "flat").make_data()
    sm = SeabedModel(cfg.robot, SimSettings(start_pose=start), world)
    data = sm.make_data()
    assert bool(data.qpos[2] > flat.qpos[2] + 1e-4) is raised
    assert data.qpos[2] == pytest.approx(flat.qpos[2]) or raised
    assert all(data.contact[k].dist >= -1e-9 for k in range(data.ncon))
    sm.settle(data, 0.2)
    assert float(np.abs(data.efc_force).max()) < 20.0  # the robot weighs ~9 N in water
