"""Body attitude and height of a walk on rough ground (pure numpy): the body follows the plane of
the feet's footholds, or is levelled from an IMU, changing smoothly over each gait slot.

The walk's feet are planned in a frame on the planned ground (the **plan frame**); the
terrain-adaptive touch-down (`foothold`) lands each foot ``δ`` [m] above or below its planned
ground. The body pose ``(z, roll, pitch)`` (a lift [m] along the plan frame's z and the
fixed-axis roll and pitch [rad] of `rotations.rpy_matrix`, REP-103) moves every foot target
``p`` of the plan frame to ``p' = R^T (p - z ẑ)`` in base_link, as the body pose command does
(`body_pose`), so the stance feet stay where they stand and the body moves.

Modes (`AttitudeMode`):

- ``stance_plane``: the least-squares plane ``δ = z + b x + c y`` through the feet's latest
  footholds (x, y of the plan at the slot's start, ``δ`` held by the touch-down): the body
  rises by ``z`` (the hips keep their height above the plane, so the belly keeps its
  clearance over a step) and turns to ``pitch = -atan(b)``, ``roll = atan(c)``;
- ``imu``: height from the plane as above; roll and pitch level the body: the measured
  attitude (an IMU's orientation) minus the commanded one is the plan frame's tilt, which
  the new command cancels;
- ``off``: no change (the plan as it is).

Each slot plans the pose from where it is to its new target with the rest profile
(``10u³ - 15u⁴ + 6u⁵``, v = a = 0 at both ends: C², like the feet), over the slot's
duration. Targets are bounded by ``max_tilt`` and ``max_lift`` (beyond that the ground is
not a plane the legs can follow).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from crawler_motion.errors import ConfigError
from crawler_motion.model.yaml_values import number_in
from crawler_motion.motion.body_pose import foot_state_at
from crawler_motion.motion.foothold import rest

#: Smallest spread [m²] of the footholds (the determinant of their x-y scatter) that defines a
#: plane; fewer or collinear footholds keep the attitude.
MIN_SPREAD = 1e-6


class AttitudeMode(str, Enum):
    """Where the body's roll, pitch and height come from during a walk."""

    STANCE_PLANE = "stance_plane"
    IMU = "imu"
    OFF = "off"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class AttitudeSettings:
    """The ``mode``, the largest |roll| and |pitch| commanded ``max_tilt`` [rad] and the
    largest |lift| ``max_lift`` [m]."""

    mode: AttitudeMode = AttitudeMode.OFF
    max_tilt: float = 0.15
    max_lift: float = 0.02

    def __post_init__(self) -> None:
        if not isinstance(self.mode, AttitudeMode):
            try:
                object.__setattr__(self, "mode", AttitudeMode(self.mode))
            except ValueError:
                raise ConfigError(f"attitude mode must be one of "
                                  f"{[m.value for m in AttitudeMode]}, got {self.mode!r}"
                                  ) from None
        for name, hi, unit in (("max_tilt", 0.5, "rad"), ("max_lift", 0.05, "m")):
            number_in(getattr(self, name), f"attitude {name}", 0.0, hi, unit)


def stance_plane(xy: np.ndarray, delta: Sequence[float]) -> tuple[float, float, float] | None:
    """``(z, roll, pitch)`` [m, rad] of the body over the least-squares plane through the
    footholds at ``xy`` ``(n, 2)`` [m] raised by ``delta`` [m] (see the module docstring);
    None for fewer than 3 footholds or collinear ones (`MIN_SPREAD`)."""
    pts = np.asarray(xy, dtype=float).reshape(-1, 2)
    d = np.asarray(delta, dtype=float).reshape(-1)
    if len(pts) < 3 or len(d) != len(pts) or not np.all(np.isfinite(d)):
        return None
    centred = pts - pts.mean(axis=0)
    if float(np.linalg.det(centred.T @ centred)) / len(pts) ** 2 < MIN_SPREAD:
        return None
    a = np.column_stack([np.ones(len(pts)), pts])
    z, b, c = np.linalg.lstsq(a, d, rcond=None)[0]
    return float(z), math.atan(float(c)), -math.atan(float(b))


def bounded(target: Sequence[float], settings: AttitudeSettings) -> tuple[float, float, float]:
    """``(z, roll, pitch)`` clipped to ``max_lift`` and ``max_tilt`` (the attitude's limits
    are the planner's, not the command's: nothing is refused)."""
    lim = (settings.max_lift, settings.max_tilt, settings.max_tilt)
    return tuple(max(-m, min(m, float(x))) for x, m in zip(target, lim, strict=True))  # type: ignore[return-value]


class AttitudeProfile:
    """The body pose ``(z, roll, pitch)`` over time [s] on the walk's clock: rest transitions
    from one target to the next (each `plan` starts from where the last one is)."""

    def __init__(self) -> None:
        self.start = (0.0, 0.0, 0.0)
        self.target = (0.0, 0.0, 0.0)
        self.t0 = 0.0
        self.duration = 0.0

    def reset(self, pose: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Hold ``pose``."""
        self.start = self.target = tuple(float(x) for x in pose)  # type: ignore[assignment]
        self.duration = 0.0

    def quiet(self) -> bool:
        """True while the pose is and stays neutral."""
        return self.start == self.target == (0.0, 0.0, 0.0)

    def plan(self, t0: float, duration: float, target: Sequence[float]) -> None:
        """From ``t0`` [s] on, move to ``target`` over ``duration`` [s] (from the pose at
        ``t0``, which a walk's timing makes a rest point: each transition ends with its
        slot)."""
        self.start = self.evaluate(t0)[0]
        self.target = tuple(float(x) for x in target)  # type: ignore[assignment]
        self.t0, self.duration = float(t0), float(duration)

    def evaluate(self, t: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """The pose and its rate [m/s, rad/s] at ``t`` [s]."""
        if self.duration <= 0.0 or t >= self.t0 + self.duration or self.start == self.target:
            return self.target, (0.0, 0.0, 0.0)
        p, dp, _ = rest((t - self.t0) / self.duration)
        pose = tuple(a + (b - a) * p for a, b in zip(self.start, self.target, strict=True))
        rate = tuple((b - a) * dp / self.duration
                     for a, b in zip(self.start, self.target, strict=True))
        return pose, rate  # type: ignore[return-value]


def apply_pose(pos: list[float], vel: list[float], pose: Sequence[float],
               rate: Sequence[float]) -> None:
    """Move the flat foot targets ``pos`` [m] and their rates ``vel`` [m/s] (leg-major, plan
    frame) into base_link of the body at ``pose`` ``(z, roll, pitch)`` moving at ``rate``, in
    place: ``p' = R^T (p - z ẑ)``, ``v' = R^T v`` plus the motion a fixed foot has seen from
    the moving body (`body_pose.foot_state_at`, the planner tick's plain floats)."""
    z, roll, pitch = pose
    dz, droll, dpitch = rate
    moved, seen = foot_state_at(pos, (0.0, 0.0, z, roll, pitch, 0.0),
                                (0.0, 0.0, dz, droll, dpitch, 0.0))
    turned, _ = foot_state_at(vel, (0.0, 0.0, 0.0, roll, pitch, 0.0), (0.0,) * 6)
    pos[:] = moved
    vel[:] = [a + b for a, b in zip(turned, seen, strict=True)]
