"""The simulated manager without a bus: its state machine driving axes at a speed limit."""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from typing import Protocol

import numpy as np

from crawler_motion.canbus.frames import AxisFlags
from crawler_motion.sim.manager_state import ManagerState, ManagerStateMachine

log = logging.getLogger(__name__)


class Plant(Protocol):
    """What moves the axes instead of the speed limit: e.g. a physics simulation."""

    #: Why the plant stopped (e.g. the simulation went unstable); None while it runs.
    failure: str | None

    def advance(self, dt: float, targets: np.ndarray) -> np.ndarray:
        """Drive the axes towards ``targets`` (axis order [rad]) for ``dt`` [s]; returns the
        measured axis positions [rad]."""
        ...

    def take_efforts(self) -> np.ndarray:
        """The axes' efforts (axis order [N m]) averaged since the last call."""
        ...


class ManagerModel:
    """Axis positions and targets in axis order [rad] under a `ManagerStateMachine`.

    Every axis moves towards its target at ``speed`` [rad/s] while the manager is enabled and
    the command timeout [s] has not expired; ``time`` is the simulated time [s].

    With a ``plant`` the axes' motion comes from it instead: its servos always track
    ``target`` (a manager that holds, is disabled or stopped keeps them holding where it held
    them) and ``pos`` is what the plant measures; stalls do not apply. When the plant fails, an
    enabled manager holds. `efforts` are the plant's mean drive torques since the last report;
    without a plant the axes carry no load and report 0 N m.
    """

    def __init__(self, positions: np.ndarray, speed: np.ndarray,
                 command_timeout: float, plant: Plant | None = None) -> None:
        self.pos = np.array(positions, dtype=float)
        self.target = self.pos.copy()
        self.speed = speed
        self.command_timeout = command_timeout
        self.machine = ManagerStateMachine(self.pos.size)
        self.time = 0.0
        self._last_target_time = 0.0
        self.plant = plant

    @property
    def state(self) -> ManagerState:
        """The manager state."""
        return self.machine.state

    def hold(self) -> None:
        """Make the axes hold where they are."""
        self.target = self.pos.copy()

    def command(self, command: str) -> None:
        """Apply an MM_Control command (ValueError when unsupported); entering a state holds
        the axes, entering ``enabled`` restarts the command timeout."""
        if self.machine.command(command):
            self.hold()
            if self.machine.state == ManagerState.ENABLED:
                self._last_target_time = self.time

    def apply_targets(self, axes: Mapping[int, float]) -> bool:
        """New targets [rad] by axis index; False (ignored) unless enabled."""
        if self.machine.state != ManagerState.ENABLED:
            return False
        for axis, value in axes.items():
            self.target[axis] = value
        self._last_target_time = self.time
        self.machine.timed_out = False
        return True

    def inject_fault(self, axis: int, kind: str) -> None:
        """Raise a fault condition on an axis (see `ManagerStateMachine.inject_fault`)."""
        if self.machine.inject_fault(axis, kind):
            self.hold()

    def advance(self, dt: float) -> None:
        """Advance the simulated time by ``dt`` [s]: command timeout, then motion."""
        if not (math.isfinite(dt) and dt >= 0):
            raise ValueError(f"dt must be a finite time >= 0 s, got {dt!r}")
        self.time += dt
        if self.machine.check_timeout(self.time - self._last_target_time,
                                      self.command_timeout):
            self.hold()
            log.debug("command timeout at t=%.3f s: holding", self.time)
        if self.plant is not None:
            self._advance_plant(dt)
        elif self.machine.following:
            step = np.clip(self.target - self.pos, -self.speed * dt, self.speed * dt)
            step[list(self.machine.stalled)] = 0.0
            self.pos += step

    def _advance_plant(self, dt: float) -> None:
        self.pos = np.array(self.plant.advance(dt, self.target.copy()), dtype=float)
        if self.plant.failure is not None and self.machine.state == ManagerState.ENABLED:
            self.command(ManagerState.HOLD.value)
            log.error("plant failed at t=%.3f s: holding (%s)", self.time, self.plant.failure)

    def efforts(self) -> np.ndarray:
        """The efforts to report, axis order [N m]: the plant's mean since the last report,
        else zero (massless axes moved at a speed limit)."""
        if self.plant is None:
            return np.zeros(self.pos.size)
        return np.array(self.plant.take_efforts(), dtype=float)

    def flags(self) -> list[AxisFlags]:
        """The status bits of every axis, in axis order."""
        return self.machine.flags()
