"""Effort traces: what the driver would publish while the seabed simulator walks, with the truth.

`record_effort_trace` drives a `SeabedPlant` with a planned walk at the feedback period, as the
simulated manager does, and keeps per feedback period what ``joint_states`` would carry (the
measured joint angles and the mean drive torques, both through the CAN codec, so quantised as
on the bus) and the truth: each foot's mean normal force over the same period. The contact
estimation tests run on such traces (`save_trace`, `load_trace`: a compressed NPZ).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from crawler_motion.canbus.protocol import EffortFeedback, MotorProtocol, PositionFeedback
from crawler_motion.model.config import Config
from crawler_motion.motion.gait import WalkParams, plan_walk
from crawler_motion.sim.seabed.contacts import foot_loads
from crawler_motion.sim.seabed.model import SeabedModel, SimSettings
from crawler_motion.sim.seabed.plant import SeabedPlant

#: Feedback period of the simulated manager [s] (100 Hz).
PERIOD = 0.01
#: Standing time at the walk's first pose before the walk starts [s].
SETTLE_TIME = 0.5


@dataclass(frozen=True)
class EffortTrace:
    """One sample per feedback period: ``time`` ``(n,)`` [s] (0 at the walk's start),
    ``positions`` and ``efforts`` ``(n, 12)`` in joint order [rad], [N m], ``loads``
    ``(n, n_legs)`` each foot's mean normal force over the period [N] (the truth), and
    ``net_weight`` the robot's weight in water [N]; ``world`` the world file's name."""

    time: np.ndarray
    positions: np.ndarray
    efforts: np.ndarray
    loads: np.ndarray
    net_weight: float
    gait: str
    world: str


def _over_the_bus(protocol: MotorProtocol, axes: np.ndarray, axis_efforts: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles [rad] and torques [N m] as the driver decodes them from the frames."""
    index = {name: i for i, name in enumerate(protocol.joint_names)}
    q, tau = np.empty(protocol.n_axes), np.empty(protocol.n_axes)
    frames = protocol.encode_efforts(axis_efforts, 0) + protocol.encode_feedback(axes, 0)
    for msg in frames:
        frame = protocol.decode(msg)
        if isinstance(frame, PositionFeedback):
            for joint, value in frame.positions.items():
                q[index[joint]] = value
        elif isinstance(frame, EffortFeedback):
            for joint, value in frame.efforts.items():
                tau[index[joint]] = value
    return q, tau


def record_effort_trace(cfg: Config, params: WalkParams, steps: int,
                        world: str | Path | None = None,
                        settings: SimSettings | None = None) -> EffortTrace:
    """Walk ``steps`` gait cycles of ``params`` on ``world`` and record the trace."""
    plan = plan_walk(cfg, params, steps)
    sm = SeabedModel(cfg.robot, settings, world)
    protocol = MotorProtocol.from_config(cfg.robot)
    plant = SeabedPlant(sm, protocol)
    ticks = np.arange(0.0, plan.duration + 1e-9, PERIOD)
    targets = plan.joints(ticks)[0].reshape(len(ticks), -1)
    first = protocol.to_axis(targets[0])
    for _ in range(round(SETTLE_TIME / PERIOD)):
        plant.advance(PERIOD, first)
    plant.take_efforts()
    load_sum = np.zeros(cfg.robot.n_legs + 1)  # the loads [N] and the number of steps

    def add_loads(data: mujoco.MjData) -> None:
        load_sum[:-1] += foot_loads(sm, data)
        load_sum[-1] += 1

    plant.on_step = add_loads
    n = len(ticks)
    q, tau = np.empty((n, protocol.n_axes)), np.empty((n, protocol.n_axes))
    loads = np.empty((n, cfg.robot.n_legs))
    for k, target in enumerate(targets):
        load_sum[:] = 0.0
        axes = plant.advance(PERIOD, protocol.to_axis(target))
        q[k], tau[k] = _over_the_bus(protocol, axes, plant.take_efforts())
        loads[k] = load_sum[:-1] / max(load_sum[-1], 1.0)
    if plant.failure is not None:
        raise RuntimeError(plant.failure)
    net = sm.dry_weight * (1.0 - sm.settings.water.buoyancy_fraction)
    return EffortTrace(ticks + PERIOD, q, tau, loads, net, params.gait,
                       Path(sm.world.source).stem)


def save_trace(trace: EffortTrace, path: str | Path) -> None:
    """Write ``trace`` as a compressed NPZ (float32 samples)."""
    np.savez_compressed(path, time=trace.time.astype(np.float32),
                        positions=trace.positions.astype(np.float32),
                        efforts=trace.efforts.astype(np.float32),
                        loads=trace.loads.astype(np.float32),
                        net_weight=np.float64(trace.net_weight), gait=trace.gait,
                        world=trace.world)


def load_trace(path: str | Path) -> EffortTrace:
    """Read a trace written by `save_trace` (samples as float64)."""
    with np.load(path) as data:
        return EffortTrace(*(data[k].astype(float) for k in ("time", "positions", "efforts",
                                                             "loads")),
                           net_weight=float(data["net_weight"]), gait=str(data["gait"]),
                           world=str(data["world"]))


def main(argv: list[str] | None = None) -> int:
    """``python -m crawler_motion.sim.seabed.effort_trace OUT.npz [--gait G] [--world W]
    [--steps N]``: record a trace with the shipped robot and gait defaults."""
    import argparse
    from dataclasses import replace

    from crawler_motion.model.config import load_config

    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("out", help="NPZ file to write")
    parser.add_argument("--gait", default=None, help="gait (default: the config's)")
    parser.add_argument("--world", default=None, help="world file or name (default: flat)")
    parser.add_argument("--steps", type=int, default=2, help="gait cycles (default 2)")
    args = parser.parse_args(argv)
    cfg = load_config()
    params = WalkParams.defaults(cfg.gait)
    if args.gait is not None:
        params = replace(params, gait=args.gait)
    trace = record_effort_trace(cfg, params, args.steps, args.world)
    save_trace(trace, args.out)
    print(f"{args.out}: {len(trace.time)} samples, {trace.gait} on {trace.world}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
