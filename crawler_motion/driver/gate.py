"""The motion gate: lifecycle, enable, e-stop latch and command watchdog as one state machine."""

from __future__ import annotations

import math
from enum import Enum

from crawler_motion.driver.settings import OnDeactivate, OnTimeout

#: Re-sends of an ``enable`` the manager never confirmed (it reports ``disabled`` instead).
MAX_ENABLE_RESENDS = 3


class GateState(str, Enum):
    """Where the gate is; only ``ENABLED`` lets target frames out.

    ``ESTOP`` lies over the others: the latch survives `MotionGate.close` and may be set with
    no bus open; `MotionGate.reset` goes back to the state underneath, motors disabled.
    """

    INACTIVE = "inactive"  # not active (lifecycle): commands are dropped
    DISABLED = "disabled"  # active, motors not enabled
    ENABLED = "enabled"  # active, enabled: commands go out
    HOLDING = "holding"  # watchdog tripped, ``hold`` sent: motors powered, motion blocked
    TRIPPED = "tripped"  # watchdog tripped, ``disable`` sent
    ESTOP = "estop"  # e-stop latched


#: What an e-stop leaves underneath: the motors are no longer enabled.
_ESTOP_CLEARS = {GateState.ENABLED: GateState.DISABLED, GateState.HOLDING: GateState.TRIPPED}


class MotionGate:
    """The gate's state and its transitions; every method returns the manager command to send
    (``enable``, ``hold``, ``disable``, ``estop``, ``reset``) or None. Times are steady [s].

    The watchdog arms with the first command accepted after an ``enable``; an unarmed watchdog
    never trips. An ``enable`` is confirmed by the first heartbeat reporting ``enabled``.
    """

    def __init__(self) -> None:
        self._base = GateState.INACTIVE  # the state under a latched e-stop
        self.estop_reason: str | None = None
        self.last_command: float | None = None  # steady time of the last accepted command
        self._armed = False
        self.last_enable_tx = -math.inf
        self.last_estop_tx = -math.inf
        self._enable_confirmed = False
        self._enable_resends = 0
        self.enable_epoch = 0  # incremented by every `enable` (the planner resumes on it)

    # ---- observation -----------------------------------------------------------------------

    @property
    def state(self) -> GateState:
        """The current state."""
        return GateState.ESTOP if self.estop_reason is not None else self._base

    @property
    def active(self) -> bool:
        """True between `activate` and `deactivate` / `close`."""
        return self._base is not GateState.INACTIVE

    @property
    def enabled(self) -> bool:
        """True while the driver has the motors enabled (an ``enable`` was sent)."""
        return self._base in (GateState.ENABLED, GateState.HOLDING)

    @property
    def tripped(self) -> bool:
        """True from a watchdog trip until `enable`, `deactivate` or `reset`."""
        return self._base in (GateState.HOLDING, GateState.TRIPPED)

    @property
    def enable_confirmed(self) -> bool:
        """True once a heartbeat reported ``enabled`` after the last ``enable`` sent."""
        return self._enable_confirmed

    @property
    def latched(self) -> bool:
        """True from `estop` until `reset`."""
        return self.estop_reason is not None

    @property
    def motion_allowed(self) -> bool:
        """True when a valid command would be sent now."""
        return self.state is GateState.ENABLED

    def blocked_reason(self) -> str:
        """Why a valid command is not sent now."""
        if self.latched:
            return f"ESTOP latched ({self.estop_reason}): ~/reset then ~/enable"
        if self.tripped:
            return "command watchdog tripped: call ~/enable (or deactivate + activate)"
        return "motors not enabled: call ~/enable"

    # ---- transitions -----------------------------------------------------------------------

    def enable(self) -> str:
        """Enable (from `activate` or ``~/enable``): disarms the watchdog; sends ``enable``."""
        self._base = GateState.ENABLED
        self.enable_epoch += 1
        self._enable_resends = 0
        self._armed = False
        self.last_command = None
        return "enable"

    def deactivate(self, on_deactivate: str) -> str:
        """Stop forwarding: ``on_deactivate``, or ``disable`` when not enabled (``hold`` would
        power unpowered axes)."""
        command = on_deactivate
        if command == OnDeactivate.HOLD.value and not self.enabled:
            command = OnDeactivate.DISABLE.value
        self._base = GateState.INACTIVE
        return command

    def close(self) -> None:
        """The bus closed: inactive (a latched e-stop stays latched)."""
        self._base = GateState.INACTIVE

    def estop(self, reason: str) -> bool:
        """Latch the e-stop (the first reason is kept); True when it was not latched yet."""
        first = self.estop_reason is None
        if first:
            self.estop_reason = reason
        self._base = _ESTOP_CLEARS.get(self._base, self._base)
        return first

    def reset(self) -> None:
        """Clear the latch and any trip; the motors need `enable` again."""
        self.estop_reason = None
        if self.active:
            self._base = GateState.DISABLED

    def accept(self, now: float) -> None:
        """A command was accepted and sent at ``now``: arms and feeds the watchdog."""
        self.last_command = now
        self._armed = True

    def watch(self, now: float, timeout: float, on_timeout: str) -> bool:
        """Trip the watchdog when no command came for ``timeout`` [s]; True when it tripped."""
        if not (self.state is GateState.ENABLED and self._armed and self.last_command is not None
                and now - self.last_command > timeout):
            return False
        self._base = (GateState.TRIPPED if on_timeout == OnTimeout.DISABLE.value
                      else GateState.HOLDING)
        return True

    def sent(self, command: str, now: float) -> None:
        """A control command went out at ``now``."""
        if command == "estop":
            self.last_estop_tx = now
        elif command == "enable":
            self.last_enable_tx = now
            self._enable_confirmed = False

    def on_heartbeat(self, manager_state: str, now: float, period: float,
                     idle: bool) -> str | None:
        """The command a heartbeat reporting ``manager_state`` calls for, or None.

        ``idle``: no control command is queued; ``period`` is the heartbeat period [s].
        ``estop`` again when latched and the manager left (or never saw) the e-stop; ``enable``
        again when an unconfirmed ``enable`` met a ``disabled`` manager (it came up after the
        enable, or the frame was lost), at most `MAX_ENABLE_RESENDS` times. A manager that
        confirmed and fell back to ``disabled`` (e.g. rebooted) needs an explicit ``~/enable``.
        """
        if (self.latched and manager_state != "estop" and idle
                and now - self.last_estop_tx > period):
            return "estop"
        if manager_state == "enabled":
            self._enable_confirmed = True
        elif (manager_state == "disabled" and self.state is GateState.ENABLED
              and not self._enable_confirmed and idle and now - self.last_enable_tx > period
              and self._enable_resends < MAX_ENABLE_RESENDS):
            self._enable_resends += 1
            return "enable"
        return None
