"""What the driver sends when: lifecycle and safety commands, joint targets, the watchdog."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.driver.gate import MotionGate
from crawler_motion.driver.link import BusLink
from crawler_motion.driver.outbox import Outbox
from crawler_motion.driver.settings import DriverSettings
from crawler_motion.driver.step_bound import StepBound
from crawler_motion.errors import ProtocolError
from crawler_motion.model.joint_state import JointStateError, JointStateRule
from crawler_motion.runtime.log import Severity


@dataclass(frozen=True)
class CommandResult:
    """What `DriverCore.submit` did with a command: ``sent``, or why not."""

    accepted: bool  # valid and allowed to move (sent, or pending a retry)
    reason: str = ""
    sent: bool = False  # every target frame went out within the call


class MotionControl:
    """Drives the `MotionGate` and sends what it allows through the `Outbox` and `BusLink`.

    Callers hold the core's lock around every method. ``settings()`` gives the current
    settings, ``clock()`` the steady time [s], ``say(key, severity, message)`` logs.
    """

    def __init__(self, protocol: MotorProtocol, link: BusLink, gate: MotionGate,
                 outbox: Outbox, settings: Callable[[], DriverSettings],
                 clock: Callable[[], float], say: Callable[[str, Severity, str], None],
                 measured: Callable[[], np.ndarray]) -> None:
        self.protocol, self.link, self.gate, self.outbox = protocol, link, gate, outbox
        self._settings = settings
        self._clock = clock
        self._say = say
        self._rule = JointStateRule(protocol.joint_names, protocol.lower, protocol.upper,
                                    subject="joint command")
        self._target_counter = 0
        self._measured = measured
        self.bound = StepBound(outbox.target_period)
        self.last_refusal = ""
        self.counts = dict.fromkeys(("commands", "refused", "step_refused", "blocked",
                                     "inactive", "watchdog_trips", "estops"), 0)

    # ---- sending ---------------------------------------------------------------------------

    def control(self, command: str) -> bool:
        """Queue a manager command (replacing a queued one) and try to send it."""
        self.outbox.control = command
        return self.flush(self._clock())

    def flush(self, now: float) -> bool:
        """Send what is queued; True when nothing is left queued."""
        return self.outbox.flush(now, self.link.send, self.protocol.encode_control,
                                 self.gate.motion_allowed, self.gate.sent)

    def bus_back(self) -> None:
        """The bus works again: re-assert a latched e-stop, send what is queued."""
        if self.gate.latched and self.outbox.control is None:
            self.outbox.control = "estop"  # the manager may have missed it
        self.flush(self._clock())

    def on_heartbeat(self, manager_state: str, now: float, period: float) -> None:
        """Re-send ``estop`` or ``enable`` when the heartbeat calls for it (``period`` [s])."""
        command = self.gate.on_heartbeat(manager_state, now, period,
                                         idle=self.outbox.control is None)
        if command is not None:
            self.control(command)

    def tick(self, now: float) -> None:
        """Trip the watchdog when due (sending ``on_timeout``), else retry what is queued."""
        s = self._settings()
        last = self.gate.last_command
        if self.gate.watch(now, s.command_timeout, s.on_timeout):
            self.counts["watchdog_trips"] += 1
            self.outbox.targets = []
            self._say("", Severity.ERROR, f"command watchdog: no joint_commands for "
                      f"{now - last:.3f} s (> {s.command_timeout:g} s); sent "
                      f"{s.on_timeout}, call ~/enable to resume")
            self.control(s.on_timeout)
        elif not self.outbox.empty:
            self.flush(now)

    # ---- lifecycle and safety commands -----------------------------------------------------

    def activate(self) -> tuple[bool, str]:
        """Enable the motors and start forwarding commands; (ok, why not / what happened)."""
        if not self.link.is_open:
            return False, "the bus is not open (configure first)"
        if self.gate.latched:
            return False, (f"ESTOP is latched ({self.gate.estop_reason}); call ~/reset "
                           f"before activating")
        return self._enable()

    def deactivate(self) -> str:
        """Stop forwarding and send ``on_deactivate`` (only ``disable`` if not enabled)."""
        was_active, latched = self.gate.active, self.gate.latched
        command = self.gate.deactivate(self._settings().on_deactivate)
        self.outbox.targets = []
        if not (self.link.is_open and was_active) or latched:
            return "nothing sent"
        sent = self.control(command)
        return f"{command} {'sent' if sent else 'queued (bus down)'}"

    def enable(self) -> tuple[bool, str]:
        """Re-enable after a watchdog trip, a reset or an ``on_timeout: disable``."""
        if not self.link.is_open:
            return False, "not configured"
        if not self.gate.active:
            return False, "not active: activate the driver"
        if self.gate.latched:
            return False, f"ESTOP is latched ({self.gate.estop_reason}); call ~/reset first"
        return self._enable()

    def _enable(self) -> tuple[bool, str]:
        self.outbox.targets = []
        self.bound.forget()
        sent = self.control(self.gate.enable())
        return True, "enable sent" if sent else "enable queued (bus down); retrying"

    def estop(self, reason: str) -> bool:
        """Latch ESTOP and send the e-stop frame; True when the frame went out now."""
        self.counts["estops"] += 1
        if self.gate.estop(reason):
            self._say("", Severity.ERROR, f"ESTOP latched: {reason}")
        self.outbox.targets = []
        return self.link.is_open and self.control("estop")

    def reset(self) -> tuple[bool, str]:
        """Clear the ESTOP latch and send ``reset``; the motors then need `enable`."""
        self.gate.reset()
        self.outbox.targets = []
        if not self.link.is_open:
            return True, "latch cleared (no bus open)"
        sent = self.control("reset")
        return True, ("reset sent" if sent else "reset queued (bus down)") + (
            "; motors disabled: call ~/enable")

    def submit(self, names: Sequence[str], positions: Sequence[float],
               velocities: Sequence[float], efforts: Sequence[float]) -> CommandResult:
        """Validate, encode and send one joint command (names and positions [rad])."""
        if not self.gate.active:
            self.counts["inactive"] += 1
            return CommandResult(False, "inactive: commands are dropped")
        try:
            q = self._rule.validate(names, positions, velocities, efforts)
            frames = self.protocol.encode_targets(q, self._target_counter + 1)
        except (JointStateError, ProtocolError) as exc:
            self.counts["refused"] += 1
            self.last_refusal = str(exc)
            return CommandResult(False, str(exc))
        if not self.gate.motion_allowed:
            self.counts["blocked"] += 1
            return CommandResult(False, self.gate.blocked_reason())
        now = self._clock()
        s = self._settings()
        too_far = self.bound.check(q, self._measured(), now, s.step_speed_limit, s.step_margin,
                                   s.command_timeout)
        if too_far:
            self.counts["step_refused"] += 1
            self.last_refusal = too_far
            self._say("step", Severity.WARNING, f"joint command refused: {too_far}")
            return CommandResult(False, too_far)
        self.bound.sent(q, now)
        self._target_counter += 1
        self.counts["commands"] += 1
        self.gate.accept(now)
        self.outbox.put_targets(frames, now)
        done = self.flush(now)
        return CommandResult(True, "sent" if done else "queued: bus busy or down",
                             sent=done and not self.outbox.targets)
