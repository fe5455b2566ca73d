"""The navigator's mission topics (rclpy in-process): a repeat of the running mission's text
changes nothing; another text replaces it; no odometry refuses it."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")

from std_msgs.msg import String  # noqa: E402

from crawler_motion.navigation.apf_navigator import ApfNavigator  # noqa: E402
from crawler_motion.navigation.mission_runner import MissionState  # noqa: E402
from crawler_motion.navigation.mission_topics import MissionTopics  # noqa: E402

ONE = "id: one\ntasks: [{goto: {x: 1.0, y: 0.0}}]\n"
TWO = "id: two\ntasks: [{goto: {x: 0.5, y: 0.0}}]\n"


def topics(pose: tuple[float, float, float] | None) -> tuple[MissionTopics, list[str]]:
    node = rclpy.create_node("mission_topics_test")
    refused: list[str] = []
    return MissionTopics(node, ApfNavigator(), 0.16, lambda: pose, refused.append,
                         lambda: None), refused


def test_a_repeat_of_the_running_mission_changes_nothing(ros_domain: int) -> None:
    mt, refused = topics((0.0, 0.0, 0.0))
    try:
        mt._on_mission(String(data=ONE))
        first = mt.runner
        assert first is not None and mt.running
        mt._on_mission(String(data=ONE))  # the sender's repeat
        assert mt.runner is first and first.state is MissionState.RUNNING
        mt._on_mission(String(data=TWO))  # another mission replaces it
        assert mt.runner is not first and first.state is MissionState.CANCELLED
        assert mt.runner is not None and mt.runner.mission.id == "two"
        assert refused == []
    finally:
        mt.node.destroy_node()


def test_a_mission_without_odometry_is_refused(ros_domain: int) -> None:
    mt, refused = topics(None)
    try:
        mt._on_mission(String(data=ONE))
        assert mt.runner is None and refused and "no odometry yet" in refused[0]
    finally:
        mt.node.destroy_node()
