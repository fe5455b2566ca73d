"""The driver's diagnostic entries: the manager and driver state, the bus, one per axis."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from crawler_motion.driver.bus_watch import BusWatch
from crawler_motion.driver.feedback import Feedback
from crawler_motion.driver.gate import GateState, MotionGate
from crawler_motion.driver.link import BusLink
from crawler_motion.driver.outbox import Outbox
from crawler_motion.driver.settings import DriverSettings

#: The longest the CAN receiver may go without taking the bus's frames before the driver
#: reports itself stalled (ERROR) [s].
RECEIVE_STALL_LIMIT = 1.0
#: Axis flags that are faults, in the order they are reported.
FAULT_BITS = ("over_current", "over_temp", "encoder_fault")
#: Axis flags reported as values, in order.
FLAG_VALUES = ("enabled", "tracking", *FAULT_BITS, "stalled", "command_timeout")


class Level(IntEnum):
    """Diagnostic levels (the values of diagnostic_msgs/DiagnosticStatus)."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass(frozen=True)
class StatusEntry:
    """One diagnostic status: a name, a `Level`, a message and (key, value) texts."""

    name: str
    level: Level
    message: str
    values: tuple[tuple[str, str], ...]


def age(now: float, then: float | None) -> str:
    """Seconds since ``then`` as text [s], ``never`` for None."""
    return "never" if then is None else f"{now - then:.3f}"


def _summary(errors: list[str], warnings: list[str], ok: str) -> tuple[Level, str]:
    level = Level.ERROR if errors else Level.WARN if warnings else Level.OK
    return level, "; ".join(errors + warnings) or ok


def unconfigured_entry(label: str, configure_error: str, latched: str,
                       dropped: int) -> StatusEntry:
    """The one diagnostic entry of a driver without a core (lifecycle state ``label``)."""
    level, message = Level.WARN, f"{label}: not configured"
    if configure_error:
        level, message = Level.ERROR, f"{message}; {configure_error}"
    if latched:
        level, message = Level.ERROR, f"{message}; ESTOP latched ({latched})"
    return StatusEntry("motor manager", level, message,
                       (("estop_latched", str(bool(latched))),
                        ("dropped_unconfigured", str(dropped))))


class DriverDiagnostics:
    """Builds the status entries from the driver's parts (read with the core's lock held)."""

    def __init__(self, link: BusLink, gate: MotionGate, feedback: Feedback, outbox: Outbox,
                 heartbeat_period: float, watch: BusWatch) -> None:
        self.link, self.gate, self.feedback, self.outbox = link, gate, feedback, outbox
        self.watch = watch
        self.heartbeat_period = heartbeat_period  # [s]
        self._joint_of_axis = {m.axis: m.joint for m in feedback.protocol.axis_map}

    def entries(self, now: float, settings: DriverSettings, counts: dict[str, int],
                last_refusal: str) -> list[StatusEntry]:
        """All entries at steady time ``now`` [s]."""
        return [self.manager(now, settings, counts, last_refusal), self.bus(now, settings,
                                                                           counts),
                *self.axes(now, settings)]

    def heard_until(self, now: float) -> float:
        """The steady time [s] up to which the receiver has taken the bus's frames: ``now``
        unless it has not run since (what was sent meanwhile is queued, not missing)."""
        listened = self.feedback.listened
        return now if listened is None else min(now, listened)

    def _link_problems(self, now: float, hb_timeout: float, settings: DriverSettings,
                       errors: list[str], warnings: list[str]) -> None:
        link, fb = self.link, self.feedback
        if not link.is_open:
            warnings.append("not configured")
            return
        if not link.ok:
            errors.append(f"CAN bus down for {now - (link.down_since or now):.3f} s")
        state = fb.heartbeat.state if fb.heartbeat else "unknown"
        # the manager is silent only for as long as the driver listened: a stall of this
        # process (DDS discovery can hold the GIL ~0.3 s, runtime/dds.py) leaves the
        # heartbeats queued on the bus, not missing
        listened = self.heard_until(now)
        if now - listened > max(hb_timeout, RECEIVE_STALL_LIMIT):
            errors.append(f"CAN receiver stalled: no frame taken off the bus for "
                          f"{now - listened:.3f} s")
        if fb.heartbeat_time is None:
            silent = now - (link.open_time or now)
            if silent > max(hb_timeout, settings.heartbeat_startup_grace):
                errors.append(f"no heartbeat from the motor manager for {silent:.3f} s")
            else:
                warnings.append("waiting for the first heartbeat")
        elif listened - fb.heartbeat_time > hb_timeout:
            errors.append(f"heartbeat missing for {listened - fb.heartbeat_time:.3f} s "
                          f"(> {settings.heartbeat_timeout_periods} periods of "
                          f"{self.heartbeat_period:g} s)")
        elif state in ("estop", "fault"):
            errors.append(f"motor manager in state {state}")
        elif (self.gate.enabled and not self.gate.tripped and state == "disabled"
              and fb.heartbeat_time - self.gate.last_enable_tx > self.heartbeat_period):
            errors.append("motor manager is disabled although the driver enabled it; "
                          "call ~/enable")
        if fb.heartbeat_time is not None and listened - fb.heartbeat_time <= hb_timeout:
            self._contradictions(listened, hb_timeout, state, errors)

    def _contradictions(self, heard: float, hb_timeout: float, state: str,
                        errors: list[str]) -> None:
        """A fresh heartbeat that contradicts what the driver commanded or measured."""
        gate, fb = self.gate, self.feedback
        if state == "hold" and gate.state is GateState.ENABLED and gate.enable_confirmed:
            errors.append("motor manager in hold, which the driver did not command (a "
                          "spoofed frame or another controller): call ~/enable")
        elif state == "enabled" and gate.state not in (GateState.ENABLED, GateState.HOLDING):
            errors.append(f"motor manager enabled, which the driver did not command (driver "
                          f"{gate.state.value})")
        since = fb.position_time if fb.position_time is not None else self.link.open_time
        if since is not None and heard - since > hb_timeout:
            errors.append(f"heartbeat without positions for {heard - since:.3f} s: the manager "
                          f"is frozen or the heartbeat forged")

    def _gate_problems(self, settings: DriverSettings, errors: list[str],
                       warnings: list[str]) -> None:
        flags = sorted(self.feedback.flags.items())
        faults = [self._joint_of_axis[a] for a, f in flags if f.fault]
        if faults:
            errors.append(f"fault bits on {', '.join(faults)}")
        stalled = [self._joint_of_axis[a] for a, f in flags if f.stalled and not f.fault]
        if stalled:
            errors.append(f"stalled (not following the target): {', '.join(stalled)}")
        gate = self.gate
        if gate.latched:
            errors.append(f"ESTOP latched ({gate.estop_reason}): ~/reset then ~/enable")
        if gate.tripped:
            errors.append(f"command watchdog tripped ({settings.on_timeout} sent): "
                          f"call ~/enable")
        if self.link.is_open and not gate.active:
            warnings.append("inactive: joint_commands are dropped")
        elif gate.active and not gate.enabled and not gate.latched:
            errors.append("motors not enabled: call ~/enable")  # motion blocked: gait pauses

    def manager(self, now: float, settings: DriverSettings, counts: dict[str, int],
                last_refusal: str) -> StatusEntry:
        """The motor manager and the driver's own state."""
        errors: list[str] = []
        warnings: list[str] = []
        hb_timeout = settings.heartbeat_timeout_periods * self.heartbeat_period
        self._link_problems(now, hb_timeout, settings, errors, warnings)
        self._gate_problems(settings, errors, warnings)
        alarm = self.watch.active_alarm(now)  # foreign frames, forged counters, racing senders
        if alarm:
            errors.append(alarm)
        level, message = _summary(errors, warnings, "enabled, forwarding joint_commands")
        fb, gate, control = self.feedback, self.gate, self.outbox.last_control
        values = (
            ("manager_state", fb.heartbeat.state if fb.heartbeat else "unknown"),
            ("heartbeat_age", age(now, fb.heartbeat_time)),
            ("heartbeat_timeout", f"{hb_timeout:g}"),
            ("command_age", age(now, gate.last_command)),
            ("command_timeout", f"{settings.command_timeout:g}"),
            ("feedback_age", age(now, fb.position_time)),
            ("effort_age", age(now, fb.effort_time)),
            ("active", str(gate.active)),
            ("enabled", str(gate.enabled)),
            ("estop_latched", str(gate.latched)),
            ("estop_reason", gate.estop_reason or ""),
            ("watchdog_tripped", str(gate.tripped)),
            ("last_control", f"{control[0]} ({now - control[1]:.3f} s ago)" if control
             else "none"),
            ("pending_control", self.outbox.control or "none"),
            ("commands", str(counts["commands"])),
            ("refused", str(counts["refused"])),
            ("blocked", str(counts["blocked"])),
            ("dropped_inactive", str(counts["inactive"])),
            ("step_refused", str(counts["step_refused"])),
            ("foreign_frames", str(counts["foreign_targets"] + counts["foreign_controls"])),
            ("rx_conflicts", str(counts["rx_conflicts"])),
            ("sender_conflicts", str(counts["sender_conflicts"])),
            ("last_alarm", self.watch.last_alarm),
            ("last_refusal", last_refusal),
        )
        return StatusEntry("motor manager", level, message, values)

    def bus(self, now: float, settings: DriverSettings, counts: dict[str, int]) -> StatusEntry:
        """The CAN bus and every counter."""
        link = self.link
        if not link.is_open:
            level, message = Level.WARN, "closed"
        elif not link.ok:
            level, message = Level.ERROR, (f"down for {now - (link.down_since or now):.3f} s, "
                                           f"reopening every {settings.reopen_period:g} s")
        else:
            level, message = Level.OK, "open"
        values = (("bus_open", str(link.ok)),
                  *((name, str(value)) for name, value in counts.items()),
                  ("last_tx_error", link.last_tx_error),
                  ("last_rx_error", self.feedback.last_rx_error))
        return StatusEntry("CAN bus", level, message, values)

    def axes(self, now: float, settings: DriverSettings) -> list[StatusEntry]:
        """One entry per axis, in axis-map order."""
        stale_after = settings.heartbeat_timeout_periods * self.heartbeat_period
        fb, heard = self.feedback, self.heard_until(now)
        entries = []
        for i, m in enumerate(fb.protocol.axis_map):
            flags = fb.flags.get(m.axis)
            seen = fb.flags_time.get(m.axis)
            position = fb.positions[i]
            values: list[tuple[str, str]] = [
                ("joint", m.joint), ("axis", str(m.axis)),
                ("position", "unknown" if math.isnan(position) else f"{position:.4f}"),
                ("status_age", age(now, seen))]
            if flags is None:
                level, message = Level.STALE, "no status frame yet"
            else:
                values.extend((attr, str(getattr(flags, attr))) for attr in FLAG_VALUES)
                bits = [a for a in FAULT_BITS if getattr(flags, a)]
                if bits:
                    level, message = Level.ERROR, f"fault: {', '.join(bits)}"
                elif seen is not None and heard - seen > stale_after:
                    level, message = Level.STALE, f"no status for {heard - seen:.3f} s"
                elif flags.stalled:
                    level, message = Level.ERROR, "stalled: not following the target"
                elif flags.command_timeout:
                    level, message = Level.WARN, "manager command timeout: holding"
                else:
                    level, message = Level.OK, "tracking" if flags.tracking else (
                        "powered" if flags.enabled else "unpowered")
            entries.append(StatusEntry(f"axis {m.axis:02d} {m.joint}", level, message,
                                       tuple(values)))
        return entries
