"""Per-gait-cycle figures of a recorded walk, measured against the plan's no-slip body path.

How each figure is measured (so figures compare between runs):

- cycles: consecutive runs of ``n_groups`` steady slots, each starting with the same swing
  group, so every cycle starts at the same gait phase;
- planned motion: the no-slip body path, i.e. the planar rigid motion of the body that keeps
  the plan's stance feet fixed on the ground (a weighted 2-D Procrustes fit of the planned
  stance feet between consecutive samples, integrated), not the ``stride`` parameter;
- advance: the body's true displacement over the cycle, in the body frame at the cycle start,
  projected on the planned displacement (ratio = advance / planned); lateral drift: its part
  perpendicular to it (+ left) [m]; yaw drift: true minus planned yaw change [rad];
- loaded foot slip: speed of the foot sphere's contact point (centre velocity + ω × (−r ẑ))
  parallel to the ground while the foot is in its planned stance and carries more than
  ``LOAD_THRESHOLD`` of its share of the net weight [m/s] (a loaded swing foot is counted as
  mid-swing contact instead);
- loaded slip per stance: that speed integrated over each planned stance's loaded samples
  [m] (mean and max over the cycle's stances);
- stance-foot displacement: net slide of the foot's contact point over each planned stance,
  the contact point's velocity (as for the slip, loaded or not) integrated [m]: a foot that
  rolls without sliding has not slid (the plan rolls the sphere on purpose, `motion.contact`;
  the point of the ground under it moves by the roll); the foot centre's own travel, roll
  included, is reported beside it. The ground's normal is taken as +z (on relief and rocks
  the figure, like the slip, is approximate);
- stance contact loss: share of planned-stance samples with the foot below the threshold;
- mid-swing contact: share of samples in the middle half of a swing with any foot load;
- body contact: share of samples with the hull or a link touching the world;
- torque p99: 99th percentile of the servo torque magnitudes (touch-down impacts are peaks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crawler_motion.motion.gait import WalkPlan
from crawler_motion.motion.zmp import line_distance, zmp_of
from crawler_motion.sim.seabed.replay import Recording


@dataclass(frozen=True)
class PlanPhases:
    """Per sample and leg: planned stance (bool) and swing phase in [0, 1) (NaN in stance)."""

    stance: np.ndarray  # (n, n_legs)
    swing_phase: np.ndarray  # (n, n_legs)


def plan_phases(plan: WalkPlan, time: np.ndarray) -> PlanPhases:
    """Which legs the plan has on the ground at each time [s]."""
    n_legs = len(plan.legs)
    idx = np.clip(np.searchsorted(plan.starts, time, side="right") - 1, 0, len(plan.slots) - 1)
    member = np.zeros((len(plan.slots), n_legs), dtype=bool)
    for s, slot in enumerate(plan.slots):
        member[s, list(slot.group)] = True
    swing_time = np.array([slot.swing_time for slot in plan.slots])[idx]
    elapsed = time - plan.starts[idx]
    phase = np.divide(elapsed, swing_time, out=np.full_like(elapsed, np.inf),
                      where=swing_time > 0)  # a slot without a swing: every foot down
    swinging = member[idx] & ((phase > 0.0) & (phase < 1.0))[:, None]  # on the ground at A, E
    return PlanPhases(stance=~swinging,
                      swing_phase=np.where(swinging, phase[:, None], np.nan))


def no_slip_path(plan: WalkPlan, time: np.ndarray, stance: np.ndarray) -> np.ndarray:
    """Planned planar body pose ``(n, 3)`` (x [m], y [m], yaw [rad]) from the first sample,
    keeping the planned stance feet's contact points fixed on the ground."""
    feet = plan.contact_points(time)[..., :2]  # (n, n_legs, 2) in base_link
    w = (stance[1:] & stance[:-1]).astype(float)  # feet on the ground at both samples
    wsum = np.maximum(w.sum(axis=1, keepdims=True), 1e-12)
    src, dst = feet[1:], feet[:-1]  # body k+1 coordinates -> body k coordinates
    cs = (w[..., None] * src).sum(axis=1) / wsum
    cd = (w[..., None] * dst).sum(axis=1) / wsum
    a, b = src - cs[:, None], dst - cd[:, None]
    cross = (w * (a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])).sum(axis=1)
    dot = (w * (a * b).sum(axis=-1)).sum(axis=1)
    dyaw = np.arctan2(cross, dot)
    c, s = np.cos(dyaw), np.sin(dyaw)
    step = cd - np.stack((c * cs[:, 0] - s * cs[:, 1], s * cs[:, 0] + c * cs[:, 1]), axis=-1)
    yaw = np.concatenate(([0.0], np.cumsum(dyaw)))
    world = (step[:, 0] + 1j * step[:, 1]) * np.exp(1j * yaw[:-1])
    pos = np.concatenate(([0.0], np.cumsum(world)))
    return np.stack((pos.real, pos.imag, yaw), axis=-1)


def planned_displacement(plan: WalkPlan, period: float = 0.002) -> np.ndarray:
    """The whole walk's no-slip body displacement (x [m], y [m], yaw [rad]) in the body frame
    at its start, from the plan sampled every ``period`` [s] (2 ms: within 1e-6 m)."""
    swing_ends = plan.starts + np.array([slot.swing_time for slot in plan.slots])
    time = np.union1d(np.arange(0.0, plan.duration, period),  # every lift-off and touch-down
                      np.concatenate((plan.starts, swing_ends, [plan.duration])))
    return no_slip_path(plan, time, plan_phases(plan, time).stance)[-1]


def steady_cycles(plan: WalkPlan, time: np.ndarray) -> list[tuple[int, int]]:
    """Sample index ranges ``[k0, k1]`` of the steady gait cycles."""
    n = len({slot.group for slot in plan.slots if slot.group})
    steady = [i for i, slot in enumerate(plan.slots) if slot.kind == "steady"]
    cycles = []
    for first in range(0, len(steady) - n + 1, n):
        t0 = plan.starts[steady[first]]
        t1 = t0 + sum(plan.slots[i].duration for i in steady[first:first + n])
        k0, k1 = np.searchsorted(time, [t0 - 1e-9, t1 - 1e-9])
        cycles.append((int(k0), int(min(k1, len(time) - 1))))
    return cycles


def attitude(quat: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw ``(n, 3)`` [rad] of unit quaternions ``(n, 4)`` (w, x, y, z)."""
    w, x, y, z = quat.T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack((roll, pitch, yaw), axis=-1)


def _wrap(angle: float) -> float:
    return math.remainder(angle, 2 * math.pi)


def body_motion(rec: Recording, path: np.ndarray, k0: int, k1: int, rpy: np.ndarray
                ) -> dict[str, float]:
    """Advance, drifts and turn of one cycle (true vs planned)."""
    planned = path[k1] - path[k0]
    c, s = math.cos(path[k0, 2]), math.sin(path[k0, 2])
    plan_d = np.array([c * planned[0] + s * planned[1], -s * planned[0] + c * planned[1]])
    yaw0 = rpy[k0, 2]
    true = rec.base[k1, :2] - rec.base[k0, :2]
    true_d = np.array([math.cos(yaw0) * true[0] + math.sin(yaw0) * true[1],
                       -math.sin(yaw0) * true[0] + math.cos(yaw0) * true[1]])
    true_turn = _wrap(rpy[k1, 2] - yaw0)
    length = float(np.hypot(*plan_d))
    unit = plan_d / length if length > 1e-3 else np.array([1.0, 0.0])
    advance = float(true_d @ unit)
    return {
        "planned_advance": length,
        "advance": advance,
        "advance_ratio": advance / length if length > 1e-3 else math.nan,
        "lateral_drift": float(unit[0] * true_d[1] - unit[1] * true_d[0]),
        "planned_turn": float(planned[2]),
        "turn": true_turn,
        "yaw_drift": true_turn - float(planned[2]),
        "turn_ratio": true_turn / planned[2] if abs(planned[2]) > 1e-3 else math.nan,
    }


def stance_runs(stance: np.ndarray) -> list[tuple[int, int, int]]:
    """Planned stance runs ``(leg, first, last)`` sample indices, whole walk."""
    runs = []
    for leg in range(stance.shape[1]):
        edges = np.diff(np.concatenate(([0], stance[:, leg].astype(int), [0])))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
        runs += [(leg, int(a), int(b)) for a, b in zip(starts, ends, strict=True)]
    return runs


#: Width of the moving average that smooths the measured body acceleration [s] (contact
#: impacts ring at the physics step; the pendulum's time constant is ~0.2 s).
ZMP_SMOOTHING = 0.02


def measured_zmp(rec: Recording, omega2: float, shift: np.ndarray) -> np.ndarray:
    """The zero-moment point ``(n, 2)`` [m, world] of the body centre's measured horizontal
    motion (`motion.zmp.zmp_of`; the acceleration smoothed over `ZMP_SMOOTHING`)."""
    centre = rec.base[:, :2]
    dt = float(np.median(np.diff(rec.time))) if len(rec.time) > 1 else 1.0
    width = max(1, round(ZMP_SMOOTHING / dt))
    kernel = np.ones(width) / width
    velocity = np.gradient(centre, rec.time, axis=0)
    accel = np.gradient(velocity, rec.time, axis=0)
    accel = np.stack([np.convolve(accel[:, d], kernel, mode="same") for d in range(2)], axis=-1)
    return zmp_of(centre, accel, omega2, shift)


def zmp_distances(rec: Recording, stance: np.ndarray, omega2: float, shift: np.ndarray
                  ) -> np.ndarray:
    """Distance ``(n,)`` [m] of the `measured_zmp` from the line through the two planned
    stance feet's measured centres; NaN where the plan has not exactly two feet down."""
    point = measured_zmp(rec, omega2, shift)
    out = np.full(len(rec.time), np.nan)
    two = stance.sum(axis=1) == 2
    if not two.any():
        return out
    legs = np.argsort(~stance[two], axis=1, kind="stable")[:, :2]
    rows = np.flatnonzero(two)
    first = rec.feet[rows, legs[:, 0], :2]
    second = rec.feet[rows, legs[:, 1], :2]
    out[rows] = line_distance(point[rows], first, second)
    return out
