"""The planner's measured joint states: the ``joint_states`` topic and a direct hand-over.

The planner node takes ``joint_states`` (sensor_msgs/JointState, sensor-data QoS) through its
executor. In the composed controller (`crawler_motion.controller.node`) its driver runs in the
same process and hands each measured state over directly (`MeasuredInput.hand_over`, in the
driver's CAN thread, right after publishing it), as the planner hands its targets to the driver:
no serialisation, no executor wake-up and wait-set rebuild per message (at 100 Hz the largest
share of the executor's CPU). The planner takes the states handed over in its tick thread,
right after a tick (`take_handed`): that work then fills the time between two ticks instead of
holding the interpreter lock when the next tick is due. Each state keeps the steady time it was
handed over at, so one taken after a stalled tick thread is not taken for a newer measurement
(a resume waits for one taken after the interruption). The topic is then read by a thread of
its own
(`runtime.ros_reader.SubscriptionReader`) and only while it has a publisher besides that
driver; the driver's own messages (``own_state``) reached the planner already and are skipped,
any other publisher's are taken as in the two-node pipeline.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState

from crawler_motion.runtime.ros_reader import SubscriptionReader

#: QoS of the ``joint_states`` subscription (only fresh measurements matter).
MEASURED_QOS = qos_profile_sensor_data
#: Least time between two warnings of more than one joint_states publisher [s].
FOREIGN_WARN_PERIOD = 2.0
#: A joint state's lag (the node's clock minus its header stamp) is compared with the least lag
#: of this many recent states (2 s at 100 Hz), which holds the clocks' offset and the transport.
LAG_WINDOW = 200
#: States handed over and not yet taken, at most (the oldest is dropped beyond: a stalled tick
#: thread must not grow the queue; 0.16 s of feedback at 100 Hz).
MAX_HANDED = 16


class StampAges:
    """When each joint state was measured, by its header stamp (no ROS: plain numbers).

    A state's age is its lag (the node's clock minus its header stamp) beyond the least lag of
    the last `LAG_WINDOW` states: a constant offset between the driver's and the planner's
    clocks (another machine) and the usual transport delay are not age. States that waited in
    the subscription's queue while the planner process was stopped are so taken for what they
    are, measurements from before the wait (a resume starts from a pose measured after it).
    An unstamped state (stamp 0) counts from its receipt.
    """

    def __init__(self) -> None:
        self._lags: deque[float] = deque(maxlen=LAG_WINDOW)

    def measured_at(self, msg: JointState, clock_ns: int, received: float | None = None
                    ) -> float:
        """Steady time [s] ``msg`` was measured: its receipt ``received`` (None: now) minus
        its age against the node's clock ``clock_ns`` [ns]."""
        now = time.monotonic() if received is None else received
        stamp = msg.header.stamp
        if stamp.sec == 0 and stamp.nanosec == 0:
            return now
        lag = (clock_ns - (stamp.sec * 1_000_000_000 + stamp.nanosec)) * 1e-9
        self._lags.append(lag)
        return now - (lag - min(self._lags))


class MeasuredInput:
    """``take(msg)`` for every measured joint state of ``node``: from the ``joint_states``
    topic through the executor, or after `compose` directly from the driver (`hand_over`:
    ``take(msg, received)``, the steady time [s] of the hand-over) and from the topic's other
    publishers."""

    def __init__(self, node: Node, take: Callable[..., None]) -> None:
        self._node = node
        self._take = take
        self._subscription = node.create_subscription(JointState, "joint_states", take,
                                                      MEASURED_QOS)
        self._topic = self._subscription.topic_name
        self._reader: SubscriptionReader | None = None
        self._handed: deque[tuple[JointState, float]] = deque(maxlen=MAX_HANDED)
        self.ages = StampAges()  # when a state of the topic was measured
        self.closed = False
        self.handed = 0  # states handed over directly
        self.dropped = 0  # of them, dropped untaken (more than MAX_HANDED waiting)
        self.publishers = 0  # of the topic, as last counted

    @property
    def composed(self) -> bool:
        """True after `compose`."""
        return self._reader is not None

    def compose(self, own_state: Callable[[JointState], bool]) -> None:
        """The composed controller: ``own_state(msg)`` tells the messages its driver handed
        over already. The topic moves out of the executor into a reader thread that takes it
        only while another process or node publishes it too."""
        if self._reader is not None:
            return
        subscription = self._subscription
        topic = subscription.topic_name
        self._reader = SubscriptionReader(
            self._node, JointState, "joint_states", MEASURED_QOS,
            lambda msg, _info: None if own_state(msg) else self._take(msg),
            name="planner-joint-states", on_error=self._node.get_logger().error,
            when=lambda: self._node.count_publishers(topic) > 1)
        self._node.destroy_subscription(subscription)
        self._reader.start()

    def hand_over(self, msg: JointState) -> None:
        """One measured joint state from the driver of the same process (any thread); taken
        by the next `take_handed`."""
        if not self.closed:
            self.handed += 1
            if len(self._handed) == MAX_HANDED:
                self.dropped += 1
            self._handed.append((msg, time.monotonic()))

    def take_handed(self) -> int:
        """Take the states handed over since the last call, in order (the tick thread, after
        a tick); returns how many."""
        taken = 0
        while self._handed and not self.closed:
            self._take(*self._handed.popleft())
            taken += 1
        return taken

    def count_publishers(self) -> int:
        """Count the topic's publishers now (a graph query: the caller's periodic timer, not
        the tick thread); more than 1 means the measured pose may be any of theirs: a warning
        (at most every `FOREIGN_WARN_PERIOD`)."""
        self.publishers = self._node.count_publishers(self._topic)
        if self.publishers > 1:
            self._node.get_logger().warning(
                f"joint_states has {self.publishers} publishers: the measured pose may be any "
                f"of theirs; stop all but the driver", throttle_duration_sec=FOREIGN_WARN_PERIOD)
        return self.publishers

    def report(self) -> dict[str, int]:
        """``publishers`` of the topic as last counted (`count_publishers`), the states
        ``handed`` over directly and of them ``dropped`` untaken."""
        return {"publishers": self.publishers, "handed": self.handed, "dropped": self.dropped}

    def close(self) -> None:
        """Take nothing more (the node is being destroyed)."""
        self.closed = True
        if self._reader is not None:
            self._reader.close()
