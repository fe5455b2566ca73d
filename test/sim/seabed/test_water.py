"""Buoyancy: a standing robot presses the seabed with its net weight in water."""

from __future__ import annotations

import mujoco
import pytest

from crawler_motion.sim.seabed.contacts import foot_loads, robot_load
from crawler_motion.sim.seabed.model import SeabedModel, SimSettings
from crawler_motion.sim.seabed.water import Medium, WaterSettings


def _settled_load(cfg, water: WaterSettings) -> tuple[float, float, SeabedModel]:
    sm = SeabedModel(cfg.robot, SimSettings(water=water))
    data = sm.make_data()
    mujoco.mj_step(sm.model, data, nstep=int(1.0 / sm.timestep))
    return robot_load(sm, data), float(foot_loads(sm, data).sum()), sm


@pytest.mark.parametrize(("water", "fraction"), [
    (WaterSettings(), 0.3),
    (WaterSettings(net_weight_fraction=0.5), 0.5),
    (WaterSettings(medium=Medium.LAND), 1.0),
])
def test_standing_robot_presses_with_its_net_weight(cfg, water, fraction):
    total, feet, sm = _settled_load(cfg, water)
    assert total == pytest.approx(fraction * sm.dry_weight, rel=0.03)
    assert feet == pytest.approx(total, rel=1e-9)  # it stands on its feet only


def test_current_pushes_the_robot_downstream(cfg):
    sm = SeabedModel(cfg.robot, SimSettings(water=WaterSettings(current=(0.0, 1.5, 0.0))))
    data = sm.make_data()
    mujoco.mj_step(sm.model, data, nstep=int(1.0 / sm.timestep))
    assert data.qpos[1] > 0.01  # drag beyond friction x net weight: swept along +y


def test_imu_at_rest_reads_gravity_and_the_body_attitude(cfg):
    import numpy as np

    from crawler_motion.sim.seabed.model import IMU_SENSORS

    sm = SeabedModel(cfg.robot, SimSettings(start_pose=(0.0, 0.0, 0.5)))
    data = sm.make_data()
    mujoco.mj_step(sm.model, data, nstep=int(0.5 / sm.timestep))
    read = {name: data.sensor(name).data for name in IMU_SENSORS}
    assert np.allclose(read["imu_gyro"], 0.0, atol=1e-2)
    assert np.allclose(read["imu_accelerometer"], [0.0, 0.0, 9.81], atol=0.05)
    assert np.allclose(np.abs(read["imu_framequat"]), np.abs(data.qpos[3:7]), atol=1e-6)
