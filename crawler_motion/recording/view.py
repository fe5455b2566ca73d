"""``crawler-motion view``: the running stack served live to Foxglove over its WebSocket protocol.

The stack's topics are relayed unchanged (CDR under their ``ros2msg`` schemas, which Foxglove
decodes like a ``ros2 bag``): odometry, joint states and commands, terrain map, scan, goal,
planner / navigation status and ``/diagnostics``. Without tf2, the frame tree is computed here:
``/tf`` carries ``odom`` -> ``base_link`` from ``odom`` and every URDF joint's transform at the
measured ``joint_states`` (`crawler_motion.recording.frames`); ``/robot_description`` carries the
URDF generated from the robot configuration (``--config``, ``--calibration``: give the planner's
leg calibration when it is not robot.yaml's). Load ``docs/foxglove_layout.json`` in Foxglove and
connect to ``ws://127.0.0.1:8765``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from functools import partial
from typing import Any

import foxglove
import rclpy
from foxglove.channels import FrameTransformsChannel
from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Timestamp, Vector3
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.model.calibration_file import with_calibration
from crawler_motion.model.config import load_config
from crawler_motion.model.urdf import generate_urdf
from crawler_motion.recording.frames import Transform, joint_transforms, urdf_joints
from crawler_motion.recording.msgdefs import message_definition
from crawler_motion.recording.recorder import message_class
from crawler_motion.recording.topics import STACK_TOPICS, absolute
from crawler_motion.runtime.cli_args import OneLineParser

PROG = "crawler-motion view"
#: Topics relayed to Foxglove as they are.
RELAYED = ("odom", "joint_states", "joint_commands", "terrain_map", "scan", "goal_pose",
           "planner_status", "navigation_status", "driver_status", "/diagnostics", "imu")
TF_TOPIC = "/tf"
DESCRIPTION_TOPIC = "/robot_description"
STRING_TYPE = "std_msgs/msg/String"
#: Period of the robot description for clients that connect later [s].
DESCRIPTION_PERIOD = 2.0
#: Best effort, volatile: matches every publisher.
RELAY_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)


def ros2_channel(topic: str, type_name: str) -> foxglove.Channel:
    """A Foxglove channel carrying CDR messages of ``type_name``."""
    schema = foxglove.Schema(name=type_name, encoding="ros2msg",
                             data=message_definition(type_name).encode())
    return foxglove.Channel(topic, schema=schema, message_encoding="cdr")


def frame_transforms(transforms: list[Transform], sec: int, nanosec: int) -> FrameTransforms:
    """The Foxglove message of ``transforms`` stamped ``sec``/``nanosec``."""
    stamp = Timestamp(sec=sec, nsec=nanosec)
    return FrameTransforms(transforms=[FrameTransform(
        timestamp=stamp, parent_frame_id=parent, child_frame_id=child,
        translation=Vector3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
        rotation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])))
        for parent, child, xyz, q in transforms])


class LiveView(Node):
    """Relays the stack's topics to Foxglove channels and publishes the computed frames."""

    def __init__(self, urdf: str | None = None) -> None:
        super().__init__("foxglove_view")
        urdf = urdf if urdf is not None else generate_urdf(load_config().robot)
        self.joints = urdf_joints(urdf)
        self.channels = {absolute(t): ros2_channel(absolute(t), STACK_TOPICS[t])
                         for t in RELAYED}
        self.tf = FrameTransformsChannel(TF_TOPIC)
        self.description = ros2_channel(DESCRIPTION_TOPIC, STRING_TYPE)
        self.urdf = serialize_message(String(data=urdf))
        for topic in RELAYED:
            self.create_subscription(message_class(STACK_TOPICS[topic]), topic,
                                     partial(self.relay, absolute(topic)), RELAY_QOS, raw=True)
        self.create_timer(DESCRIPTION_PERIOD, self.describe)
        self.describe()

    def describe(self) -> None:
        """Publish the URDF on ``/robot_description``."""
        self.description.log(self.urdf)

    def relay(self, topic: str, data: bytes) -> None:
        """Pass one message on; odometry and joint states also move the frames."""
        self.channels[topic].log(data)
        if topic == "/odom":
            odom = deserialize_message(data, Odometry)
            p, q = odom.pose.pose.position, odom.pose.pose.orientation
            self._frames([(odom.header.frame_id or "odom", odom.child_frame_id or "base_link",
                           (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))], odom.header.stamp)
        elif topic == "/joint_states":
            state = deserialize_message(data, JointState)
            angles = dict(zip(state.name, state.position, strict=False))
            self._frames(joint_transforms(self.joints, angles), state.header.stamp)

    def _frames(self, transforms: list[Any], stamp: Any) -> None:
        self.tf.log(frame_transforms(transforms, stamp.sec, stamp.nanosec))


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """The view's options."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to serve on (default 127.0.0.1: this machine only)")
    parser.add_argument("--port", type=int, default=8765, help="WebSocket port (default 8765)")
    parser.add_argument("--config", default=None, help="robot YAML (default: the shipped one)")
    parser.add_argument("--calibration", default=None,
                        help="leg calibration YAML (default: robot.yaml's, else nominal)")
    args, _ros = parser.parse_known_args(argv)
    if not 0 <= args.port <= 65535:
        parser.error(f"--port must be in [0, 65535], got {args.port}")
    return args


def robot_description(args: argparse.Namespace) -> str:
    """The URDF of ``--config`` with the legs of ``--calibration`` (`CrawlerMotionError` for a
    bad file)."""
    return generate_urdf(with_calibration(load_config(args.config).robot, args.calibration))


def main(argv: Sequence[str] | None = None) -> int:
    """Serve until Ctrl-C; returns the exit status."""
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        urdf = robot_description(args)
    except CrawlerMotionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    try:
        server = foxglove.start_server(name="crawler_motion", host=args.host, port=args.port)
    except RuntimeError as exc:
        print(f"{PROG}: error: cannot serve on {args.host}:{args.port}: {exc}", file=sys.stderr)
        return 1
    print(f"{PROG}: serving the stack to Foxglove at ws://{args.host}:{server.port} "
          "(layout: docs/foxglove_layout.json)", flush=True)
    rclpy.init(args=None)
    node = None
    try:
        node = LiveView(urdf)
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
