"""Calibration in the simulator: tracker readings of the physical model's feet, identification
of every leg from them, and where a planned walk puts the feet of the simulated robot.

The simulated robot (`SeabedModel`) is built from a "true" robot, e.g. a perturbed calibration;
the planner's robot is another (nominal, or the identified calibration). Measurements are
kinematic: joints are set in the MuJoCo state and `mujoco.mj_forward` gives the foot sites
(`SeabedModel.feet_in_base`), exactly what a tracker on a robot held on a stand would read;
no contact, slip or servo lag enters, so the figures are those of the kinematics alone.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from crawler_motion.calibration import study, synthetic
from crawler_motion.calibration.identify import Method
from crawler_motion.model.calibration_file import nominal_calibration
from crawler_motion.model.config import Config, RobotConfig
from crawler_motion.motion.fastpath import FastKinematics
from crawler_motion.motion.gait import WalkParams, plan_walk
from crawler_motion.sim.seabed.model import SeabedModel

#: A foot counts as on the ground when its planned height is within this of the lowest [m].
GROUND_TOLERANCE = 1e-9


def tracker_readings(sm: SeabedModel, leg: int, poses: np.ndarray, noise: float,
                     rng: np.random.Generator) -> np.ndarray:
    """Foot sites ``(len(poses), 3)`` [m, base_link] of leg ``leg`` of the simulated robot at
    joint ``poses`` ``(n, 3)`` [rad] (the other legs standing), with Gaussian tracker noise
    ``noise`` [m] per axis."""
    data = sm.make_data()
    q = sm.standing_pose()
    feet = np.empty((len(poses), 3))
    for k, pose in enumerate(poses):
        q[leg] = pose
        sm.set_joints(data, q)
        feet[k] = sm.feet_in_base(data)[leg]
    return synthetic.measure(feet, noise, rng)


def identify_robot(robot: RobotConfig, sm: SeabedModel, poses: np.ndarray, noise: float,
                   seed: int, method: Method = Method.RLS_DE) -> RobotConfig:
    """``robot`` with every leg identified (``method``) from tracker readings of the simulated
    robot at ``poses`` ``(n, 3)`` [rad], noise ``noise`` [m] per axis."""
    base = robot.geometry or nominal_calibration(robot.legs, (robot.l1, robot.l2, robot.l3))
    rng = np.random.default_rng(seed)
    for leg, name in enumerate(robot.legs):
        measured = tracker_readings(sm, leg, poses, noise, rng)
        comp = study.compare(robot, leg, poses, measured, seed)
        base = base.with_leg(name, comp.fits[method.value].params)
    return replace(robot, geometry=base)


@dataclass(frozen=True)
class Placement:
    """Distances [m] between planned feet and the simulated robot's feet over a walk."""

    ground_mean: float  # feet on the ground at every segment boundary (touch-down, lift-off)
    ground_max: float
    samples: int  # planned ground contacts compared


def walk_placement(cfg: Config, planner: RobotConfig, sm: SeabedModel, steps: int = 2
                   ) -> Placement:
    """Plan a default walk of ``steps`` steps with the planner's robot ``planner``, turn its
    feet into joint angles with the planner's tick IK (`FastKinematics`), set them in the
    simulated robot ``sm`` and measure where its feet are, at every segment boundary."""
    planned = replace(cfg, robot=planner)
    plan = plan_walk(planned, WalkParams.defaults(cfg.gait), steps)
    times = np.unique(np.concatenate([np.asarray(leg.breaks) for leg in plan.legs]))
    kin = FastKinematics(planner)
    data = sm.make_data()
    errors = []
    for t in times:
        feet = plan.evaluate(float(t))[0][0]
        q = np.reshape(kin.inverse(feet.reshape(-1).tolist()), feet.shape)
        sm.set_joints(data, q)
        gap = np.linalg.norm(sm.feet_in_base(data) - feet, axis=-1)
        down = feet[:, 2] <= feet[:, 2].min() + GROUND_TOLERANCE
        errors.extend(gap[down])
    return Placement(float(np.mean(errors)), float(np.max(errors)), len(errors))
