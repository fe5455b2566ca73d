"""A body-pose move in progress: joint targets per tick from the pose's rest sextic (pure).

The move is planned and checked as a whole by `body_pose.plan_pose_move` (every foot fixed on
the ground, every sample within the workspace, the joint limits and the velocity limits). Per
tick the pose is evaluated by `fastpath.Track`, the feet and their velocities by
`body_pose.foot_state_at` and the joints by `fastpath.FastKinematics.solve` (the closed-form IK
with its limit check and the Jacobian), all in plain floats.
"""

from __future__ import annotations

import numpy as np

from crawler_motion.model.config import Config
from crawler_motion.motion.body_pose import (
    BodyPose,
    PosePath,
    check_pose,
    foot_state_at,
    plan_pose_move,
)
from crawler_motion.motion.fastpath import FastKinematics, Track
from crawler_motion.planner.context import JointTarget
from crawler_motion.planner.state import STANDING, PlannerState


class PoseMove:
    """The pose move from ``start`` to ``end`` (relative to the standing ``body_height`` [m])
    starting at ``t0`` [s]; ``target`` names it ("pose", or "stand" back to neutral). Raises
    `PoseError` if it cannot be executed. `current` is the pose of the last target given."""

    end_state: PlannerState = STANDING

    def __init__(self, cfg: Config, body_height: float, start: BodyPose, end: BodyPose,
                 t0: float, target: str = "pose") -> None:
        self.path: PosePath = plan_pose_move(cfg, body_height, start, end)
        self._track = Track([self.path.path], dims=6)
        self._standing = self.path.standing.reshape(-1).tolist()
        self._kin = FastKinematics(cfg.robot)
        self._lo = cfg.robot.lower_limits().reshape(-1).copy()
        self._hi = cfg.robot.upper_limits().reshape(-1).copy()
        self.final = check_pose(cfg, body_height, end).reshape(-1)  # held at the end [rad]
        self.t0 = float(t0)
        self.target = target
        self.end = end
        self.current = start

    @property
    def duration(self) -> float:
        """Duration [s]."""
        return self.path.duration

    def done(self, now: float) -> bool:
        """True from the end of the move on."""
        return now - self.t0 >= self.path.duration

    def at(self, now: float) -> JointTarget:
        """Joint targets at steady time ``now`` [s] (within the limits); raises
        `KinematicsError` should a tick between the checked samples be out of reach."""
        pose, rate = self._track.evaluate(now - self.t0)
        q, rates = self._kin.solve(*foot_state_at(self._standing, pose, rate))
        self.current = BodyPose(*pose)
        return JointTarget(np.clip(np.array(q), self._lo, self._hi), np.array(rates))
