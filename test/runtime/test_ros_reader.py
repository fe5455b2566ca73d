"""Tests of crawler_motion.runtime.ros_reader: a subscription taken by its own thread."""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Iterator
from typing import Any

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from crawler_motion.runtime.ros_reader import SubscriptionReader  # noqa: E402
from crawler_motion.testing.polling import wait_until  # noqa: E402


@pytest.fixture()
def graph() -> Iterator[dict[str, Any]]:
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node(f"reader_{uuid.uuid4().hex[:8]}", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        yield {"node": node, "topic": f"reader_test_{uuid.uuid4().hex[:8]}"}
    finally:
        executor.shutdown(timeout_sec=2.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        spinner.join(2.0)


def test_messages_come_in_the_reader_thread_with_their_info_not_in_the_executor(graph):
    node, topic = graph["node"], graph["topic"]
    got: list[tuple[str, str, dict]] = []
    reader = SubscriptionReader(
        node, String, topic, 10,
        lambda msg, info: got.append((msg.data, threading.current_thread().name, info)),
        on_error=lambda text: got.append(("error", text, {})), name="the-reader")
    reader.start()
    pub = node.create_publisher(String, topic, 10)
    assert wait_until(lambda: pub.get_subscription_count() > 0)
    for i in range(5):
        pub.publish(String(data=str(i)))
    assert wait_until(lambda: len(got) == 5), got
    assert [g[0] for g in got] == ["0", "1", "2", "3", "4"]
    assert {g[1] for g in got} == {"the-reader"}
    assert [g[2]["publication_sequence_number"] for g in got] == [1, 2, 3, 4, 5]
    reader.close()
    assert not reader.running


def test_a_failing_callback_is_reported_and_the_reader_goes_on(graph):
    node, topic = graph["node"], graph["topic"]
    errors: list[str] = []
    seen: list[str] = []

    def callback(msg: Any, _info: dict) -> None:
        seen.append(msg.data)
        if msg.data == "bad":
            raise ValueError("boom")

    reader = SubscriptionReader(node, String, topic, 10, callback, on_error=errors.append)
    reader.start()
    pub = node.create_publisher(String, topic, 10)
    assert wait_until(lambda: pub.get_subscription_count() > 0)
    pub.publish(String(data="bad"))
    pub.publish(String(data="good"))
    assert wait_until(lambda: seen == ["bad", "good"]), seen
    assert len(errors) == 1 and "ValueError: boom" in errors[0]
    reader.close()


def test_while_when_is_false_nothing_is_taken_and_the_newest_waits(graph):
    node, topic = graph["node"], graph["topic"]
    taking = threading.Event()
    seen: list[str] = []
    reader = SubscriptionReader(node, String, topic, 1, lambda m, _i: seen.append(m.data),
                                on_error=seen.append, when=taking.is_set)
    reader.start()
    pub = node.create_publisher(String, topic, 10)
    assert wait_until(lambda: pub.get_subscription_count() > 0)
    for i in range(3):
        pub.publish(String(data=str(i)))
    time.sleep(0.4)
    assert seen == []
    taking.set()
    assert wait_until(lambda: seen == ["2"]), seen  # depth 1: the newest only
    reader.close()
