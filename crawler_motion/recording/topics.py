"""The stack's topics and their message types: what `record` and `view` subscribe to."""

from __future__ import annotations

#: Topic -> message type of every topic the stack publishes (names as published, relative
#: names resolve in the recorder's namespace). Topics other issues add are found on the graph.
STACK_TOPICS: dict[str, str] = {
    "planner_status": "std_msgs/msg/String",
    "foot_contacts": "std_msgs/msg/String",
    "driver_status": "std_msgs/msg/String",
    "gait_command": "std_msgs/msg/String",
    "cmd_vel": "geometry_msgs/msg/Twist",
    "joint_commands": "sensor_msgs/msg/JointState",
    "joint_states": "sensor_msgs/msg/JointState",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    "odom": "nav_msgs/msg/Odometry",
    "imu": "sensor_msgs/msg/Imu",
    "scan": "sensor_msgs/msg/PointCloud2",
    "terrain_map": "nav_msgs/msg/OccupancyGrid",
    "terrain_heights": "sensor_msgs/msg/PointCloud2",
    "navigation_status": "std_msgs/msg/String",
    "goal_pose": "geometry_msgs/msg/PoseStamped",
    "follow_command": "std_msgs/msg/String",
    "estop": "std_msgs/msg/Bool",
}


def absolute(topic: str) -> str:
    """``topic`` as the graph names it in the root namespace (leading ``/``)."""
    return topic if topic.startswith("/") else f"/{topic}"
