"""The planner node's ``foot_contacts`` topic and its ``foot contacts`` diagnostic status (rclpy).

`ContactTopics` feeds each validated ``joint_states`` message to the core's
`contacts.ContactMonitor` (thread-safe on its own: not under the node's lock, which the tick
thread takes) and publishes what it says: ``foot_contacts``
(std_msgs/String JSON, see `planner.contacts`) and, on ``/diagnostics``, the status
``<node>: foot contacts`` (hardware_id ``crawler_planner``; WARN while joint states carry no
efforts, else OK) every `DIAGNOSTICS_PERIOD` and at once when its level changes.
"""

from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from crawler_motion.planner.contacts import HARDWARE_ID, STATUS_WHAT, ContactMonitor
from crawler_motion.runtime.diagnostic_names import status_prefix

#: Period of the ``foot contacts`` diagnostic status [s].
DIAGNOSTICS_PERIOD = 1.0


class ContactTopics:
    """Publishers, timer and joint-state hook of the foot contacts of ``node``."""

    def __init__(self, node: Node, monitor: ContactMonitor) -> None:
        self._node, self._monitor = node, monitor
        self._contacts = node.create_publisher(String, "foot_contacts", 10)
        self._diagnostics = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._name = f"{status_prefix(node.get_namespace(), node.get_name())}: {STATUS_WHAT}"
        self._warn: bool | None = None
        node.create_timer(DIAGNOSTICS_PERIOD, self.publish_diagnostics,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    def on_joint_state(self, msg: JointState, angles: np.ndarray) -> None:
        """Estimate from one joint state whose positions were validated (``angles`` in joint
        order [rad]); its header stamp dates it (the reception time when it has none)."""
        now = time.monotonic()
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec or now
        text = self._monitor.update(msg.name, angles, msg.effort, stamp, now)
        warn = self._monitor.diagnostic(now)[0]
        if text is not None:
            self._contacts.publish(String(data=text))
        if warn != self._warn:
            self.publish_diagnostics()

    def publish_diagnostics(self) -> None:
        """Publish the ``foot contacts`` status now."""
        warn, message = self._monitor.diagnostic(time.monotonic())
        self._warn = warn
        status = DiagnosticStatus(level=DiagnosticStatus.WARN if warn else DiagnosticStatus.OK,
                                  name=self._name, hardware_id=HARDWARE_ID, message=message)
        array = DiagnosticArray(status=[status])
        array.header.stamp = self._node.get_clock().now().to_msg()
        self._diagnostics.publish(array)
