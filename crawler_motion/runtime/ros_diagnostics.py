"""One ``/diagnostics`` status of a node with its counters as key-value pairs (rclpy messages).

The status is named ``<node>: <what>`` (`diagnostic_names.status_prefix`), so a node reading
``/diagnostics`` places it on its robot; the values are the node's counters, one key each.
"""

from __future__ import annotations

from collections.abc import Mapping

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

from crawler_motion.runtime.diagnostic_names import status_prefix

#: Status levels by name (the message's constants are one-byte ``bytes``).
LEVELS = {"ok": DiagnosticStatus.OK, "warn": DiagnosticStatus.WARN,
          "error": DiagnosticStatus.ERROR}


def counters_array(node: Node, what: str, hardware_id: str, level: str, message: str,
                   values: Mapping[str, object]) -> DiagnosticArray:
    """A `DiagnosticArray` of one status of ``node`` (``level``: ok, warn or error) whose
    values are ``values`` as text, stamped with the node's clock."""
    status = DiagnosticStatus(
        level=LEVELS[level], name=f"{status_prefix(node.get_namespace(), node.get_name())}: "
        f"{what}", hardware_id=hardware_id, message=message,
        values=[KeyValue(key=str(k), value=str(v)) for k, v in values.items()])
    array = DiagnosticArray(status=[status])
    array.header.stamp = node.get_clock().now().to_msg()
    return array
