"""Joint efforts of the seabed simulator: the plant's mean servo torques, the effort frames of
its manager, and effort traces recorded from a walk (with the true foot loads)."""

from __future__ import annotations

import uuid

import can
import mujoco
import numpy as np
import pytest

from crawler_motion.canbus.protocol import EffortFeedback, MotorProtocol
from crawler_motion.model.config import Config
from crawler_motion.motion.contact_estimation import ContactEstimator, FootContact, foot_forces
from crawler_motion.motion.gait import WalkParams
from crawler_motion.sim.motor_manager import MotorManagerSim
from crawler_motion.sim.seabed.contacts import foot_loads
from crawler_motion.sim.seabed.effort_trace import load_trace, record_effort_trace, save_trace
from crawler_motion.sim.seabed.model import SeabedModel
from crawler_motion.sim.seabed.plant import SeabedPlant


@pytest.fixture(scope="module")
def protocol(cfg: Config) -> MotorProtocol:
    return MotorProtocol.from_config(cfg.robot)


def test_efforts_are_the_mean_servo_torques_since_the_last_report(cfg, protocol):
    plant = SeabedPlant(SeabedModel(cfg.robot), protocol)
    seen: list[np.ndarray] = []
    plant.on_step = lambda data: seen.append(data.actuator_force.copy())
    targets = plant.initial_axes + 0.05  # every servo pulls
    plant.advance(0.01, targets)
    mean = protocol.effort_to_axis(np.mean(seen, axis=0))
    np.testing.assert_allclose(plant.take_efforts(), mean, atol=1e-12)
    assert len(seen) == round(0.01 / plant.sm.timestep)
    assert np.abs(mean).max() > 0.1
    last = protocol.effort_to_axis(plant.data.actuator_force)
    np.testing.assert_allclose(plant.take_efforts(), last)  # no step since: the instant


def test_standing_feet_carry_the_weight_in_water(cfg, protocol):
    """Statics through the leg Jacobians: the four estimated normal forces of the standing
    robot add up to its weight in water (less the legs' own, ~0.1 N each in water, which the
    drives hold and the estimate leaves out: 8.27 of 8.83 N)."""
    sm = SeabedModel(cfg.robot)
    plant = SeabedPlant(sm, protocol)
    for _ in range(50):
        plant.advance(0.01, plant.initial_axes)
    q = plant.data.qpos[sm.qpos_index].reshape(4, 3)
    tau = protocol.effort_to_joint(plant.take_efforts()).reshape(4, 3)
    normal = foot_forces(cfg.robot, q, tau)[:, 2]
    net = sm.dry_weight * (1.0 - sm.settings.water.buoyancy_fraction)
    assert normal.sum() == pytest.approx(net - 4 * 0.11, rel=0.02)
    assert np.all(normal > 0.15 * net)  # every foot bears part of it


def test_the_seabed_manager_sends_effort_frames(cfg, protocol):
    sm = SeabedModel(cfg.robot)
    plant = SeabedPlant(sm, protocol)
    channel = f"effort-{uuid.uuid4().hex}"
    bus, spy = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    try:
        sim = MotorManagerSim(bus, protocol, plant=plant,
                              initial_positions=protocol.to_joint(plant.initial_axes))
        for _ in range(3):
            sim.step(0.01)
        frames = []
        while (msg := spy.recv(0.0)) is not None:
            frames.append(protocol.decode(msg))
        efforts = [f for f in frames if isinstance(f, EffortFeedback)]
        assert len(efforts) == 12  # 4 groups x 3 cycles, before the positions of each
        assert isinstance(frames[0], EffortFeedback)
        assert any(abs(v) > 0.05 for f in efforts for v in f.efforts.values())
    finally:
        bus.shutdown()
        spy.shutdown()


def test_a_recorded_trace_agrees_with_the_true_contacts(cfg, tmp_path):
    trace = record_effort_trace(cfg, WalkParams.defaults(cfg.gait), 1, "flat")
    n = len(trace.time)
    assert trace.positions.shape == trace.efforts.shape == (n, 12)
    assert trace.loads.shape == (n, 4) and trace.world == "flat"
    np.testing.assert_allclose(np.diff(trace.time), 0.01, atol=1e-9)
    path = tmp_path / "trace.npz"
    save_trace(trace, path)
    again = load_trace(path)
    np.testing.assert_allclose(again.efforts, trace.efforts, atol=1e-6)
    truth = trace.loads > 0.1 * trace.net_weight / 4
    est = ContactEstimator(cfg.robot)
    agree = []
    for k in range(n):
        out = est.update(float(trace.time[k]), trace.positions[k], trace.efforts[k])
        if FootContact.UNKNOWN not in out.states:
            agree.append(np.array([s is FootContact.YES for s in out.states]) == truth[k - 1])
    assert np.mean(agree) >= 0.95
    assert truth.all(axis=1).any() and (~truth).any()  # standing and swinging samples


def test_loads_are_means_over_the_period(cfg):
    """The truth of a trace: a foot's load averaged over the physics steps of the period."""
    sm = SeabedModel(cfg.robot)
    data = sm.make_data()
    sm.settle(data, 0.3)
    total = np.zeros(4)
    for _ in range(20):
        mujoco.mj_step(sm.model, data)
        total += foot_loads(sm, data)
    net = sm.dry_weight * (1.0 - sm.settings.water.buoyancy_fraction)
    assert (total / 20).sum() == pytest.approx(net, rel=0.05)
