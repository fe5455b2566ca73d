"""The recorder's QoS: the stack's topics subscribed at start with the QoS their publishers
declare, the graph poll for other topics and for publishers offering less, and the
``offered_qos_profiles`` channel metadata ``ros2 bag`` writes."""

from __future__ import annotations

import random
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

rclpy = pytest.importorskip("rclpy")

from mcap.reader import make_reader  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import (  # noqa: E402
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from std_msgs.msg import String  # noqa: E402

from crawler_motion.recording import recorder  # noqa: E402
from crawler_motion.recording.qos import (  # noqa: E402
    DEPTH,
    LATCHED,
    compatible,
    declared_qos,
    offered_qos_profiles,
    requested_qos,
)
from crawler_motion.recording.sink import McapSink  # noqa: E402
from crawler_motion.recording.topics import STACK_TOPICS  # noqa: E402

REL, BE = ReliabilityPolicy.RELIABLE, ReliabilityPolicy.BEST_EFFORT
VOL, TL = DurabilityPolicy.VOLATILE, DurabilityPolicy.TRANSIENT_LOCAL


def _qos(rel: ReliabilityPolicy, dur: DurabilityPolicy, depth: int = 10) -> QoSProfile:
    return QoSProfile(depth=depth, reliability=rel, durability=dur)


@pytest.mark.parametrize(("topic", "durability", "depth"), [
    ("planner_status", TL, 1), ("driver_status", TL, 1), ("navigation_status", TL, 1),
    ("gait_command", VOL, 10), ("joint_states", VOL, 10), ("/diagnostics", VOL, 10),
    ("odom", VOL, 10), ("scan", VOL, 10),
])
def test_the_stack_topics_qos_is_what_their_publishers_declare(
        topic: str, durability: DurabilityPolicy, depth: int) -> None:
    qos = recorder.ros_qos(declared_qos(topic))
    assert (qos.reliability, qos.durability, qos.depth) == (REL, durability, depth)


def test_every_latched_topic_is_a_stack_topic() -> None:
    assert LATCHED <= {t.lstrip("/") for t in STACK_TOPICS}


@pytest.mark.parametrize(("offered", "expected"), [
    ([_qos(REL, TL)], (REL, TL)),
    ([_qos(REL, VOL)], (REL, VOL)),
    ([_qos(BE, VOL)], (BE, VOL)),
    ([_qos(REL, TL), _qos(REL, VOL)], (REL, VOL)),  # one volatile publisher: volatile
    ([_qos(REL, TL), _qos(BE, TL)], (BE, TL)),  # one best-effort publisher: best effort
])
def test_the_requested_qos_matches_every_publisher(offered: list[QoSProfile],
                                                   expected: tuple[Any, Any]) -> None:
    qos = recorder.ros_qos(requested_qos(offered))
    assert (qos.reliability, qos.durability, qos.depth) == (*expected, DEPTH)
    assert all(compatible(qos, p) for p in offered)


@pytest.mark.parametrize(("requested", "offered", "ok"), [
    ((REL, TL), (REL, TL), True), ((REL, TL), (REL, VOL), False),
    ((REL, VOL), (BE, VOL), False), ((BE, VOL), (REL, TL), True),
    ((BE, TL), (BE, VOL), False), ((REL, VOL), (REL, TL), True),
])
def test_compatibility_follows_reliability_and_durability(requested: tuple, offered: tuple,
                                                          ok: bool) -> None:
    assert compatible(_qos(*requested), _qos(*offered)) is ok


def test_the_metadata_is_the_ros2_bag_yaml_list() -> None:
    text = offered_qos_profiles([declared_qos("planner_status"), _qos(BE, VOL, 5)])
    profiles = yaml.safe_load(text)
    assert [(p["reliability"], p["durability"], p["depth"], p["history"]) for p in profiles] \
        == [("reliable", "transient_local", 1, "keep_last"), ("best_effort", "volatile", 5,
                                                               "keep_last")]
    assert set(profiles[0]) == {"history", "depth", "reliability", "durability", "deadline",
                                "lifespan", "liveliness", "liveliness_lease_duration",
                                "avoid_ros_namespace_conventions"}
    assert profiles[0]["deadline"] == {"sec": 0, "nsec": 0}
    assert profiles[0]["liveliness"] == "system_default"  # what the publishers declare


@pytest.fixture
def ros(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[dict[str, Any]]:
    """A private ROS context on a random domain: the recorder (never spun until asked) writing
    to ``rec.mcap``, a node for publishers, and ``spin(seconds, until)``."""
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    context = Context()
    rclpy.init(context=context, domain_id=random.randint(1, 100))
    sink = McapSink(tmp_path / "rec.mcap")
    rec = recorder.RecorderNode(sink, context=context)
    other = Node("publishers", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(rec)
    executor.add_node(other)

    def spin(seconds: float, until: Callable[[], bool] = lambda: False) -> bool:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
            if until():
                return True
        return until()

    try:
        yield {"sink": sink, "recorder": rec, "node": other, "spin": spin,
               "path": tmp_path / "rec.mcap"}
    finally:
        executor.shutdown()
        rec.destroy_node()
        other.destroy_node()
        sink.close()
        rclpy.try_shutdown(context=context)


def _matched(pub: Any, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if pub.get_subscription_count() >= 1:
            return True
        time.sleep(0.01)
    return False


def _channels(path: Path) -> dict[str, Any]:
    with open(path, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    return {c.topic: c for c in summary.channels.values()}


def test_a_command_published_right_after_the_start_is_recorded(ros: dict) -> None:
    # the recorder has not been spun: no graph poll has run since it started, yet the first
    # gait command (the demo's `stand`) reaches it
    pub = ros["node"].create_publisher(String, "gait_command", 10)
    assert _matched(pub, 2.0), "the recorder did not subscribe to gait_command at start"
    pub.publish(String(data='{"command": "stand"}'))
    status_qos = recorder.ros_qos(declared_qos("planner_status"))
    latched = ros["node"].create_publisher(String, "planner_status", status_qos)
    latched.publish(String(data='{"state": "IDLE"}'))
    assert ros["spin"](3.0, lambda: ros["sink"].counts["/gait_command"] >= 1
                       and ros["sink"].counts["/planner_status"] >= 1), dict(ros["sink"].counts)
    ros["sink"].close()
    channels = _channels(ros["path"])
    status = yaml.safe_load(channels["/planner_status"].metadata["offered_qos_profiles"])
    assert [(p["reliability"], p["durability"]) for p in status] \
        == [("reliable", "transient_local")]
    command = yaml.safe_load(channels["/gait_command"].metadata["offered_qos_profiles"])
    # from the graph, like ros2 bag: DDS discovery does not carry the history depth
    assert [(p["reliability"], p["durability"]) for p in command] == [("reliable", "volatile")]


def test_a_best_effort_publisher_of_a_stack_topic_is_followed_by_the_poll(ros: dict) -> None:
    pub = ros["node"].create_publisher(Odometry, "odom", qos_profile_sensor_data)
    assert pub.get_subscription_count() == 0  # the reliable subscription cannot match it
    assert ros["spin"](3.0, lambda: pub.get_subscription_count() >= 1), "not re-subscribed"
    assert ros["recorder"].requested["/odom"].reliability == "best_effort"
    pub.publish(Odometry())
    assert ros["spin"](3.0, lambda: ros["sink"].counts["/odom"] == 1)
    ros["sink"].close()
    odom = yaml.safe_load(_channels(ros["path"])["/odom"].metadata["offered_qos_profiles"])
    assert [p["reliability"] for p in odom] == ["best_effort"]


def test_a_topic_outside_the_stack_is_found_by_the_poll(ros: dict) -> None:
    pub = ros["node"].create_publisher(String, "extra_topic", 10)
    assert ros["spin"](3.0, lambda: pub.get_subscription_count() >= 1)
    pub.publish(String(data="x"))
    assert ros["spin"](3.0, lambda: ros["sink"].counts["/extra_topic"] == 1)
