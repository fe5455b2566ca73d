"""The simulated motor manager's state machine: states, commands, faults and status bits."""

from __future__ import annotations

import logging
from enum import Enum

import numpy as np

from crawler_motion.canbus.frames import AxisFlags

log = logging.getLogger(__name__)


class ManagerState(str, Enum):
    """Manager state, as the heartbeat reports it (the value is the DBC's State name)."""

    DISABLED = "disabled"  # axes unpowered, targets ignored (the start state)
    ENABLED = "enabled"  # axes powered, following the targets
    HOLD = "hold"  # axes powered, holding where they are
    ESTOP = "estop"  # stopped and unpowered, latched until ``reset``
    FAULT = "fault"  # stopped by a fault condition, latched until ``reset``

    def __str__(self) -> str:
        return self.value


class FaultKind(str, Enum):
    """A fault condition of one axis (the value is the `AxisFlags` attribute it sets)."""

    OVER_CURRENT = "over_current"
    OVER_TEMP = "over_temp"
    ENCODER_FAULT = "encoder_fault"

    def __str__(self) -> str:
        return self.value


#: States only ``reset`` leaves.
LATCHED = frozenset({ManagerState.ESTOP, ManagerState.FAULT})
#: States with the axes powered.
POWERED = frozenset({ManagerState.ENABLED, ManagerState.HOLD})
#: Commands that enter a state directly (outside the latched states).
_ENTERS = {"enable": ManagerState.ENABLED, "disable": ManagerState.DISABLED,
           "hold": ManagerState.HOLD}


class ManagerStateMachine:
    """State, fault conditions, latched fault bits, stalls and command timeout of ``n_axes``.

    Positions are not kept here: a method returning True asks the caller to make the axes hold
    where they are (the state was entered anew, a fault stopped them or the timeout expired).
    """

    def __init__(self, n_axes: int) -> None:
        self.n_axes = n_axes
        self.state = ManagerState.DISABLED
        self.faults: list[set[FaultKind]] = [set() for _ in range(n_axes)]  # active conditions
        self.latched: list[set[FaultKind]] = [set() for _ in range(n_axes)]  # reported to reset
        self.stalled: set[int] = set()
        self.timed_out = False

    @property
    def following(self) -> bool:
        """True while the axes track their targets (enabled, no command timeout)."""
        return self.state == ManagerState.ENABLED and not self.timed_out

    def _enter(self, state: ManagerState) -> bool:
        self.state = state
        self.timed_out = False
        return True

    def command(self, command: str) -> bool:
        """Apply an MM_Control command; True when a state was entered (hold the axes).

        ``estop`` latches; ``reset`` clears latched bits whose condition is gone and leaves
        ``estop``/``fault`` (for ``fault`` again while a condition stays); other commands are
        ignored while latched. ValueError for a command this manager does not implement.
        """
        if command == "estop":
            return self._enter(ManagerState.ESTOP)
        if command == "reset":
            for active, latched in zip(self.faults, self.latched, strict=True):
                latched.intersection_update(active)
            if self.state in LATCHED:
                return self._enter(ManagerState.FAULT if any(self.faults)
                                   else ManagerState.DISABLED)
            return False
        if self.state in LATCHED:
            log.debug("command %s ignored in latched state %s", command, self.state)
            return False
        if command not in _ENTERS:  # a command the DBC knows but this manager does not
            raise ValueError(f"unsupported command {command!r}")
        return self._enter(_ENTERS[command])

    def axis(self, axis: int) -> int:
        """``axis`` as an index 0..n_axes-1; ValueError otherwise."""
        if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or not (
                0 <= axis < self.n_axes):
            raise ValueError(f"axis must be an integer 0..{self.n_axes - 1}, got {axis!r}")
        return int(axis)

    def inject_fault(self, axis: int, kind: str) -> bool:
        """Raise a fault condition on an axis: ``fault`` (unless in ``estop``); True (hold)."""
        try:
            fault = FaultKind(kind)
        except ValueError:
            raise ValueError(f"fault kind must be one of {[k.value for k in FaultKind]}, "
                             f"got {kind!r}") from None
        a = self.axis(axis)
        self.faults[a].add(fault)
        self.latched[a].add(fault)
        self.timed_out = False
        if self.state != ManagerState.ESTOP:
            self.state = ManagerState.FAULT
        return True

    def stall(self, axis: int, stalled: bool) -> None:
        """Block (or free) an axis."""
        a = self.axis(axis)
        if stalled:
            self.stalled.add(a)
        else:
            self.stalled.discard(a)

    def clear(self) -> None:
        """Remove every fault condition and stall; latched bits and states stay until reset."""
        for active in self.faults:
            active.clear()
        self.stalled.clear()

    def check_timeout(self, since_target: float, timeout: float) -> bool:
        """Start the command timeout when enabled and no target came for longer than
        ``timeout`` [s] (``since_target`` [s]); True when it starts now (hold)."""
        if self.following and since_target > timeout:
            self.timed_out = True
            return True
        return False

    def flags(self) -> list[AxisFlags]:
        """The status bits of every axis, in axis order."""
        powered = self.state in POWERED
        following = self.following
        flags = []
        for axis in range(self.n_axes):
            latched = self.latched[axis]
            stalled = axis in self.stalled
            flags.append(AxisFlags(
                enabled=powered, tracking=following and not stalled,
                over_current=FaultKind.OVER_CURRENT in latched,
                over_temp=FaultKind.OVER_TEMP in latched,
                encoder_fault=FaultKind.ENCODER_FAULT in latched, stalled=stalled,
                command_timeout=self.timed_out))
        return flags
