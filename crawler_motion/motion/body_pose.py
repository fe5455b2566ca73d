"""Body pose of a standing robot: the body shifts and tilts, every foot stays on the ground (pure).

A pose is ``(x, y, z, roll, pitch, yaw)``: the position [m] and the fixed-axis roll, pitch,
yaw [rad] (`rotations.rpy_matrix`, ``R = Rz Ry Rx``) of base_link relative to its neutral
standing pose at the standing body height (REP-103: z up, so z > 0 raises the body). The feet
stay where they stand in the world: a standing foot ``p`` (`RobotConfig.standing_feet`) is at
``p' = R^T (p - t)`` in the posed base_link, and the joint angles of the pose are the one IK
(`kinematics.inverse_kinematics`, limits checked) of those targets.

A pose move interpolates the pose itself with the rest sextic (`trajectory.rest_segment`:
v = a = 0 at both ends), so every foot's base_link path is its fixed ground point seen from a
smoothly moving body: C² like every trajectory of the package, and at rest at both ends. Its
duration keeps the body's peak speed and turn rate within the config's (``body_pose.speed``,
``turn_rate``) and every joint at or below `POSE_SPEED_FRACTION` of its velocity limit; every
sample of the move is checked with `gait.check_trajectories` (the IK with the limits and the
joint rates) before anything moves.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import astuple, dataclass, fields

import numpy as np

from crawler_motion.errors import GaitError, KinematicsError, PoseError, UnreachableError
from crawler_motion.model.config import Config, RobotConfig
from crawler_motion.model.kinematics import inverse_kinematics, joint_velocities
from crawler_motion.model.rotations import (
    rpy_angular_acceleration,
    rpy_angular_velocity,
    rpy_matrix,
)
from crawler_motion.motion.gait import check_trajectories
from crawler_motion.motion.trajectory import REST_PEAK_SPEED, Piecewise, rest_segment
from crawler_motion.motion.walk_options import OPTIONS, POSE_OPTIONS, pose_height_error

#: Shortest pose move [s].
MIN_POSE_TIME = 0.5
#: Peak joint speed of a pose move as a fraction of the joint's velocity limit.
POSE_SPEED_FRACTION = 0.5
#: Samples of a pose move (at unit duration) that set its duration from the joint rates.
DURATION_SAMPLES = 201
#: Names of the pose fields, in vector order (the ``pose`` command's keys).
POSE_FIELDS: tuple[str, ...] = tuple(option.name for option in POSE_OPTIONS)


@dataclass(frozen=True)
class BodyPose:
    """Shift [m] and fixed-axis roll, pitch, yaw [rad] of base_link from its neutral standing
    pose (see the module docstring); ``z`` is relative to the standing body height."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    @classmethod
    def from_vector(cls, vector: np.ndarray) -> BodyPose:
        """The pose of ``(x, y, z, roll, pitch, yaw)``."""
        return cls(*(float(v) for v in np.asarray(vector, dtype=float).reshape(6)))

    def vector(self) -> np.ndarray:
        """``(x, y, z, roll, pitch, yaw)`` as an array."""
        return np.array(astuple(self), dtype=float)

    def as_dict(self) -> dict[str, float]:
        """The pose as ``{field: value}`` (the JSON of the ``pose`` command and the status)."""
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}

    def described(self) -> str:
        """The pose in words, e.g. ``x 0.01 m, roll 0.05 rad`` (``neutral``: every field 0)."""
        parts = [f"{name} {value:g} {OPTIONS[name].unit}"
                 for name, value in self.as_dict().items() if value]
        return ", ".join(parts) if parts else "neutral"

    @property
    def is_neutral(self) -> bool:
        """True for the neutral pose (every field 0)."""
        return not any(astuple(self))

    def rebased(self, height: float, new_height: float) -> BodyPose:
        """The same body pose relative to the standing height ``new_height`` [m] instead of
        ``height`` [m] (only ``z`` changes)."""
        return BodyPose(self.x, self.y, self.z + height - new_height, self.roll, self.pitch,
                        self.yaw)


#: The neutral standing pose.
NEUTRAL = BodyPose()


def _to_body(rotation: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """``R^T v`` for ``rotation`` ``(..., 3, 3)`` and ``vectors`` ``(..., n, 3)``."""
    return np.einsum("...ji,...nj->...ni", rotation, vectors)


def posed_feet(standing: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Foot targets ``(..., n_legs, 3)`` [m] in base_link of the body at ``pose``
    ``(..., 6)``, the feet fixed at ``standing`` ``(n_legs, 3)`` (base_link of the neutral
    pose): ``R^T (p - t)``."""
    pose = np.asarray(pose, dtype=float)
    rotation = rpy_matrix(pose[..., 3:])
    return _to_body(rotation, np.asarray(standing, dtype=float) - pose[..., None, :3])


def posed_foot_motion(standing: np.ndarray, pose: np.ndarray, rate: np.ndarray,
                      accel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Foot positions [m], velocities [m/s] and accelerations [m/s^2] ``(..., n_legs, 3)`` in
    base_link of a body moving with ``pose``, ``rate`` and ``accel`` ``(..., 6)`` (per s,
    per s^2), the feet fixed at ``standing``.

    With ``r = p - t`` and the body's angular velocity ``w`` (fixed frame):
    ``v' = -R^T (t' + w x r)``, ``a' = R^T (-t'' - w' x r + 2 w x t' + w x (w x r))``.
    """
    pose, rate, accel = (np.asarray(a, dtype=float) for a in (pose, rate, accel))
    rotation = rpy_matrix(pose[..., 3:])
    omega = rpy_angular_velocity(pose[..., 3:], rate[..., 3:])[..., None, :]
    omega_dot = rpy_angular_acceleration(pose[..., 3:], rate[..., 3:], accel[..., 3:])
    r = np.asarray(standing, dtype=float) - pose[..., None, :3]
    t_dot, t_ddot = rate[..., None, :3], accel[..., None, :3]
    w_r = np.cross(omega, r)
    vel = -_to_body(rotation, t_dot + w_r)
    acc = _to_body(rotation, -t_ddot - np.cross(omega_dot[..., None, :], r)
                   + 2.0 * np.cross(omega, t_dot) + np.cross(omega, w_r))
    return _to_body(rotation, r), vel, acc


def foot_state_at(standing: Sequence[float], pose: Sequence[float], rate: Sequence[float]
                  ) -> tuple[list[float], list[float]]:
    """`posed_foot_motion`'s positions [m] and velocities [m/s] for one instant, in plain
    floats (the planner's tick; equal to rounding): ``standing`` flat ``(3 n_legs,)``, leg-major
    x, y, z; ``pose`` and ``rate`` ``(6,)``; results flat like ``standing``."""
    x, y, z, roll, pitch, yaw = pose
    x_dot, y_dot, z_dot, roll_dot, pitch_dot, yaw_dot = rate
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    # columns of R = Rz Ry Rx (`rotations.rpy_matrix`): R^T v = (c0 . v, c1 . v, c2 . v)
    c0 = (cy * cp, sy * cp, -sp)
    c1 = (cy * sp * sr - sy * cr, sy * sp * sr + cy * cr, cp * sr)
    c2 = (cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr)
    wx = cy * cp * roll_dot - sy * pitch_dot  # `rotations.rpy_angular_velocity`
    wy = sy * cp * roll_dot + cy * pitch_dot
    wz = yaw_dot - sp * roll_dot
    pos: list[float] = []
    vel: list[float] = []
    for j in range(0, len(standing), 3):
        rx, ry, rz = standing[j] - x, standing[j + 1] - y, standing[j + 2] - z
        ux = x_dot + wy * rz - wz * ry  # t' + w x r
        uy = y_dot + wz * rx - wx * rz
        uz = z_dot + wx * ry - wy * rx
        for c in (c0, c1, c2):
            pos.append(c[0] * rx + c[1] * ry + c[2] * rz)
            vel.append(-(c[0] * ux + c[1] * uy + c[2] * uz))
    return pos, vel


def check_pose(cfg: Config, body_height: float, pose: BodyPose) -> np.ndarray:
    """Joint angles ``(n_legs, 3)`` [rad] of ``pose`` at the standing ``body_height`` [m].

    Raises `PoseError`: a field outside its range of the option table (``field`` set), a
    height outside ``body_height_range`` (``field`` "z"), or a foot outside its leg's
    workspace or joint limits (the message names the leg); `ConfigError` for a standing
    ``body_height`` outside ``body_height_range``.
    """
    standing = cfg.robot.standing_feet(body_height)
    for name, value in pose.as_dict().items():
        lo, hi = OPTIONS[name].range(cfg)
        if not (math.isfinite(value) and lo <= value <= hi):
            unit = OPTIONS[name].unit
            raise PoseError(f"{name} = {value:g} {unit} is outside [{lo:g}, {hi:g}] {unit}",
                            field=name)
    problem = pose_height_error(cfg, body_height, pose.z)
    if problem is not None:
        raise PoseError(problem, field="z")
    try:
        return inverse_kinematics(cfg.robot, posed_feet(standing, pose.vector()))
    except KinematicsError as exc:
        what = "a foot would leave its workspace" if isinstance(exc, UnreachableError) else (
            "a joint would leave its limits")
        raise PoseError(f"{what}: {exc}") from exc


class PosePath:
    """A pose move from ``start`` to ``end`` (`BodyPose`, relative to the standing
    ``body_height`` [m]) over ``duration`` [s] from t = 0: the pose's rest sextic and the
    foot targets it gives."""

    def __init__(self, robot: RobotConfig, body_height: float, start: BodyPose, end: BodyPose,
                 duration: float) -> None:
        self.robot = robot
        self.body_height = float(body_height)
        self.start, self.end = start, end
        self.standing = robot.standing_feet(body_height)
        self.path = Piecewise([rest_segment(start.vector(), end.vector(), duration, "pose")])
        self._cache: tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None

    @property
    def duration(self) -> float:
        """Duration [s]."""
        return self.path.duration

    def pose(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pose, its rate and acceleration ``(len(t), 6)`` at times ``t`` [s]."""
        return self.path.evaluate(t)

    def feet(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Foot positions, velocities, accelerations ``(len(t), n_legs, 3)`` in base_link."""
        times = np.atleast_1d(np.asarray(t, dtype=float))
        if self._cache is None or not np.array_equal(self._cache[0], times):
            self._cache = (times.copy(), posed_foot_motion(self.standing, *self.pose(times)))
        return self._cache[1]

    def joints(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles [rad] and rates [rad/s] ``(len(t), n_legs, 3)`` (limits checked)."""
        pos, vel, _ = self.feet(t)
        q = inverse_kinematics(self.robot, pos)
        return q, joint_velocities(self.robot, q, vel)

    def foot_paths(self) -> tuple[FootPath, ...]:
        """One `FootPath` per leg, for `gait.check_trajectories`."""
        return tuple(FootPath(self, leg) for leg in range(self.robot.n_legs))


class FootPath:
    """One leg's foot along a `PosePath`, with the part of the `Piecewise` interface that
    `gait.check_trajectories` samples (``t0``, ``t_end``, ``breaks``, ``evaluate``)."""

    def __init__(self, path: PosePath, leg: int) -> None:
        self._path, self._leg = path, leg
        self.t0, self.t_end = path.path.t0, path.path.t_end
        self.breaks = path.path.breaks

    def evaluate(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration ``(len(t), 3)`` of the foot in base_link."""
        pos, vel, acc = self._path.feet(t)
        return pos[:, self._leg], vel[:, self._leg], acc[:, self._leg]


def pose_move_duration(cfg: Config, body_height: float, start: BodyPose, end: BodyPose
                       ) -> float:
    """Duration [s] of the pose move from ``start`` to ``end``: at least `MIN_POSE_TIME`, the
    body's peak speed within ``body_pose.speed`` and the peak rate of its roll-pitch-yaw
    within ``turn_rate``, every joint at or below `POSE_SPEED_FRACTION` of its velocity limit
    (joint rates scale as 1 / duration along the same path). Raises `PoseError` if a sample
    leaves the workspace or the joint limits."""
    limits = cfg.body_pose
    delta = end.vector() - start.vector()
    duration = REST_PEAK_SPEED * max(float(np.linalg.norm(delta[:3])) / limits.speed,
                                     float(np.linalg.norm(delta[3:])) / limits.turn_rate)
    unit = PosePath(cfg.robot, body_height, start, end, 1.0)
    try:
        _, rates = unit.joints(np.linspace(0.0, 1.0, DURATION_SAMPLES))
    except KinematicsError as exc:  # between two poses within reach: rare
        where = "" if not exc.sample else (
            f" {exc.sample[0] / (DURATION_SAMPLES - 1):.0%} of the way")
        raise PoseError(f"the move to the pose cannot keep every foot on the ground: "
                        f"{str(exc).replace(f' at sample {exc.sample}', where)}") from exc
    joint = float(np.max(np.abs(rates) / (POSE_SPEED_FRACTION * cfg.robot.velocity)))
    return max(MIN_POSE_TIME, duration, joint)


def plan_pose_move(cfg: Config, body_height: float, start: BodyPose, end: BodyPose
                   ) -> PosePath:
    """The checked pose move from ``start`` (where the body is) to ``end`` (`check_pose`) at
    the standing ``body_height`` [m]; raises `PoseError` with the reason if it cannot be
    executed (nothing moves)."""
    check_pose(cfg, body_height, end)
    path = PosePath(cfg.robot, body_height, start, end,
                    pose_move_duration(cfg, body_height, start, end))
    try:
        check_trajectories(cfg.robot, path.foot_paths(), "the pose move")
    except GaitError as exc:
        raise PoseError(str(exc)) from exc
    return path
