"""Lock-step closed loop of the terrain-adaptive touch-down: seabed physics and the planner core
with its foot contacts, on simulated time (deterministic, faster than real time).

The same cores as the ``seabed_sim`` and ``planner_node`` processes: physics stepped per 10 ms
control tick, the planner's contact monitor fed with the simulated joint angles and the servo
torques averaged over the tick (what the effort frames carry), then the planner core ticked
at 100 Hz. It records what the rough-seabed targets are judged by: the body's path and
attitude, the joint torques and the planner's end state.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from crawler_motion.model.config import Config
from crawler_motion.model.rotations import quaternion_matrix
from crawler_motion.motion.attitude import AttitudeMode, AttitudeSettings
from crawler_motion.motion.foothold import FootholdSettings
from crawler_motion.motion.gait import WalkParams, iter_walk
from crawler_motion.motion.stumble import StumbleSettings
from crawler_motion.planner.commands import WALK_KEYS
from crawler_motion.planner.core import PlannerCore
from crawler_motion.sim.seabed.model import IMU_SENSORS, SeabedModel, SimSettings
from crawler_motion.testing.lockstep import LockStep

CONTROL_PERIOD = 0.01  # [s]


@dataclass
class WalkRecord:
    """What a closed-loop walk did: times [s], world positions [m], angles [rad], torques
    [N m] as shares of the effort limit."""

    state: str = ""
    events: list[str] = field(default_factory=list)
    planned_advance: float = 0.0  # the plan's no-slip body travel [m]
    time: list[float] = field(default_factory=list)
    position: list[np.ndarray] = field(default_factory=list)
    pitch: list[float] = field(default_factory=list)
    roll: list[float] = field(default_factory=list)
    yaw: list[float] = field(default_factory=list)
    torque: list[np.ndarray] = field(default_factory=list)  # |tau| / limit per joint

    @property
    def advance(self) -> float:
        """Body travel along world x from the walk's start [m]."""
        return float(self.position[-1][0] - self.position[0][0])

    @property
    def advance_ratio(self) -> float:
        """`advance` over the plan's no-slip body travel."""
        return self.advance / self.planned_advance

    @property
    def max_pitch(self) -> float:
        """Largest |pitch| of the body [rad]."""
        return float(np.max(np.abs(self.pitch)))

    @property
    def max_roll(self) -> float:
        """Largest |roll| of the body [rad]."""
        return float(np.max(np.abs(self.roll)))

    @property
    def yaw_change(self) -> float:
        """The body's yaw change over the walk [rad]."""
        return float(self.yaw[-1] - self.yaw[0])

    @property
    def max_torque(self) -> float:
        """Largest |joint torque| as a share of its effort limit."""
        return float(np.max(self.torque))

    def summary(self) -> str:
        """One line of the figures."""
        return (f"advance {self.advance * 1e3:.1f} mm of {self.planned_advance * 1e3:.1f} mm "
                f"(ratio {self.advance_ratio:.2f}), max pitch "
                f"{math.degrees(self.max_pitch):.1f} deg, max torque "
                f"{self.max_torque * 100:.0f} % of the limit, final x "
                f"{self.position[-1][0]:.3f} m, state {self.state}")


def planned_advance(cfg: Config, params: WalkParams, steps: int) -> float:
    """Body travel [m] of a walk's plan along its heading, without slip: the sum over slots
    of what a stance foot's contact point moves back (the sway cancels over the walk)."""
    total = 0.0
    heading = np.array([math.cos(params.heading), math.sin(params.heading)])
    for slot in iter_walk(cfg, params, steps):
        i = next(k for k in range(cfg.robot.n_legs) if k not in slot.group)
        c = slot.contacts[i]
        start, end = c.evaluate(c.t0)[0][0, :2], c.evaluate(c.t_end)[0][0, :2]
        total += float((start - end) @ heading)
    return total


class FootholdLoop(LockStep):
    """One robot in one world, walking a number of steps with the planner core."""

    def __init__(self, cfg: Config, world: str, foothold: FootholdSettings | None = None,
                 start: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 stumble: StumbleSettings | None = None,
                 attitude: AttitudeSettings | None = None) -> None:
        """``start``: x, y [m], yaw [rad] of the body in the world; ``stumble`` and
        ``attitude`` default to the planner's defaults. With the ``imu`` attitude mode the
        planner gets the body's simulated roll and pitch every tick (the IMU's orientation)."""
        self.cfg = cfg
        self.robot = cfg.robot
        self.sm = SeabedModel(cfg.robot, SimSettings(start_pose=start), world)
        self.data = self.sm.make_data()
        self.sm.settle(self.data, 0.3)
        self.core = PlannerCore(cfg, 1.0 / CONTROL_PERIOD)
        self.core.walk.foothold.configure(foothold or FootholdSettings(), stumble, attitude)
        self.limit = np.tile(np.broadcast_to(self.robot.effort, (3,)), self.robot.n_legs)
        self.t = 0.0
        self.tau = np.zeros(3 * self.robot.n_legs)

    def _physics(self) -> None:
        """One control period of physics; the servo torques averaged over it."""
        n = max(1, round(CONTROL_PERIOD / self.sm.timestep))
        total = np.zeros_like(self.tau)
        for _ in range(n):
            mujoco.mj_step(self.sm.model, self.data)
            total += self.data.actuator_force
        self.tau = total / n

    def tick(self) -> None:
        """One control period: joint state (with efforts) to the planner, planner, physics."""
        q = self.joints()
        self.core.set_measured(q, self.t)
        self.core.contacts.update(self.robot.joint_names, q, self.tau, self.t, self.t)
        footholds = self.core.walk.foothold
        if footholds.attitude.mode is AttitudeMode.IMU:
            roll, pitch, _ = self.attitude(self.data.sensor(IMU_SENSORS[2]).data)
            footholds.measure_attitude(roll, pitch)
        target = self.core.tick(self.t)
        if target is not None:
            self.data.ctrl[:] = target.positions
        self._physics()
        self.t += CONTROL_PERIOD

    def walk(self, params: WalkParams, steps: int, limit: float = 60.0) -> WalkRecord:
        """Stand, walk ``steps`` steps of ``params`` (sent as a gait command), until standing
        or holding again or ``limit`` [s] of simulated time."""
        self.stand()
        rec = WalkRecord(planned_advance=planned_advance(self.cfg, params, steps))
        command = {"command": "walk", "steps": steps, **{
            key: value for key, value in dataclasses.asdict(params).items()
            if key in WALK_KEYS and value is not None}}
        self.core.submit(json.dumps(command), self.t)
        end = self.t + limit
        while self.t < end:
            self.tick()
            self._record(rec)
            if self.core.state in ("STANDING", "HOLDING"):
                break
        rec.state = self.core.state
        rec.events = [f"{level}: {message}" for level, message in self.core.pop_events()]
        return rec

    def attitude(self, quaternion: np.ndarray | None = None) -> tuple[float, float, float]:
        """Roll, pitch, yaw [rad] (fixed-axis, REP-103) of ``quaternion`` (w, x, y, z; default
        the body's orientation in the world)."""
        rot = quaternion_matrix(self.data.qpos[3:7] if quaternion is None else quaternion)
        return (math.atan2(float(rot[2, 1]), float(rot[2, 2])),
                math.asin(-max(-1.0, min(1.0, float(rot[2, 0])))),
                math.atan2(float(rot[1, 0]), float(rot[0, 0])))

    def _record(self, rec: WalkRecord) -> None:
        roll, pitch, yaw = self.attitude()
        rec.time.append(self.t)
        rec.position.append(self.data.qpos[:3].copy())
        rec.pitch.append(pitch)
        rec.roll.append(roll)
        rec.yaw.append(yaw)
        rec.torque.append(np.abs(self.tau) / self.limit)
