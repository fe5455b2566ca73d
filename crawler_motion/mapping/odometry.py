"""Which odometry samples the terrain map may follow (pure): stale, future, absurd and jumping
samples refused; a restarted odometry adopted, with the map cleared.

The map places every scan with the odometry pose at its stamp, so one bad sample must not
steer it. `OdometryGate.check` decides for each sample, in order:

- a pose that is not finite, or farther than ``max_position`` from the origin: refused
  (``BAD_POSE``; an absurd position would overflow the grid's cell index);
- a stamp ahead of the receiver's clock by more than ``future_tolerance``: refused
  (``FUTURE``; one future stamp would otherwise make every later sample look stale);
- a stamp not after the latest accepted one: refused (``ODOM_STALE``);
- a position farther from the latest accepted one than ``max_speed`` allows in the time
  between their stamps (plus ``jump_allowance``): refused (``JUMP``).

A sample refused as stale or as a jump may be the start of a new odometry stream (a restarted
odometry source, a clock step backwards, a relocalisation): once ``reset_samples`` refused
samples in a row agree with each other (increasing stamps, plausible motion between them),
the gate answers ``RESET``: the caller clears what it built on the old stream (the map is
cleared to unknown, never to free) and follows the new one from those samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Protocol

import numpy as np


class OdometryVerdict(Enum):
    """What `OdometryGate.check` decided for one sample."""

    ACCEPT = "accepted"
    BAD_POSE = "odometry pose not finite or beyond max_position"
    FUTURE = "odometry stamped ahead of the receiver's clock by more than future_tolerance"
    ODOM_STALE = "odometry not newer than the latest accepted sample"
    JUMP = "odometry position jumped farther than max_speed allows"
    RESET = "a new odometry stream (restarted source or clock step): map cleared"


@dataclass(frozen=True)
class OdometryLimits:
    """Limits of plausible odometry (SI units)."""

    future_tolerance: float = 0.5  # [s]
    max_position: float = 1e5  # [m]
    max_speed: float = 2.0  # [m/s]
    jump_allowance: float = 0.2  # [m]
    reset_samples: int = 10


class _Stamped(Protocol):
    stamp: float
    rotation: np.ndarray
    position: np.ndarray


class OdometryGate:
    """Accepts, refuses or resets on each odometry sample (see the module docstring)."""

    def __init__(self, limits: OdometryLimits) -> None:
        self.limits = limits
        self.latest: _Stamped | None = None
        #: Refused samples in a row that agree with each other: a possible new stream.
        self.candidate: list[_Stamped] = []
        #: The samples of the new stream the last ``RESET`` adopted, in order.
        self.adopted: list[_Stamped] = []

    def plausible(self, before: _Stamped, after: _Stamped) -> bool:
        """True when ``after`` may follow ``before`` (later stamp, motion within limits)."""
        dt = after.stamp - before.stamp
        if not dt > 0.0:
            return False
        jump = float(np.linalg.norm(after.position[:2] - before.position[:2]))
        return jump <= self.limits.max_speed * dt + self.limits.jump_allowance

    def check(self, pose: _Stamped, now: float | None = None) -> OdometryVerdict:
        """The verdict on ``pose``; ``now`` [s]: the receiver's clock in the stamps' time base
        (None: not checked against a clock). An accepted pose becomes the latest; a ``RESET``
        adopts the new stream (`adopted`, its last sample the latest), which the caller
        keeps in order."""
        lim = self.limits
        if not (np.all(np.isfinite(pose.rotation)) and np.all(np.isfinite(pose.position))
                and math.isfinite(pose.stamp)) or float(
                np.max(np.abs(pose.position))) > lim.max_position:
            return OdometryVerdict.BAD_POSE
        if now is not None and pose.stamp > now + lim.future_tolerance:
            return OdometryVerdict.FUTURE
        if self.latest is None or self.plausible(self.latest, pose):
            self.latest = pose
            self.candidate.clear()
            return OdometryVerdict.ACCEPT
        verdict = (OdometryVerdict.ODOM_STALE if pose.stamp <= self.latest.stamp
                   else OdometryVerdict.JUMP)
        if self.candidate and not self.plausible(self.candidate[-1], pose):
            self.candidate.clear()
        self.candidate.append(pose)
        if len(self.candidate) >= lim.reset_samples:
            self.adopted, self.candidate = self.candidate, []
            self.latest = self.adopted[-1]
            return OdometryVerdict.RESET
        return verdict
