"""Lock-step replay of a planned walk through the physics, recording what the body does."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.motion.gait import WalkPlan
from crawler_motion.sim.seabed.contacts import body_contact, foot_loads
from crawler_motion.sim.seabed.model import SeabedModel
from crawler_motion.sim.seabed.water import check_range


@dataclass(frozen=True)
class ReplayOptions:
    """Timing of a replay [s]: servo target period (the stack's 100 Hz), record period and the
    time the robot stands (at the walk's first pose) before the walk starts."""

    control_period: float = 0.01
    sample_period: float = 0.002
    settle_time: float = 0.5

    def __post_init__(self) -> None:
        check_range("control_period", self.control_period, 1e-4, 1.0, "s")
        check_range("sample_period", self.sample_period, 1e-4, self.control_period, "s")
        check_range("settle_time", self.settle_time, 0.0, 60.0, "s")


@dataclass
class Recording:
    """Samples of a replay, one row per sample (walk time starts at 0 with the plan)."""

    time: np.ndarray  # (n,) [s]
    base: np.ndarray  # (n, 7) position [m] and quaternion w, x, y, z of base_link
    feet: np.ndarray  # (n, n_legs, 3) foot centres in the world [m]
    foot_velocity: np.ndarray  # (n, n_legs, 6) linear [m/s] and angular [rad/s], world
    loads: np.ndarray  # (n, n_legs) normal force on each foot [N]
    body_contact: np.ndarray  # (n,) hull or a link touches the world
    torque: np.ndarray  # (n, 12) servo torques [N m]


def _steps(period: float, timestep: float, what: str) -> int:
    n = round(period / timestep)
    if n < 1 or not math.isclose(n * timestep, period, rel_tol=1e-6):
        raise CrawlerMotionError(f"{what} {period} s is not a whole number of physics steps "
                                 f"of {timestep} s")
    return n


def replay(sm: SeabedModel, plan: WalkPlan, options: ReplayOptions | None = None,
           data: mujoco.MjData | None = None,
           observer: Callable[[mujoco.MjData], None] | None = None) -> Recording:
    """Drive the servos with the plan's joint angles (held per control period) and record.

    ``observer`` (e.g. a frame recorder) sees the state after every control period.
    Raises `CrawlerMotionError` if the simulation goes unstable (non-finite state).
    """
    opt = options or ReplayOptions()
    m, dt = sm.model, sm.timestep
    per_sample = _steps(opt.sample_period, dt, "sample_period")
    per_control = _steps(opt.control_period, dt * per_sample, "control_period") * per_sample
    ticks = np.arange(0.0, plan.duration + 1e-9, opt.control_period)
    targets = plan.joints(ticks)[0].reshape(len(ticks), -1)
    data = data if data is not None else sm.make_data(targets[0])
    data.ctrl[:] = targets[0]
    sm.settle(data, opt.settle_time)
    n = len(ticks) * (per_control // per_sample)
    n_legs = sm.robot.n_legs
    rec = Recording(time=np.zeros(n), base=np.zeros((n, 7)), feet=np.zeros((n, n_legs, 3)),
                    foot_velocity=np.zeros((n, n_legs, 6)), loads=np.zeros((n, n_legs)),
                    body_contact=np.zeros(n, dtype=bool), torque=np.zeros((n, m.nu)))
    t0, k = data.time, 0
    for target in targets:
        data.ctrl[:] = target
        for _ in range(per_control // per_sample):
            mujoco.mj_step(m, data, nstep=per_sample)
            _record(sm, data, rec, k, t0)
            k += 1
        if observer is not None:
            observer(data)
    return rec


def _record(sm: SeabedModel, data: mujoco.MjData, rec: Recording, k: int, t0: float) -> None:
    if not np.all(np.isfinite(data.qpos[:7])):
        raise CrawlerMotionError(f"simulation unstable at t = {data.time:.3f} s "
                                 f"(non-finite body state)")
    rec.time[k] = data.time - t0
    rec.base[k] = data.qpos[:7]
    rec.feet[k] = data.site_xpos[sm.foot_sites]
    rec.foot_velocity[k] = data.sensordata[:6 * sm.robot.n_legs].reshape(-1, 6)
    rec.loads[k] = foot_loads(sm, data)
    rec.body_contact[k] = body_contact(sm, data)
    rec.torque[k] = data.actuator_force
