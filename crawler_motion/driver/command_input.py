"""The driver's joint-command input: the ``joint_commands`` topic and a direct hand-over."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from crawler_motion.driver.core import DriverCore
from crawler_motion.runtime.ros_reader import SubscriptionReader

#: QoS of the driver's ``joint_commands`` subscription: only the newest command matters, and
#: over a lossy link a lost command must not be resent late nor hold back the next one.
COMMAND_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


class CommandInput:
    """Joint commands into the driver's core (``core()``: the current one, None while
    unconfigured), from the ``joint_commands`` topic and, in the composed controller, from the
    planner's tick (`submit`).

    The topic is taken by a thread of its own (`ros_reader.SubscriptionReader`), not by the
    node's executor, whose cost per message was most of the driver's CPU per command.
    `compose` (the controller) sets ``own_command(msg)``, True for a message its planner
    handed over already: those are skipped, and the topic is taken only while it has a
    publisher besides that planner.
    """

    def __init__(self, node: Node, core: Callable[[], DriverCore | None]) -> None:
        self._node = node
        self._core = core
        self.own_command: Callable[[JointState], bool] | None = None
        self._others = lambda: True  # the topic has publishers whose messages count
        self.dropped_unconfigured = 0  # commands dropped while no core existed
        self._reader = SubscriptionReader(node, JointState, "joint_commands", COMMAND_QOS,
                                          self._on_message, name="driver-commands",
                                          on_error=node.get_logger().error,
                                          when=lambda: self._others())

    def compose(self, own_command: Callable[[JointState], bool]) -> None:
        """The composed controller: ``own_command(msg)`` tells its planner's messages."""
        topic = self._reader.subscription.topic_name
        self.own_command = own_command
        self._others = lambda: self._node.count_publishers(topic) > 1

    def start(self) -> None:
        """Start taking the topic."""
        self._reader.start()

    def close(self) -> None:
        """Stop taking the topic and destroy its subscription."""
        self._reader.close()

    def _on_message(self, msg: JointState, info: Mapping[str, Any]) -> None:
        if self.own_command is None or not self.own_command(msg):
            self.submit(msg.name, msg.position, msg.velocity, msg.effort,
                        info.get("publication_sequence_number"))  # for the SenderWatch

    def submit(self, names: Sequence[str], positions: Sequence[float],
               velocities: Sequence[float] = (), efforts: Sequence[float] = (),
               sequence: int | None = None) -> bool:
        """One joint command into the core (`DriverCore.submit`; any thread); True if it was
        accepted. A refusal while active is logged (at most once a second)."""
        core = self._core()
        if core is None:
            self.dropped_unconfigured += 1
            return False
        result = core.submit(names, positions, velocities, efforts, sequence=sequence)
        if not result.accepted and core.active:
            self._node.get_logger().warning(f"joint_commands refused: {result.reason}",
                                            throttle_duration_sec=1.0)
        return result.accepted
