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

from crawler_motion.planner.measured_input import (  # noqa: E402
    LAG_WINDOW,
    MAX_HANDED,
    MeasuredInput,
    StampAges,
)
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


def stamped(clock_ns: int, lag: float) -> JointState:
    msg = state(0)
    stamp_ns = clock_ns - round(lag * 1e9)
    msg.header.stamp = Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    return msg


# (lags of the states before [s], lag of the state [s]) -> its age [s] (received at 100.0 s)
AGE_ROWS = [
    ((), 0.25, 0.0),  # the first state: its lag is the offset
    ((0.001,) * 5, 0.601, 0.6),  # waited 0.6 s in the queue while the planner was stopped
    ((0.001,) * 5, 3.001, 3.0),  # 3 s: still its age (a soak's stops last 1-3 s)
    ((2.0,) * 5, 2.0005, 0.0005),  # the driver's clock 2 s behind: not age
    ((-1.5,) * 5, -1.5, 0.0),  # 1.5 s ahead
    ((0.0,) * 5 + (2.0,) * LAG_WINDOW, 2.0, 0.0),  # a clock step: forgotten within the window
]


@pytest.mark.parametrize(("before", "lag", "age"), AGE_ROWS)
def test_a_state_is_as_old_as_its_lag_beyond_the_least_recent_lag(before, lag, age):
    clock_ns = 1_700_000_000 * 10**9
    ages = StampAges()
    for earlier in before:
        ages.measured_at(stamped(clock_ns, earlier), clock_ns, received=99.0)
    got = ages.measured_at(stamped(clock_ns, lag), clock_ns, received=100.0)
    assert got == pytest.approx(100.0 - age, abs=1e-6)


def test_an_unstamped_state_counts_from_its_receipt():
    msg = JointState(name=["a"], position=[0.1])
    assert StampAges().measured_at(msg, 10**18, received=5.0) == 5.0
