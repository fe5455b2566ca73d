"""From a heading to a body twist (spec §5): crabbing, or turning with the radius law.

- ``crab``: walk along the heading without turning: ``(v cos β, v sin β, 0)`` with β the
  heading in base_link. The crawler's root joints allow any direction of travel.
- ``turn``: walk forward and turn towards the heading on the study's radius law
  ``r_B = S / (2 sin(r_w π/4))`` (eq. 13), S the distance from the centre of mass to the
  velocity point, with the steering parameter ``r_w = 4 β / π`` limited to ±2 (the tightest
  radius S/2), so that ``r_B`` is the pure-pursuit radius towards the point S ahead along the
  heading. The yaw rate is the consistent ``ω = v / r_B`` (0 when walking straight), not the
  printed eq. 16 (``v cos(r_w π/4) / S``, which is non-zero when walking straight). When
  ``|ω|`` would exceed ``max_yaw_rate`` both v and ω are scaled down together, so the path
  keeps the radius r_B.
"""

from __future__ import annotations

import math
from enum import Enum


class Steering(Enum):
    """How a heading is followed."""

    CRAB = "crab"
    TURN = "turn"


#: Largest steering parameter |r_w| (sin(r_w π/4) = 1: radius S/2).
MAX_STEERING = 2.0


def turn_radius(steering: float, lever: float) -> float:
    """The study's eq. 13 [m]: ``S / (2 sin(r_w π/4))``; +inf for ``r_w`` = 0."""
    s = math.sin(steering * math.pi / 4)
    return math.inf if s == 0.0 else lever / (2.0 * s)


def twist(mode: Steering, heading: float, speed: float, lever: float, max_yaw_rate: float
          ) -> tuple[float, float, float]:
    """``(vx, vy, wz)`` [m/s, rad/s] following ``heading`` (base_link [rad]) at ``speed``."""
    beta = math.atan2(math.sin(heading), math.cos(heading))
    if mode is Steering.CRAB:
        return speed * math.cos(beta), speed * math.sin(beta), 0.0
    r_w = max(-MAX_STEERING, min(MAX_STEERING, 4.0 * beta / math.pi))
    radius = turn_radius(r_w, lever)
    v = speed
    omega = 0.0 if math.isinf(radius) else v / radius
    if abs(omega) > max_yaw_rate:
        scale = max_yaw_rate / abs(omega)
        v, omega = v * scale, omega * scale
    return v, 0.0, omega
