"""Offline walk evaluation: replay a planned walk through the physics, figures per gait cycle.

``evaluate_walk(cfg, params, steps, settings, world)`` plans the walk with `plan_walk`, replays
it in lock-step (`replay`) and measures every steady gait cycle as `metrics` describes.
"""

from __future__ import annotations

import math
import time as clock
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from crawler_motion.model.config import Config
from crawler_motion.model.medium import MediumConfig
from crawler_motion.motion.gait import WalkParams, plan_walk
from crawler_motion.sim.seabed.metrics import (
    PlanPhases,
    attitude,
    body_motion,
    no_slip_path,
    plan_phases,
    stance_runs,
    steady_cycles,
    zmp_distances,
)
from crawler_motion.sim.seabed.model import SeabedModel, SimSettings
from crawler_motion.sim.seabed.replay import Recording, ReplayOptions, replay
from crawler_motion.sim.seabed.water import Medium

#: A foot is loaded above this share of its part (1 / n_legs) of the net weight.
LOAD_THRESHOLD = 0.1
#: The middle part of a swing checked for ground contact (swing phase bounds).
MID_SWING = (0.25, 0.75)


@dataclass(frozen=True)
class CycleMetrics:
    """Figures of one steady gait cycle (lengths m, angles rad, speeds m/s, torques N m)."""

    planned_advance: float
    advance: float
    advance_ratio: float  # NaN when the plan does not translate (turn on the spot)
    lateral_drift: float
    planned_turn: float
    turn: float
    yaw_drift: float
    turn_ratio: float  # NaN when the plan does not turn
    slip_mean: float  # loaded contact-point slip speed [m/s]
    slip_max: float
    stance_slip_mean: float  # loaded slip distance per stance [m]
    stance_slip_max: float
    stance_displacement: float  # mean net slide of the contact point per stance [m]
    centre_travel: float  # mean horizontal travel of the foot centre per stance, roll incl. [m]
    stance_contact_loss: float  # share of stance samples
    zmp_mean: float  # measured ZMP's distance to the support line, two-feet samples [m]
    zmp_p95: float
    midswing_contact: float  # share of mid-swing samples
    roll_max: float
    pitch_max: float
    height_variation: float
    body_contact: float  # share of samples
    torque_p99: float


#: Figures summarised by their maximum over the cycles (the others by their mean).
_MAXIMA = ("slip_max", "stance_slip_max", "roll_max", "pitch_max", "torque_p99",
           "height_variation")


@dataclass
class EvalResult:
    """Result of `evaluate_walk`: the walk, the run and the per-cycle figures."""

    world: str
    medium: str
    params: dict
    steps: int
    sim_time: float  # simulated walk time [s]
    wall_time: float  # computing time of the replay [s]
    cycles: list[CycleMetrics] = field(default_factory=list)

    @property
    def speedup(self) -> float:
        """Simulated time per computing time (> 1: faster than real time)."""
        return self.sim_time / self.wall_time if self.wall_time > 0 else math.inf

    def summary(self) -> dict[str, float]:
        """Every figure over the steady cycles: mean, or max for peaks (see ``_MAXIMA``)."""
        if not self.cycles:
            return {}
        table = {k: np.array([getattr(c, k) for c in self.cycles], dtype=float)
                 for k in CycleMetrics.__dataclass_fields__}
        return {k: float(np.max(v) if k in _MAXIMA else np.mean(v)) for k, v in table.items()}

    def to_dict(self) -> dict:
        """Plain data for JSON (NaN becomes None)."""
        def clean(value: object) -> object:
            if isinstance(value, float) and not math.isfinite(value):
                return None
            if isinstance(value, dict):
                return {k: clean(v) for k, v in value.items()}
            if isinstance(value, list):
                return [clean(v) for v in value]
            return value

        return clean({"world": self.world, "medium": self.medium, "params": self.params,
                      "steps": self.steps, "sim_time": self.sim_time,
                      "wall_time": self.wall_time, "speedup": self.speedup,
                      "summary": self.summary(),
                      "cycles": [asdict(c) for c in self.cycles]})  # type: ignore[return-value]


def evaluate_walk(cfg: Config, params: WalkParams, steps: int = 4,
                  settings: SimSettings | None = None, world: str | Path | None = None,
                  options: ReplayOptions | None = None) -> EvalResult:
    """Plan ``steps`` gait cycles with ``params``, replay them on ``world`` and measure them
    (the planner's medium is the simulated one, `medium_of`)."""
    settings = SimSettings() if settings is None else settings
    cfg = replace(cfg, medium=medium_of(cfg, settings))
    plan = plan_walk(cfg, params, steps)
    sm = SeabedModel(cfg.robot, settings, world)
    start = clock.perf_counter()
    rec = replay(sm, plan, options)
    wall = clock.perf_counter() - start
    net = sm.dry_weight * (1.0 - sm.settings.water.buoyancy_fraction)
    threshold = LOAD_THRESHOLD * net / cfg.robot.n_legs
    phases = plan_phases(plan, rec.time)
    path = no_slip_path(plan, rec.time, phases.stance)
    rpy = attitude(rec.base[:, 3:])
    runs = stance_runs(phases.stance)
    contact = _contact_velocity(rec, sm.foot_radius)
    slip = np.hypot(contact[..., 0], contact[..., 1])
    zmp = zmp_distances(rec, phases.stance,
                        cfg.medium.omega2(float(plan.slots[0].params.body_height)),
                        cfg.medium.zmp_shift)  # the medium set above, `medium_of`
    cycles = []
    for k0, k1 in steady_cycles(plan, rec.time):
        cycles.append(_cycle(rec, phases, path, rpy, runs, (contact, slip), threshold, k0, k1,
                             zmp))
    return EvalResult(world=sm.world.source, medium=sm.settings.water.medium.value,
                      params=asdict(plan.slots[0].params), steps=steps,
                      sim_time=float(plan.duration), wall_time=wall, cycles=cycles)


def medium_of(cfg: Config, settings: SimSettings) -> MediumConfig:
    """The planner's medium for a walk in ``settings``: the config's in water, full weight on
    land (`MediumConfig.on_land`)."""
    return cfg.medium.on_land() if settings.water.medium is Medium.LAND else cfg.medium


def _contact_velocity(rec: Recording, radius: float) -> np.ndarray:
    """Velocity of each foot's contact point parallel to the ground ``(n, n_legs, 2)``
    [m/s]: the material point of the sphere touching the ground (zero when it rolls)."""
    lin, ang = rec.foot_velocity[..., :3], rec.foot_velocity[..., 3:]
    return np.stack((lin[..., 0] - radius * ang[..., 1],  # v + w x (0, 0, -r)
                     lin[..., 1] + radius * ang[..., 0]), axis=-1)


def net_slide(velocity: np.ndarray, time: np.ndarray) -> float:
    """Net horizontal slide [m] of a foot's contact point whose velocity ``(n, 2)`` [m/s]
    (`_contact_velocity`) is sampled at ``time`` ``(n,)`` [s]: how far the sphere's material
    point touching the ground has moved from where it was (0 for a sphere that rolls)."""
    return float(np.hypot(*np.trapezoid(velocity, time, axis=0)))


def _cycle(rec: Recording, phases: PlanPhases, path: np.ndarray, rpy: np.ndarray, runs: list,
           contact_slip: tuple[np.ndarray, np.ndarray], threshold: float, k0: int, k1: int,
           zmp: np.ndarray) -> CycleMetrics:
    """One cycle's figures; ``contact_slip``: the contact points' velocities ``(n, n_legs,
    2)`` [m/s] and their speeds ``(n, n_legs)`` [m/s] over the whole walk."""
    part = slice(k0, k1)
    contact, slip = contact_slip
    loaded = rec.loads[part] > threshold
    stance = phases.stance[part]
    swing = phases.swing_phase[part]
    mid = (swing >= MID_SWING[0]) & (swing <= MID_SWING[1])
    slips = slip[part][loaded & stance]
    centre = [float(np.hypot(*(rec.feet[b, leg, :2] - rec.feet[a, leg, :2])))
              for leg, a, b in runs if k0 <= a < k1]
    dt = np.gradient(rec.time)
    travel = [net_slide(contact[a:b + 1, leg], rec.time[a:b + 1])
              for leg, a, b in runs if k0 <= a < k1]
    loaded_all = rec.loads > threshold
    per_stance = [float(np.sum((slip[a:b + 1, leg] * dt[a:b + 1])[loaded_all[a:b + 1, leg]]))
                  for leg, a, b in runs if k0 <= a < k1]
    zmp_part = zmp[part][np.isfinite(zmp[part])]
    return CycleMetrics(
        **body_motion(rec, path, k0, k1, rpy),
        zmp_mean=float(zmp_part.mean()) if zmp_part.size else math.nan,
        zmp_p95=float(np.percentile(zmp_part, 95)) if zmp_part.size else math.nan,
        slip_mean=float(slips.mean()) if slips.size else 0.0,
        slip_max=float(slips.max()) if slips.size else 0.0,
        stance_slip_mean=float(np.mean(per_stance)) if per_stance else 0.0,
        stance_slip_max=float(np.max(per_stance)) if per_stance else 0.0,
        stance_displacement=float(np.mean(travel)) if travel else 0.0,
        centre_travel=float(np.mean(centre)) if centre else 0.0,
        stance_contact_loss=float((stance & ~loaded).sum() / max(stance.sum(), 1)),
        midswing_contact=float((mid & (rec.loads[part] > 0.0)).sum() / max(mid.sum(), 1)),
        roll_max=float(np.abs(rpy[part, 0]).max()),
        pitch_max=float(np.abs(rpy[part, 1]).max()),
        height_variation=float(np.ptp(rec.base[part, 2])),
        body_contact=float(rec.body_contact[part].mean()),
        torque_p99=float(np.percentile(np.abs(rec.torque[part]), 99)))


#: Columns of `format_table`: header, summary key, scale to display units, format.
TABLE_COLUMNS: tuple[tuple[str, str, float, str], ...] = (
    ("adv", "advance_ratio", 1.0, "{:5.2f}"), ("lat mm", "lateral_drift", 1e3, "{:6.1f}"),
    ("yaw °", "yaw_drift", 180 / math.pi, "{:5.1f}"), ("turn", "turn_ratio", 1.0, "{:5.2f}"),
    ("slip mm", "stance_slip_mean", 1e3, "{:5.1f}"), ("max", "stance_slip_max", 1e3, "{:5.1f}"),
    ("foot mm", "stance_displacement", 1e3, "{:5.1f}"),
    ("ctr mm", "centre_travel", 1e3, "{:5.1f}"),
    ("loss %", "stance_contact_loss", 100.0, "{:5.1f}"),
    ("zmp mm", "zmp_mean", 1e3, "{:5.1f}"), ("p95", "zmp_p95", 1e3, "{:5.1f}"),
    ("scuff %", "midswing_contact", 100.0, "{:5.1f}"),
    ("roll °", "roll_max", 180 / math.pi, "{:5.1f}"),
    ("pitch °", "pitch_max", 180 / math.pi, "{:5.1f}"),
    ("dz mm", "height_variation", 1e3, "{:5.1f}"), ("hull %", "body_contact", 100.0, "{:5.1f}"),
    ("τ99 N m", "torque_p99", 1.0, "{:5.2f}"),
)


def format_table(rows: list[tuple[str, EvalResult]]) -> str:
    """Plain-text table of labelled results, one row each (figures: `EvalResult.summary`)."""
    width = max([len(label) for label, _ in rows] + [4])
    header = " | ".join([f"{'walk':<{width}}", *(f"{h:>7}" for h, *_ in TABLE_COLUMNS)])
    lines = [header, "-" * len(header)]
    for label, result in rows:
        summary = result.summary()
        cells = []
        for _, key, scale, fmt in TABLE_COLUMNS:
            value = summary.get(key, math.nan)
            cells.append(f"{'-' if not math.isfinite(value) else fmt.format(value * scale):>7}")
        lines.append(" | ".join([f"{label:<{width}}", *cells]))
    return "\n".join(lines)
