"""The medium around the robot as the body planner sees it: section ``medium`` of robot.yaml.

On its two stance feet the body is a linear inverted pendulum (`crawler_motion.motion.zmp`).
In water it weighs only ``net_weight`` of its dry weight, the water it drags along adds
``added_mass`` of its mass to its inertia without adding weight, and the buoyancy acts at the
centre of buoyancy, ``buoyancy_offset`` from the centre of mass. On land: ``net_weight`` 1,
``added_mass`` 0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from crawler_motion.errors import ConfigError
from crawler_motion.model.yaml_values import number, number_in

#: Standard gravity [m/s²].
GRAVITY = 9.80665
#: Largest added-mass factor accepted (a body that drags ten times its mass is not a crawler).
MAX_ADDED_MASS = 10.0
#: Largest buoyancy offset accepted per axis [m].
MAX_BUOYANCY_OFFSET = 0.1


@dataclass(frozen=True)
class MediumConfig:
    """Net weight (share of the dry weight, in (0, 1]), added-mass factor (>= 0, share of the
    body's mass) and the centre of buoyancy relative to the centre of mass ``(3,)`` [m,
    base_link axes]."""

    net_weight: float = 0.3
    added_mass: float = 0.3
    buoyancy_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def omega2(self, height: float) -> float:
        """Squared natural frequency ``g net / ((1 + added) h)`` [1/s²] of the body as an
        inverted pendulum of height ``height`` [m] (the centre of mass above the ground)."""
        if not (math.isfinite(height) and height > 0.0):
            raise ConfigError(f"the pendulum height must be a finite length > 0 m, got {height}")
        return GRAVITY * self.net_weight / ((1.0 + self.added_mass) * height)

    @property
    def zmp_shift(self) -> np.ndarray:
        """Constant horizontal shift ``(2,)`` [m] of the zero-moment point from the centre of
        mass of a level body at rest: the buoyancy (``1 - net`` of the weight) pulls up at the
        centre of buoyancy, so the net load moves by ``-(1 - net) / net`` times its offset."""
        return -(1.0 - self.net_weight) / self.net_weight * self.buoyancy_offset[:2]

    def on_land(self) -> MediumConfig:
        """The same robot in air: full weight, no added mass, no buoyancy."""
        return MediumConfig(1.0, 0.0, np.zeros(3))


def parse_medium(data: Mapping[str, Any] | None, where: str = "medium") -> MediumConfig:
    """Validate the ``medium`` section (missing: the defaults of `MediumConfig`): each value is
    refused with its key, the value and the allowed range."""
    if data is None:
        return MediumConfig()
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where} must be a mapping, got {data!r}")
    unknown = sorted(set(data) - {"net_weight", "added_mass", "buoyancy_offset"})
    if unknown:
        raise ConfigError(f"{where}: unknown keys {unknown}; allowed: net_weight, added_mass, "
                          f"buoyancy_offset")
    base = MediumConfig()
    net = number_in(data.get("net_weight", base.net_weight), f"{where}.net_weight", 0.0, 1.0,
                    "(share of the dry weight)", above=True)
    added = number_in(data.get("added_mass", base.added_mass), f"{where}.added_mass", 0.0,
                      MAX_ADDED_MASS, "(share of the body's mass)")
    offset = data.get("buoyancy_offset", [0.0, 0.0, 0.0])
    if not isinstance(offset, list) or len(offset) != 3:
        raise ConfigError(f"{where}.buoyancy_offset must be [x, y, z] in m, got {offset!r}")
    values = [number(v, f"{where}.buoyancy_offset") for v in offset]
    for v in values:
        if abs(v) > MAX_BUOYANCY_OFFSET:
            raise ConfigError(f"{where}.buoyancy_offset must be within "
                              f"[-{MAX_BUOYANCY_OFFSET:g}, {MAX_BUOYANCY_OFFSET:g}] m per axis, "
                              f"got {offset!r}")
    return MediumConfig(net, added, np.array(values))
