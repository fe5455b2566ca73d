"""The driver's ROS messages built from its core: ``/diagnostics`` and ``driver_status``."""

from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from crawler_motion.driver.core import DriverCore
from crawler_motion.driver.diagnostics import StatusEntry

#: hardware_id of the driver's statuses (the planner's ``fault_hardware_id`` watches it).
HARDWARE_ID = "motor_manager"


def diagnostic_array(entries: list[StatusEntry], prefix: str,
                     lifecycle_state: str) -> DiagnosticArray:
    """The /diagnostics message of ``entries`` (unstamped), each status named ``<prefix>:
    <entry>`` (``prefix``: `diagnostic_names.status_prefix` of the node); the manager's entry
    also carries the lifecycle state."""
    array = DiagnosticArray()
    for entry in entries:
        values = [KeyValue(key="lifecycle_state", value=lifecycle_state)] if (
            entry.name == "motor manager") else []
        values.extend(KeyValue(key=k, value=v) for k, v in entry.values)
        array.status.append(DiagnosticStatus(
            level=bytes([entry.level]), name=f"{prefix}: {entry.name}",
            message=entry.message, hardware_id=HARDWARE_ID, values=values))
    return array


def driver_status(core: DriverCore | None, lifecycle: str, latched: str,
                  configure_error: str, instance: str) -> dict[str, Any]:
    """The ``driver_status`` object: gate state, enable epoch, lifecycle state, reason, the
    ``instance`` token of this driver process and the ``command_timeout`` [s]."""
    common = {"lifecycle": lifecycle, "instance": instance}
    if core is None:
        return {"state": "estop" if latched else "inactive", "enable_epoch": 0, **common,
                "reason": latched or configure_error or "not configured"}
    return {"state": core.gate_state, "enable_epoch": core.enable_epoch, **common,
            "command_timeout": core.settings.command_timeout, "reason": core.estop_reason or (
                "" if core.motion_allowed else "motors not enabled / watchdog tripped")}
