"""The plant seam of the simulated manager and the seabed physics as its plant (in-process)."""

from __future__ import annotations

import math

import can
import mujoco
import numpy as np
import pytest

from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.errors import ConfigError
from crawler_motion.model.config import Config, load_scanner
from crawler_motion.sim.manager_model import ManagerModel
from crawler_motion.sim.manager_state import ManagerState
from crawler_motion.sim.motor_manager import MotorManagerSim
from crawler_motion.sim.seabed.contacts import body_contact, body_touches
from crawler_motion.sim.seabed.model import SeabedModel, SimSettings
from crawler_motion.sim.seabed.parameters import SEABED_PARAMETERS, check_values
from crawler_motion.sim.seabed.plant import (
    MAX_PENETRATION,
    PlantSettings,
    SeabedPlant,
    unstable_reason,
)
from crawler_motion.sim.seabed.scanner import RangeScanner


class FakePlant:
    """Moves every axis halfway to its target per call; fails when told."""

    def __init__(self, n: int) -> None:
        self.pos = np.zeros(n)
        self.failure: str | None = None
        self.calls: list[tuple[float, np.ndarray]] = []

    def advance(self, dt: float, targets: np.ndarray) -> np.ndarray:
        self.calls.append((dt, targets.copy()))
        self.pos = self.pos + 0.5 * (targets - self.pos)
        return self.pos.copy()


@pytest.fixture(scope="module")
def protocol(cfg: Config) -> MotorProtocol:
    return MotorProtocol.from_config(cfg.robot)


@pytest.fixture()
def plant(cfg: Config, protocol: MotorProtocol) -> SeabedPlant:
    sm = SeabedModel(cfg.robot, SimSettings(), "wall")
    return SeabedPlant(sm, protocol, RangeScanner(sm, load_scanner()))


# ---- the seam ------------------------------------------------------------------------------

@pytest.mark.parametrize("state_command, moves", [(None, True), ("hold", False),
                                                  ("disable", False), ("estop", False)])
def test_the_plant_moves_the_axes_and_servos_hold_unless_enabled(
        state_command: str | None, moves: bool) -> None:
    fake = FakePlant(3)
    model = ManagerModel(np.zeros(3), np.full(3, 1e-6), 10.0, fake)
    model.command("enable")
    model.apply_targets({0: 1.0})
    if state_command is not None:
        model.command(state_command)
    model.advance(0.01)
    # the speed limit (1e-6 rad/s) does not apply: the plant moved the axis
    assert model.pos[0] == pytest.approx(0.5 if moves else 0.0)
    assert fake.calls[-1][0] == 0.01
    assert fake.calls[-1][1][0] == (1.0 if moves else 0.0)


def test_a_failed_plant_makes_an_enabled_manager_hold() -> None:
    fake = FakePlant(2)
    model = ManagerModel(np.zeros(2), np.ones(2), 10.0, fake)
    model.command("enable")
    model.advance(0.01)
    assert model.state == ManagerState.ENABLED
    fake.failure = "broken"
    model.advance(0.01)
    assert model.state == ManagerState.HOLD
    assert not model.apply_targets({0: 1.0})


def test_without_a_plant_the_speed_limit_still_moves_the_axes() -> None:
    model = ManagerModel(np.zeros(2), np.full(2, 2.0), 10.0)
    model.command("enable")
    model.apply_targets({0: 1.0})
    model.advance(0.1)
    assert model.pos[0] == pytest.approx(0.2)


# ---- the seabed plant ----------------------------------------------------------------------

def test_the_robot_starts_standing_and_settled(plant: SeabedPlant,
                                               protocol: MotorProtocol) -> None:
    standing = plant.sm.standing_pose().reshape(-1)
    assert np.abs(protocol.to_joint(plant.initial_axes) - standing).max() < 0.02
    sample = plant.sample()
    assert abs(sample.position[2] - 0.078) < 0.01  # resting on its feet [m]
    assert np.linalg.norm(sample.linear_velocity) < 0.01


def test_advance_steps_whole_time_steps_and_carries_the_rest(plant: SeabedPlant) -> None:
    targets = plant.initial_axes
    steps = plant.steps
    plant.advance(0.4 * plant.sm.timestep, targets)
    assert plant.steps == steps
    plant.advance(0.7 * plant.sm.timestep, targets)
    assert plant.steps == steps + 1
    plant.advance(0.01, targets)
    assert plant.steps == steps + 1 + round(0.01 / plant.sm.timestep)


def test_a_servo_tracks_its_target(plant: SeabedPlant, protocol: MotorProtocol) -> None:
    joints = protocol.to_joint(plant.initial_axes)
    joints[0] += 0.1  # the first leg's root joint [rad]
    targets = protocol.to_axis(joints)
    for _ in range(50):
        measured = protocol.to_joint(plant.advance(0.01, targets))
    assert abs(measured[0] - joints[0]) < 0.02
    assert abs(measured[0] - joints[0]) < 0.05 * 0.1  # it moved most of the way


@pytest.mark.parametrize(("period", "kept"), [(0.0, 0), (0.1, 6), (0.05, 11), (0.2, 3)])
def test_states_are_kept_once_per_snapshot_period(cfg: Config, protocol: MotorProtocol,
                                                  period: float, kept: int) -> None:
    plant = SeabedPlant(SeabedModel(cfg.robot), protocol,
                        settings=PlantSettings(snapshot_period=period))
    for _ in range(50):  # 0.5 s after the start state
        plant.advance(0.01, plant.initial_axes)
    assert len(plant.snapshots) == kept
    assert all(len(q) == plant.sm.model.nq for q in plant.snapshots)


def test_a_scan_comes_once_per_scan_period(plant: SeabedPlant) -> None:
    plant.take_scan()
    for _ in range(10):
        plant.advance(0.01, plant.initial_axes)
    scan = plant.take_scan()
    assert scan is not None and scan.points.shape[1] == 3 and len(scan.points) > 50
    assert scan.stamp == scan.time  # no clock: the simulated time
    assert plant.take_scan() is None


def test_a_sample_is_taken_once_per_advance(plant: SeabedPlant) -> None:
    """The sensors' timer may fire twice between two physics advances: the second time there
    is nothing to publish (a repeated odom stamp was refused downstream as not newer)."""
    first = plant.take_sample()
    assert first is not None and plant.take_sample() is None
    plant.advance(0.01, plant.initial_axes)
    second = plant.take_sample()
    assert second is not None and second.time > first.time
    assert plant.take_sample() is None
    assert plant.sample() is second  # the latest state, for whoever asks


def test_samples_and_scans_carry_the_clock_time_their_state_was_reached(
        cfg: Config, protocol: MotorProtocol) -> None:
    ticks = iter(range(1000, 2000))
    sm = SeabedModel(cfg.robot, SimSettings(), "wall")
    plant = SeabedPlant(sm, protocol, RangeScanner(sm, load_scanner()),
                        clock=lambda: float(next(ticks)))
    plant.take_scan()
    stamps = []
    for _ in range(10):
        plant.advance(0.01, plant.initial_axes)
        stamps.append(plant.sample().stamp)
    scan = plant.take_scan()
    assert stamps == [float(t) for t in range(1001, 1011)]  # one reading per advance
    assert scan is not None and scan.stamp in stamps


def test_a_non_finite_state_stops_the_plant_and_keeps_the_last_positions(
        plant: SeabedPlant) -> None:
    before = plant.advance(0.01, plant.initial_axes)
    plant.data.qvel[0] = math.nan
    after = plant.advance(0.01, plant.initial_axes)
    assert plant.failure is not None and "non-finite" in plant.failure
    assert np.array_equal(before, after)
    steps = plant.steps
    plant.advance(0.01, plant.initial_axes)
    assert plant.steps == steps  # the physics stays stopped


@pytest.mark.parametrize("sink, unstable", [(0.0, False), (MAX_PENETRATION + 0.03, True)])
def test_deep_penetration_is_unstable(plant: SeabedPlant, sink: float, unstable: bool) -> None:
    plant.data.qpos[2] -= sink
    mujoco.mj_forward(plant.sm.model, plant.data)
    reason = unstable_reason(plant.sm, plant.data, MAX_PENETRATION)
    assert (reason is not None) == unstable
    if unstable:
        assert "penetration" in reason


def test_the_manager_reports_what_the_physics_measures(plant: SeabedPlant,
                                                       protocol: MotorProtocol) -> None:
    bus = can.Bus(interface="virtual", channel="seabed_plant_test")
    try:
        sim = MotorManagerSim(bus, protocol, plant=plant,
                              initial_positions=protocol.to_joint(plant.initial_axes))
        for _ in range(20):
            sim.step(0.01)
        assert np.array_equal(sim.positions, protocol.to_axis(
            plant.data.qpos[plant.sm.qpos_index]))
        assert sim.counters.sent > 0
    finally:
        bus.shutdown()


# ---- parameters ----------------------------------------------------------------------------

DEFAULTS = {spec.name: spec.default for spec in SEABED_PARAMETERS}


@pytest.mark.parametrize("name, value, ok", [
    ("timestep", 1e-5, True), ("timestep", 0.0025, True), ("timestep", 0.0026, False),
    ("net_weight_fraction", 0.001, True), ("net_weight_fraction", 1.0, True),
    ("net_weight_fraction", 0.0, False), ("imu_noise", 0.0, True), ("imu_noise", -0.1, False),
    ("range_noise", 1.0, True), ("range_noise", 1.01, False), ("dropout", 1.0, True),
    ("dropout", 1.5, False), ("max_range", 0.01, True), ("max_range", 0.0, False),
    ("start_pose", (1.0, 2.0, 3.0), True), ("start_pose", (1.0, 2.0), False),
    ("start_pose", (0.0, 0.0, math.nan), False), ("current", (5.0, 0.0, 0.0), True),
    ("current", (5.1, 0.0, 0.0), False), ("medium", "land", True), ("medium", "air", False),
    ("world", "", False), ("can_port", 65536, False), ("record", "", True),
    ("record", "plots/walk", True), ("record", 1, False), ("record_fps", 0.5, True),
    ("record_fps", 30.0, True), ("record_fps", 0.49, False), ("record_fps", 30.1, False),
])
def test_parameters_out_of_range_are_refused_with_the_reason(name: str, value: object,
                                                             ok: bool) -> None:
    values = {**DEFAULTS, name: value}
    if ok:
        check_values(values)
    else:
        with pytest.raises(ConfigError, match=name):
            check_values(values)


@pytest.mark.parametrize("where, seabed, obstacle", [
    ("standing", 0, 0),  # only the feet touch
    ("hull on the seabed", 1, 0),
    ("hull in the wall's face", 1, 1),  # the hull still rests on the seabed
])
def test_hull_contacts_are_counted_by_what_they_touch(plant: SeabedPlant, where: str,
                                                      seabed: int, obstacle: int) -> None:
    if where != "standing":
        plant.data.qpos[2] -= 0.06  # the hull down to the seabed
    if where == "hull in the wall's face":
        plant.data.qpos[0] = 0.60 - 0.05  # the wall's near face is x = 0.60 m
    mujoco.mj_forward(plant.sm.model, plant.data)
    touched = [mujoco.mj_id2name(plant.sm.model, mujoco.mjtObj.mjOBJ_GEOM, g)
               for _, g in body_touches(plant.sm, plant.data)]
    assert ("seabed" in touched) == bool(seabed), touched
    assert ("wall" in touched) == bool(obstacle), touched
    assert body_contact(plant.sm, plant.data) == bool(seabed or obstacle)
    plant._count_contacts()
    assert (plant.body_contacts, plant.obstacle_contacts) == (min(1, seabed + obstacle),
                                                              obstacle)
    assert sorted(plant.first_contacts) == sorted(
        k for k, n in (("seabed", seabed), ("obstacle", obstacle)) if n)
    if obstacle:
        assert " on wall at " in plant.first_contacts["obstacle"]
