"""The medium around the robot: water (buoyancy, drag, current) or land, as MJCF settings.

MuJoCo's fluid model gives drag and lift only, no buoyancy and no added mass. Buoyancy is added
per body with MuJoCo's ``gravcomp`` body attribute: an upward force ``(1 - f) m g`` at the body's
centre of mass, computed inside the physics step (no per-step Python work), where ``f`` is the
net weight in water as a fraction of the dry weight. The generated robot has uniform-density
solids, so every body's centre of volume coincides with its centre of mass and this is exactly
the buoyancy force ``rho g V`` scaled to the requested net weight. A uniform current is MuJoCo's
``wind`` (the velocity of the medium [m/s]); drag uses the fluid's density and viscosity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from crawler_motion.errors import ConfigError


class Medium(str, Enum):
    """What surrounds the robot."""

    WATER = "water"
    LAND = "land"


#: Density [kg/m³] and dynamic viscosity [Pa s] of sea water at about 10 °C.
WATER_DENSITY = 1000.0
WATER_VISCOSITY = 0.0009


@dataclass(frozen=True)
class WaterSettings:
    """Medium, net weight in water, fluid properties and current (SI units).

    ``net_weight_fraction``: weight in water / dry weight, in (0, 1]; ``current``: uniform
    velocity of the water in the world frame [m/s] (water only).
    """

    medium: Medium = Medium.WATER
    net_weight_fraction: float = 0.3
    density: float = WATER_DENSITY
    viscosity: float = WATER_VISCOSITY
    current: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "medium", Medium(self.medium))
        except ValueError as exc:
            raise ConfigError(f"medium must be one of {[m.value for m in Medium]}, "
                              f"got {self.medium!r}") from exc
        check_range("net_weight_fraction", self.net_weight_fraction, 1e-3, 1.0, "")
        check_range("density", self.density, 1.0, 2000.0, "kg/m³")
        check_range("viscosity", self.viscosity, 0.0, 1.0, "Pa s")
        if len(self.current) != 3:
            raise ConfigError(f"current must be [vx, vy, vz] in m/s, got {self.current!r}")
        for value in self.current:
            check_range("current", value, -5.0, 5.0, "m/s")
        if self.medium is Medium.LAND and any(self.current):
            raise ConfigError(f"a current {list(self.current)} m/s needs medium 'water'")

    @property
    def buoyancy_fraction(self) -> float:
        """Fraction of each body's weight carried by buoyancy (MuJoCo ``gravcomp``)."""
        return 1.0 - self.net_weight_fraction if self.medium is Medium.WATER else 0.0

    def option_attributes(self) -> dict[str, str]:
        """MJCF ``<option>`` attributes of the medium (fluid density, viscosity, wind)."""
        if self.medium is Medium.LAND:
            return {"density": "0", "viscosity": "0"}
        return {"density": repr(float(self.density)), "viscosity": repr(float(self.viscosity)),
                "wind": " ".join(repr(float(v)) for v in self.current)}


def check_range(name: str, value: object, lo: float, hi: float, unit: str) -> None:
    """Raise `ConfigError` unless ``value`` is a finite number in [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            value) or not lo <= value <= hi:
        raise ConfigError(f"{name} = {value!r} {unit} is outside [{lo}, {hi}] {unit}".replace(
            "  ", " "))
