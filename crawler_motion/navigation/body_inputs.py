"""The navigator's body inputs: its pose from ``odom`` and its virtual radius from
``joint_states``, each taken by a thread of its own.

At 50 Hz (``odom``) and 100 Hz (``joint_states``) the executor's wake-ups and wait-set
rebuilds for these two topics were two thirds of the navigator's CPU (py-spy on the real-time
stack), its callbacks a tenth. Here `runtime.ros_reader.SubscriptionReader` takes them:
every ``odom`` sample (through `OdometryInput`'s gate, as before), and the newest joint state
at most every `JOINTS_PERIOD` (the radius only matters at the map cycles, a few a second).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from crawler_motion.errors import CommandError
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.joint_state import validate_joint_state
from crawler_motion.navigation.body import envelope_radius, virtual_radius
from crawler_motion.navigation.odometry_input import OdometryInput
from crawler_motion.runtime.ros_reader import SubscriptionReader

#: The virtual radius is recomputed from the newest joint state at most this often [s] (the
#: driver publishes 100 Hz; the map cycles run a few times a second).
JOINTS_PERIOD = 0.1
#: joint_states: best effort, the newest state only.
JOINTS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
#: odom: reliable, every sample (the odometry gate checks each against the last).
ODOM_QOS = 20


class BodyInputs:
    """``odom`` into `odom` (`OdometryInput`) and the virtual radius [m] (`radius`: the
    envelope radius until a joint state arrives) of ``robot``, for ``node``. ``guard`` wraps
    each callback (`runtime.callback_guard.CallbackGuard.wrap`); ``now()`` is the node's clock
    in the stamps' time base [s]. `start` starts the threads, `close` ends them."""

    def __init__(self, node: Node, robot: RobotConfig,
                 guard: Callable[[str, Callable[..., Any]], Callable[..., Any]],
                 now: Callable[[], float]) -> None:
        self.odom = OdometryInput(node.get_logger())
        self.radius = envelope_radius(robot)
        self._robot, self._now = robot, now
        self._joints_at = -float("inf")  # steady time of the last joint state taken [s]
        error = node.get_logger().error
        self._readers = (
            SubscriptionReader(node, Odometry, "odom", ODOM_QOS,
                               guard("odom", lambda m, _: self.odom.take(m, self._now())),
                               on_error=error, name="navigator-odom"),
            SubscriptionReader(node, JointState, "joint_states", JOINTS_QOS,
                               guard("joint_states", lambda m, _: self.take_joints(m)),
                               on_error=error, name="navigator-joints", when=self._joints_due))

    def start(self) -> None:
        """Start taking messages."""
        for reader in self._readers:
            reader.start()

    def close(self) -> None:
        """Stop the threads and destroy the subscriptions."""
        for reader in self._readers:
            reader.close()

    def _joints_due(self) -> bool:
        """True when the radius is `JOINTS_PERIOD` old: take the newest state."""
        return time.monotonic() - self._joints_at >= JOINTS_PERIOD

    def take_joints(self, msg: JointState) -> None:
        """The virtual radius of one joint state (one that is not valid is ignored)."""
        self._joints_at = time.monotonic()
        try:
            q = validate_joint_state(msg.name, msg.position, msg.velocity,
                                     self._robot.joint_names)
        except CommandError:
            return
        self.radius = virtual_radius(self._robot, q)
