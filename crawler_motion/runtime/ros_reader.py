"""A subscription read by a thread of its own, outside the node's executor.

rclpy's executor rebuilds its wait set from every entity of its nodes (subscriptions, timers,
the lifecycle and parameter services, the QoS event handlers) before each callback it runs: for
the driver, ~20 entities and ~0.5 ms of CPU per joint command at 500 Hz, more than the command's
own work (the executor cost of ros2/rclcpp#1637, larger in Python). `SubscriptionReader` keeps
the subscription on the node (the graph, remappings, QoS and ``ros2 topic info`` are unchanged)
but in a callback group that the executor never schedules, and takes its messages in a thread
waiting on a wait set of just that subscription, as ``rclpy.wait_for_message`` does.

The callback runs in the reader's thread: it must be thread-safe with the node's other
callbacks. It receives ``(message, info)``, ``info`` being rclpy's message-info dict
(``publication_sequence_number``, ``source_timestamp``, ...). With ``when`` the reader takes
messages only while ``when()`` is true (asked every `GATE_PERIOD` and after each message):
meanwhile the subscription keeps its newest messages (its QoS depth) and costs nothing.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from rclpy.callback_groups import CallbackGroup
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile

#: Longest wait of the reader before it looks at its stop flag and the context again [ns].
WAIT_TIMEOUT_NS = 200_000_000
#: Messages taken per wake-up at most (a flood cannot keep the thread from stopping).
MAX_TAKES_PER_WAKE = 100
#: Period of asking ``when()`` while it is false [ns].
GATE_PERIOD_NS = 100_000_000


class Unscheduled(CallbackGroup):
    """A callback group whose entities no executor runs (a `SubscriptionReader` takes them)."""

    def can_execute(self, entity: Any) -> bool:
        """Never: the executor leaves the entity out of its wait set."""
        return False

    def beginning_execution(self, entity: Any) -> bool:
        """Never."""
        return False

    def ending_execution(self, entity: Any) -> None:
        """Nothing to release."""


class SubscriptionReader:
    """``callback(message, info)`` for every message of ``topic``, from a daemon thread.

    `start` starts the thread; `stop` (also from `close`) ends it; `close` destroys the
    subscription. ``on_error(text)`` receives a callback's exception (the reader goes on).
    """

    def __init__(self, node: Node, msg_type: type, topic: str, qos: QoSProfile | int,
                 callback: Callable[[Any, dict[str, Any]], None], *,
                 on_error: Callable[[str], None], name: str = "ros-reader",
                 when: Callable[[], bool] | None = None) -> None:
        self._node = node
        self._when = when
        self._callback = callback
        self._on_error = on_error
        self.subscription = node.create_subscription(msg_type, topic, _never, qos,
                                                     callback_group=Unscheduled())
        self._wake = GuardCondition(None, None, context=node.context)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    @property
    def running(self) -> bool:
        """True while the thread runs."""
        return self._thread.is_alive()

    def start(self) -> None:
        """Start taking messages."""
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the thread and wait up to ``timeout`` [s] for it."""
        self._stop.set()
        try:
            self._wake.trigger()
        except Exception:  # the context is already shut down: the thread ends by its timeout
            pass
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    def close(self) -> None:
        """Stop the thread, then destroy the subscription and the wake-up condition."""
        self.stop()
        self._node.destroy_subscription(self.subscription)
        self._wake.destroy()

    def _run(self) -> None:
        sub, context = self.subscription, self._node.context
        try:
            with context.handle:
                wait_set = _rclpy.WaitSet(1, 1, 0, 0, 0, 0, context.handle)
            while not self._stop.is_set() and context.ok():
                taking = self._when is None or self._when()
                with sub.handle, self._wake.handle:
                    wait_set.clear_entities()
                    if taking:
                        wait_set.add_subscription(sub.handle)
                    wait_set.add_guard_condition(self._wake.handle)
                    wait_set.wait(WAIT_TIMEOUT_NS if taking else GATE_PERIOD_NS)
                    ready = taking and (
                        sub.handle.pointer in wait_set.get_ready_entities("subscription"))
                if ready and not self._stop.is_set():
                    self._take_all(sub)
        except Exception as exc:  # shutdown races end the thread quietly; others are reported
            if not self._stop.is_set() and context.ok():
                self._on_error(f"reader of {sub.topic_name} stopped: "
                               f"{type(exc).__name__}: {exc}")

    def _take_all(self, sub: Any) -> None:
        for _ in range(MAX_TAKES_PER_WAKE):
            with sub.handle:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
            if taken is None:
                return
            try:
                self._callback(*taken)
            except Exception as exc:  # one bad message must not end the reader
                self._on_error(f"{sub.topic_name} callback failed: {type(exc).__name__}: {exc}")
            if self._when is not None and not self._when():
                return  # the rest wait in the subscription's queue


def _never(*_args: Any) -> None:
    """The subscription's executor callback, never run (its group is `Unscheduled`)."""
