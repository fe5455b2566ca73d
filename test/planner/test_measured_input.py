"""Tests of crawler_motion.planner.measured_input: joint_states through the executor, or handed
over directly (composed) and taken in the tick thread, the topic's other publishers still
taken, the driver's own messages skipped."""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Callable, Iterator
from typing import Any

import pytest

rclpy = pytest.importorskip("rclpy")

from builtin_interfaces.msg import Time  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from crawler_motion.planner.measured_input import MAX_HANDED, MeasuredInput  # noqa: E402
from crawler_motion.testing.polling import wait_until  # noqa: E402


def state(nanosec: int) -> JointState:
    msg = JointState(name=["a"], position=[0.1 * nanosec])
    msg.header.stamp = Time(sec=7, nanosec=nanosec)
    return msg


@pytest.fixture()
def node() -> Iterator[Any]:
    context = Context()
    rclpy.init(context=context)
    ns = f"/measured_{uuid.uuid4().hex[:8]}"
    node = rclpy.create_node("planner", namespace=ns, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        yield node
    finally:
        executor.shutdown(timeout_sec=2.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        spinner.join(2.0)


def _taker() -> tuple[list[tuple[int, str]], Callable[..., None]]:
    got: list[tuple[int, str]] = []
    return got, lambda msg, received=None: got.append((msg.header.stamp.nanosec,
                                                       threading.current_thread().name))


def test_alone_the_topic_is_taken_by_the_executor(node) -> None:
    got, take = _taker()
    measured = MeasuredInput(node, take)
    pub = node.create_publisher(JointState, "joint_states", 10)
    assert wait_until(lambda: pub.get_subscription_count() == 1)
    pub.publish(state(1))
    assert wait_until(lambda: got) and got[0][0] == 1 and not measured.composed
    assert got[0][1] != "planner-joint-states"
    assert measured.take_handed() == 0


def test_composed_states_handed_over_are_taken_in_order_by_take_handed(node) -> None:
    got, take = _taker()
    measured = MeasuredInput(node, take)
    measured.compose(lambda msg: True)
    for n in range(MAX_HANDED + 3):  # the tick thread stalled: the oldest 3 are dropped
        measured.hand_over(state(n))
    assert got == []  # nothing taken in the handing thread
    assert measured.take_handed() == MAX_HANDED
    assert [n for n, _ in got] == list(range(3, MAX_HANDED + 3))
    assert (measured.handed, measured.dropped) == (MAX_HANDED + 3, 3)
    measured.close()
    measured.hand_over(state(99))
    assert measured.take_handed() == 0 and len(got) == MAX_HANDED


def test_composed_the_topic_is_taken_only_with_another_publisher_skipping_own(node) -> None:
    """The driver's publisher alone: nothing is taken from the topic. A second publisher: its
    messages are taken (in the reader thread), the driver's own (by stamp) still skipped."""
    got, take = _taker()
    measured = MeasuredInput(node, take)
    own = {1, 2, 3}
    measured.compose(lambda msg: msg.header.stamp.nanosec in own)
    driver = node.create_publisher(JointState, "joint_states", 10)
    assert wait_until(lambda: driver.get_subscription_count() == 1)  # the reader's, moved
    driver.publish(state(1))
    time.sleep(0.3)  # a gate period: the reader does not take the topic
    assert got == []
    other = node.create_publisher(JointState, "joint_states", 10)
    assert wait_until(lambda: node.count_publishers("joint_states") == 2)
    deadline = time.monotonic() + 10.0
    while not got and time.monotonic() < deadline:
        driver.publish(state(2))
        other.publish(state(50))
        time.sleep(0.05)
    assert got and {n for n, _ in got} == {50}
    assert {name for _, name in got} == {"planner-joint-states"}
    measured.close()


def test_a_state_handed_over_keeps_the_time_it_was_handed_over_at(node) -> None:
    """Taken after a stalled tick thread, a state is as old as it is: a resume from the
    measured pose waits for one handed over after the interruption."""
    received: list[float] = []
    measured = MeasuredInput(node, lambda msg, at=None: received.append(at))
    measured.compose(lambda msg: True)
    before = time.monotonic()
    measured.hand_over(state(1))
    time.sleep(0.2)  # the tick thread stalls
    measured.hand_over(state(2))
    after = time.monotonic()
    assert measured.take_handed() == 2
    assert before <= received[0] <= received[0] + 0.15 < received[1] <= after
    measured.close()


@pytest.mark.parametrize(("age", "expected"), [
    (0.0, 100.0), (0.25, 99.75), (1.0, 99.0),
    (1.01, 100.0),  # older than MAX_STAMP_AGE: from its receipt
    (-0.01, 100.0),  # stamped in the future (another clock): from its receipt
])
def test_a_state_is_measured_when_its_stamp_says_within_reason(age, expected):
    from crawler_motion.planner.measured_input import measured_at

    clock_ns = 7 * 10**9 + 500_000_000
    msg = state(0)
    stamp_ns = clock_ns - round(age * 1e9)
    msg.header.stamp = Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    assert measured_at(msg, clock_ns, received=100.0) == pytest.approx(expected, abs=1e-9)
