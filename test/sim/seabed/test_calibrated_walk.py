"""A calibrated walk in the simulator: the simulated robot is a perturbed "true" robot; the
planner walks on the nominal legs, then on legs identified from the simulator's tracker
readings; the feet on the ground are compared with the plan (kinematics only, no slip)."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.calibration import study
from crawler_motion.calibration.synthetic import perturbed_robot
from crawler_motion.sim.seabed.calibrated_walk import (
    identify_robot,
    tracker_readings,
    walk_placement,
)
from crawler_motion.sim.seabed.model import SeabedModel
from crawler_motion.sim.seabed.parameters import SEABED_PARAMETERS, build_simulator


@pytest.fixture(scope="module")
def setup(cfg):
    true = perturbed_robot(cfg.robot, 15)
    sm = SeabedModel(true)
    poses = study.select_poses(cfg.robot, 0, 200, 50, 0, 5).poses
    return cfg, true, sm, poses


def test_tracker_reads_the_true_legs(setup):
    _, true, sm, poses = setup
    feet = tracker_readings(sm, 2, poses[:10], 0.0, np.random.default_rng(0))
    angles = np.broadcast_to(sm.standing_pose(), (10, 4, 3)).copy()
    angles[:, 2] = poses[:10]
    from crawler_motion.model.kinematics import forward_kinematics

    np.testing.assert_allclose(feet, forward_kinematics(true, angles)[:, 2], atol=1e-9)
    noisy = tracker_readings(sm, 2, poses[:10], 2e-5, np.random.default_rng(0))
    assert 5e-6 < np.std(noisy - feet) < 4e-5


@pytest.mark.parametrize("noise", [0.0, 2e-5])
def test_identified_planner_lands_the_feet_within_a_tenth_of_a_millimetre(setup, noise):
    cfg, _, sm, poses = setup
    nominal = walk_placement(cfg, cfg.robot, sm)
    identified = identify_robot(cfg.robot, sm, poses, noise, seed=1)
    calibrated = walk_placement(cfg, identified, sm)
    assert nominal.samples == calibrated.samples > 20
    assert nominal.ground_mean > 1e-3  # the uncalibrated planner misses by millimetres
    assert calibrated.ground_max < 1e-4
    assert calibrated.ground_mean < (1e-6 if noise == 0.0 else 5e-5)


def test_seabed_sim_builds_the_true_robot_from_its_calibration_file(tmp_path, setup):
    from crawler_motion.model.calibration_file import write_calibration

    _, true, sm, _ = setup
    write_calibration(tmp_path / "true.yaml", true.geometry)
    values = {**{spec.name: spec.default for spec in SEABED_PARAMETERS},
              "calibration_file": str(tmp_path / "true.yaml")}
    sim = build_simulator(values)
    data = sim.model.make_data()
    q = sm.standing_pose()
    sim.model.set_joints(data, q)
    reference = sm.make_data(q)
    np.testing.assert_allclose(sim.model.feet_in_base(data), sm.feet_in_base(reference),
                               atol=1e-12)
