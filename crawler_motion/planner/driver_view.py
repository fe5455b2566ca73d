"""What the planner knows of the driver: its gate state and enable epoch from ``driver_status``.

The driver publishes ``driver_status`` (std_msgs/String, one JSON object, see
`crawler_motion.driver.status`). The planner reads two keys: ``state`` (the driver's motion
gate: ``inactive``, ``disabled``, ``enabled``, ``holding``, ``tripped``, ``estop``) and
``enable_epoch`` (incremented on every ``enable`` the driver sends), and ``instance`` (new at
every start of the driver: a restarted driver ends a motion like a deactivation). A state in
`ENDING_STATES` ends a walk or a move (the planner goes to IDLE and needs an explicit
``stand``); a new epoch while the planner moves makes it resume from the measured pose.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from enum import Enum

from crawler_motion.errors import CommandError

#: Driver gate states of an e-stop, a deactivation or a watchdog trip: a motion of the planner
#: ends (IDLE, an explicit stand needed) rather than pauses.
ENDING_STATES = frozenset(("inactive", "holding", "tripped", "estop"))
#: Every gate state the driver reports; ``disabled`` (after a ``~/reset`` of a manager fault)
#: pauses (the driver's diagnostics are ERROR) until ``~/enable`` starts a new epoch.
DRIVER_STATES = ENDING_STATES | {"enabled", "disabled"}


class DriverChange(Enum):
    """What a new driver report means for the planner."""

    NONE = "none"
    ENDED = "ended"  # the driver stopped following: end the motion
    RESTARTED = "restarted"  # another driver process: end the motion
    REENABLED = "reenabled"  # the driver enabled again: resume from the measured pose


@dataclass(frozen=True)
class DriverReport:
    """One ``driver_status``: the gate ``state``, the ``enable_epoch``, a ``reason`` and the
    driver process's ``instance`` (a token new at every start)."""

    state: str
    enable_epoch: int
    reason: str = ""
    instance: str = ""
    command_timeout: float | None = None  # [s] the driver's watchdog


def parse_driver_status(text: str) -> DriverReport:
    """The `DriverReport` of one ``driver_status`` JSON text; `CommandError` if malformed."""
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise CommandError(f"driver_status is not JSON: {exc}") from exc
    if not isinstance(data, dict):
        raise CommandError("driver_status must be a JSON object")
    state, epoch = data.get("state"), data.get("enable_epoch")
    if state not in DRIVER_STATES:
        raise CommandError(f"driver_status state {state!r} is not one of "
                           f"{sorted(DRIVER_STATES)}")
    if not isinstance(epoch, int) or isinstance(epoch, bool) or epoch < 0:
        raise CommandError(f"driver_status enable_epoch must be an integer >= 0, got {epoch!r}")
    reason, instance = data.get("reason", ""), data.get("instance", "")
    timeout = data.get("command_timeout")
    if timeout is not None and not (isinstance(timeout, (int, float))
                                    and not isinstance(timeout, bool) and timeout > 0):
        raise CommandError(f"driver_status command_timeout must be a time > 0 s, got "
                           f"{timeout!r}")
    return DriverReport(state, epoch, reason if isinstance(reason, str) else "",
                        instance if isinstance(instance, str) else "",
                        None if timeout is None else float(timeout))


def rate_problem(rate_hz: float, report: DriverReport | None) -> str:
    """Why a planner ``rate`` [Hz] would trip the driver's command watchdog ("" if it does
    not, or the driver's timeout is not known): its period must stay below half the
    ``command_timeout`` (one late tick must not trip it)."""
    if report is None or report.command_timeout is None:
        return ""
    if 2.0 / rate_hz <= report.command_timeout:
        return ""
    return (f"rate {rate_hz:g} Hz: two periods ({2.0 / rate_hz:.3f} s) exceed the driver's "
            f"command_timeout {report.command_timeout:g} s, its watchdog would trip; use at "
            f"least {2.0 / report.command_timeout:g} Hz")


class DriverView:
    """The last driver report and what each new one changes (nothing known before the first:
    a planner without a driver, as in the unit tests, is not constrained)."""

    def __init__(self) -> None:
        self.report: DriverReport | None = None

    @property
    def ending(self) -> bool:
        """True while the last report is a state in `ENDING_STATES`."""
        return self.report is not None and self.report.state in ENDING_STATES

    def why(self) -> str:
        """The driver's state and reason, as text."""
        if self.report is None:
            return "driver state unknown"
        reason = f": {self.report.reason}" if self.report.reason else ""
        return f"driver {self.report.state}{reason}"

    def update(self, report: DriverReport) -> DriverChange:
        """Take ``report``; what it changes."""
        last, self.report = self.report, report
        if last is not None and last.instance != report.instance:
            return DriverChange.RESTARTED
        if report.state in ENDING_STATES:
            return DriverChange.ENDED
        if last is not None and last.enable_epoch != report.enable_epoch:
            return DriverChange.REENABLED
        return DriverChange.NONE
