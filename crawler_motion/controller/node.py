"""``controller_node``: the planner and the driver composed in one process.

As ros2_control's controller manager runs controllers and hardware interfaces together, this
runs a `PlannerNode` and a `DriverNode` in one process and one executor, and each tick of the
planner hands its targets straight to the driver (`DirectLink`, in the tick thread: validated,
encoded and on the bus within the tick), with no DDS hop; the other way, each measured joint
state the driver publishes goes straight to the planner (`link_measured`, in the driver's CAN
thread), not through DDS and the executor. Everything else is the two nodes as
they are: their names (``planner``, ``driver``), parameters, topics, services and lifecycle; the
planner still publishes ``joint_commands`` (for observers and recorders) and the driver
``joint_states``, ``driver_status`` and ``/diagnostics``; so tools and tests address the
controller as they address the two-node pipeline. Only the timing differs.

The driver still reads ``joint_commands``: its own planner's messages (recognised by their
stamps) reached it already and are skipped; any other publisher's are submitted as in the
two-node pipeline, so a second publisher racing the planner is detected the same way (the
hand-over numbers its commands as a stream of its own for `driver.senders.SenderWatch`).
Likewise the planner takes ``joint_states`` from other publishers (`planner.measured_input`),
skipping its own driver's.

Parameters: ``-p name:=value`` goes to both nodes (each takes its own; ``config_file`` both),
``--params-file`` sections ``planner`` / ``driver`` apply as for the two processes; a node's own
remap is ``-r planner:__node:=...``. The driver's ``priority`` applies to the whole process.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

from builtin_interfaces.msg import Time
from rclpy.node import Node
from sensor_msgs.msg import JointState

from crawler_motion.driver.node import DriverNode
from crawler_motion.planner.core import JointTarget
from crawler_motion.planner.node import PlannerNode
from crawler_motion.runtime.ros_main import run_nodes

#: GIL switch interval of the controller process [s], as of the two nodes: the tick thread,
#: the CAN thread and the executor share one interpreter; a tick waits at most about this long
#: for the GIL (shorter intervals measured no better here, and cost CPU).
GIL_SWITCH_INTERVAL = 0.0005
#: Stamps of the commands handed over that are remembered (to skip them on joint_commands).
OWN_STAMPS = 64
#: First number of the hand-over's commands for the driver's sender watch: far above any DDS
#: publication sequence number, so the two never continue each other's stream.
LOCAL_SEQUENCE_BASE = 1 << 62


class OwnStamps:
    """The header stamps of the last `OWN_STAMPS` messages handed over directly, to tell them
    when they arrive on their topic too (deque appends and reads are thread-safe)."""

    def __init__(self) -> None:
        self._stamps: deque[tuple[int, int]] = deque(maxlen=OWN_STAMPS)

    def add(self, stamp: Time) -> None:
        """A message stamped ``stamp`` was handed over."""
        self._stamps.append((stamp.sec, stamp.nanosec))

    def is_own(self, msg: JointState) -> bool:
        """True for a message handed over already (recognised by its header stamp)."""
        stamp = msg.header.stamp
        return (stamp.sec, stamp.nanosec) in self._stamps


class DirectLink:
    """The planner's tick to the driver core, in the tick thread (`PlannerNode.on_target`)."""

    def __init__(self, driver: DriverNode, joint_names: Sequence[str]) -> None:
        self._input = driver.commands
        self._names = list(joint_names)
        self._stamps = OwnStamps()
        self._sequence = LOCAL_SEQUENCE_BASE
        self.handed = 0  # commands handed over
        self.accepted = 0  # of them, accepted by the driver

    def hand_over(self, target: JointTarget, stamp: Time) -> None:
        """Submit one tick's targets; its ``stamp`` marks the message published after it."""
        self._stamps.add(stamp)
        self._sequence += 1
        self.handed += 1
        if self._input.submit(self._names, target.position_list(),
                              target.velocity_list(), (), self._sequence):
            self.accepted += 1

    def is_own(self, msg: JointState) -> bool:
        """True for a joint_commands message of this controller's planner."""
        return self._stamps.is_own(msg)


def link_measured(driver: DriverNode, planner: PlannerNode) -> OwnStamps:
    """Each joint state the driver publishes to the planner directly (in the driver's CAN
    thread); the planner skips those on ``joint_states`` (the returned stamps)."""
    stamps = OwnStamps()
    measured = planner.measured
    measured.compose(stamps.is_own)

    def hand_over(msg: JointState) -> None:
        stamps.add(msg.header.stamp)
        measured.hand_over(msg)

    driver.on_joint_state = hand_over
    return stamps


def compose(nodes: list[Node]) -> DirectLink:
    """Build the driver and the planner into ``nodes`` and link them. The driver first: its
    ``priority`` sets every thread of the process, the planner's tick thread then takes its
    own ``tick_priority``; at the end the planner stops first (no tick without a driver, and
    no joint state is handed to it any more)."""
    driver = DriverNode()
    nodes.append(driver)
    planner = PlannerNode()
    nodes.append(planner)
    link = DirectLink(driver, planner.cfg.robot.joint_names)
    driver.commands.compose(link.is_own)
    planner.on_target = link.hand_over
    link_measured(driver, planner)
    planner.get_logger().info("composed with the driver: each tick goes to the bus directly")
    return link


def main(args: list[str] | None = None) -> None:
    """Console script ``controller_node``: spin both nodes until Ctrl-C or shutdown."""
    run_nodes(compose, "controller_node: error", args, switch_interval=GIL_SWITCH_INTERVAL)


if __name__ == "__main__":
    main()
