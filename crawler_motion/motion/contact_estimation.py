"""Touch-down and foot contact estimation from joint efforts and positions (pure numpy).

Each leg's drive holds the ground's force on its foot: quasi-statically ``tau = -J(q)^T F``
(``J = d foot / d q`` of `kinematics.foot_jacobians`, base_link; ``tau`` the drive torques
[N m], ``F`` the force of the ground on the foot [N]), so ``F = -J^-T tau``. The normal force
is ``F_z``, the component along base_link +z. What else the drives do is removed first:

- accelerating their own rotors: ``drive_inertia * q_dd`` per joint (the reflected rotor
  inertia [kg m²] at the output; the leg links' own inertia is ~40 times smaller and neglected);
  ``q_dd`` is the mean acceleration over the feedback period the efforts average, from
  centred differences of four position samples, so an estimate describes the sample *before*
  the newest one (one feedback period, 10 ms, late); sample times are taken as whole
  multiples of the feedback ``period`` (the manager samples on its clock; the jitter of
  reception stamps would otherwise enter the acceleration twice differentiated);
- carrying the legs' weight in water: not modelled; it is ~0.1 N at the foot for the shipped
  leg (about 11 g in water), below the threshold, which is set above it (docs/contact.md).

A foot is in contact when its contact force reaches ``threshold`` and stays in contact until it
drops below ``threshold - hysteresis`` [N]. The contact force is the normal force, or the
whole force over `SIDE_CONTACT_FACTOR` when that is larger: a foot pressed against a step face
or a rock's flank feels the ground sideways (the sideways remainders of the swing, about 1 N,
stay below it). Contact is *unknown* (`FootContact.UNKNOWN`, force
NaN) while efforts are missing (an empty or partial effort vector, NaN), while fewer than four
position samples follow each other without a gap, and where a leg's Jacobian is singular;
nothing is ever filled in.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from enum import Enum

import numpy as np

from crawler_motion.model.config import RobotConfig
from crawler_motion.model.kinematics import foot_jacobians
from crawler_motion.model.yaml_values import number_in

#: Samples more feedback periods apart than this start the history anew (a lost stream).
MAX_GAP_PERIODS = 5
#: |det J| [m³] below which a leg's Jacobian counts as singular (no force through it).
SINGULAR_DET = 1e-9
#: Position samples the mean acceleration of one feedback period needs.
HISTORY = 4
#: A force of any direction this many times the threshold is contact, too (see the module).
SIDE_CONTACT_FACTOR = 3.0


class FootContact(str, Enum):
    """Whether a foot touches the ground (the value is the word used in JSON)."""

    YES = "yes"
    NO = "no"
    UNKNOWN = "unknown"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class ContactSettings:
    """Touch-down ``threshold`` and lift-off ``hysteresis`` of the contact force [N] (lift-off
    below ``threshold - hysteresis``), the drives' reflected rotor inertia [kg m²] and the
    manager's feedback ``period`` [s]."""

    threshold: float = 0.75
    hysteresis: float = 0.5
    drive_inertia: float = 0.005
    period: float = 0.01

    def __post_init__(self) -> None:
        _check("threshold", self.threshold, 0.0, 1e4, "N", above=True)
        _check("hysteresis", self.hysteresis, 0.0, self.threshold, "N (the threshold)")
        _check("drive_inertia", self.drive_inertia, 0.0, 10.0, "kg m²")
        _check("period", self.period, 1e-4, 1.0, "s")


def _check(name: str, value: object, lo: float, hi: float, unit: str, *,
           above: bool = False) -> None:
    """`ConfigError` unless ``value`` is a finite number in [lo, hi] ((lo, hi] if ``above``)."""
    number_in(value, f"contact {name}", lo, hi, unit, above=above)


@dataclass(frozen=True)
class ContactEstimate:
    """Contact of every foot at ``stamp`` [s]: ``states`` (one `FootContact` per leg),
    ``normal_forces`` ``(n_legs,)`` [N] and ``forces`` ``(n_legs, 3)`` [N] of the ground on the
    feet in base_link (NaN where unknown); ``reason`` says why any is unknown ("" if none)."""

    stamp: float
    states: tuple[FootContact, ...]
    normal_forces: np.ndarray
    forces: np.ndarray
    reason: str = ""


def contact_state(previous: FootContact, force: float, settings: ContactSettings
                  ) -> FootContact:
    """The hysteresis: YES from ``force >= threshold``, back to NO below ``threshold -
    hysteresis`` [N]; UNKNOWN for a non-finite force (the next known one starts afresh)."""
    if not math.isfinite(force):
        return FootContact.UNKNOWN
    if previous is FootContact.YES:
        return FootContact.YES if force >= settings.threshold - settings.hysteresis \
            else FootContact.NO
    return FootContact.YES if force >= settings.threshold else FootContact.NO


def foot_forces(robot: RobotConfig, angles: np.ndarray, torques: np.ndarray) -> np.ndarray:
    """Force of the ground on each foot ``(..., n_legs, 3)`` [N] in base_link, ``-J^-T tau``,
    from joint angles [rad] and drive torques [N m] ``(..., n_legs, 3)``; NaN for a leg whose
    Jacobian is singular (or whose torques are NaN)."""
    jac = foot_jacobians(robot, angles)
    tau = np.asarray(torques, dtype=float)
    singular = np.abs(np.linalg.det(jac)) < SINGULAR_DET
    jac = np.where(singular[..., None, None], np.eye(3), jac)
    force = -np.linalg.solve(np.swapaxes(jac, -1, -2), tau[..., None])[..., 0]
    return np.where(singular[..., None], np.nan, force)


def mean_acceleration(times: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Mean joint acceleration [rad/s²] over ``(times[1], times[2]]`` from four samples
    ``times`` ``(4,)`` [s] and ``q`` ``(4, ...)`` [rad]: the difference of the centred
    velocities at ``times[2]`` and ``times[1]`` over the interval."""
    t = np.asarray(times, dtype=float)
    v2 = (q[3] - q[1]) / (t[3] - t[1])
    v1 = (q[2] - q[0]) / (t[2] - t[0])
    return (v2 - v1) / (t[2] - t[1])


class ContactEstimator:
    """Per-foot contact of a stream of (stamp, joint angles, efforts) samples; see the module
    docstring. `update` returns the estimate of the sample before the newest one."""

    def __init__(self, robot: RobotConfig, settings: ContactSettings | None = None) -> None:
        self.robot = robot
        self.settings = settings or ContactSettings()
        self.reset()

    def reset(self) -> None:
        """Forget the samples and the contact states."""
        # (feedback periods since the first, angles, torques or None, stamp [s])
        self._samples: deque[tuple[int, np.ndarray, np.ndarray | None, float]] = deque(
            maxlen=HISTORY)
        self._states = [FootContact.UNKNOWN] * self.robot.n_legs

    def configure(self, settings: ContactSettings) -> None:
        """New thresholds and inertia (the contact states stay)."""
        self.settings = settings

    @property
    def angles(self) -> np.ndarray | None:
        """The newest sample's joint angles ``(n_legs, 3)`` [rad] (a copy), None before one."""
        return self._samples[-1][1].copy() if self._samples else None

    def update(self, stamp: float, angles: np.ndarray, efforts: np.ndarray | None
               ) -> ContactEstimate:
        """Take one sample stamped ``stamp`` [s]: ``angles`` ``(n_legs, 3)`` or flat [rad],
        ``efforts`` the joint torques in the same order [N m] (None or empty: not reported).
        A stamp less than half a period after the previous one (or before it), or more than
        `MAX_GAP_PERIODS` after it, starts the history anew."""
        n = self.robot.n_legs
        q = np.asarray(angles, dtype=float).reshape(n, 3)
        tau = None if efforts is None or np.size(efforts) == 0 else np.asarray(
            efforts, dtype=float).reshape(n, 3)
        ticks = 0
        if self._samples:
            ticks = round((stamp - self._samples[-1][3]) / self.settings.period)
            if not 0 < ticks <= MAX_GAP_PERIODS:
                self._samples.clear()
                ticks = 0
        tick = self._samples[-1][0] + ticks if self._samples else 0
        self._samples.append((tick, q, tau, float(stamp)))
        if len(self._samples) < HISTORY:
            return self._unknown(stamp, "fewer than 4 joint-state samples without a gap")
        times = self.settings.period * np.array([s[0] for s in self._samples], dtype=float)
        angles4 = np.stack([s[1] for s in self._samples])
        _, q1, tau1, t1 = self._samples[2]
        if tau1 is None:
            return self._unknown(t1, "joint_states carry no effort")
        drive = self.settings.drive_inertia * mean_acceleration(times, angles4)
        forces = foot_forces(self.robot, q1, tau1 - drive)
        normal = forces[:, 2]
        pressing = np.maximum(normal, np.linalg.norm(forces, axis=1) / SIDE_CONTACT_FACTOR)
        self._states = [contact_state(s, float(f), self.settings)
                        for s, f in zip(self._states, pressing, strict=True)]
        unknown = [leg for leg, s in zip(self.robot.legs, self._states, strict=True)
                   if s is FootContact.UNKNOWN]
        reason = f"no force for {unknown} (effort NaN or Jacobian singular)" if unknown else ""
        return ContactEstimate(t1, tuple(self._states), normal, forces, reason)

    def _unknown(self, stamp: float, reason: str) -> ContactEstimate:
        n = self.robot.n_legs
        self._states = [FootContact.UNKNOWN] * n
        return ContactEstimate(float(stamp), tuple(self._states), np.full(n, np.nan),
                               np.full((n, 3), np.nan), reason)
