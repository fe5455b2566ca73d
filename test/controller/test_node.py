"""Tests of crawler_motion.controller.node: the direct hand-over from the planner's tick to the
driver. (The composed process runs the end-to-end and safety tests of test/system.)"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rclpy")

from builtin_interfaces.msg import Time
from sensor_msgs.msg import JointState

from crawler_motion.controller.node import (
    LOCAL_SEQUENCE_BASE,
    OWN_STAMPS,
    DirectLink,
    link_measured,
)
from crawler_motion.driver.senders import MAX_SEQUENCE_GAP, SenderWatch
from crawler_motion.planner.context import JointTarget

NAMES = [f"j{i}" for i in range(12)]


class Input:
    """The driver's `CommandInput`: records what it is given; accepts unless told not to."""

    def __init__(self) -> None:
        self.calls: list[tuple[Any, ...]] = []
        self.accept = True

    def submit(self, *args: Any) -> bool:
        self.calls.append(args)
        return self.accept


def _target(value: float) -> JointTarget:
    return JointTarget(np.full(12, value), np.full(12, 0.1))


def _link() -> tuple[DirectLink, Input]:
    inp = Input()
    return DirectLink(SimpleNamespace(commands=inp), NAMES), inp  # type: ignore[arg-type]


def test_each_tick_is_submitted_with_its_own_rising_sequence() -> None:
    link, inp = _link()
    link.hand_over(_target(0.5), Time(sec=1, nanosec=2))
    inp.accept = False
    link.hand_over(_target(0.6), Time(sec=1, nanosec=3))
    names, positions, velocities, efforts, sequence = inp.calls[0]
    assert names == NAMES and positions == [0.5] * 12 and velocities == [0.1] * 12
    assert efforts == () and sequence == LOCAL_SEQUENCE_BASE + 1
    assert inp.calls[1][4] == LOCAL_SEQUENCE_BASE + 2
    assert (link.handed, link.accepted) == (2, 1)


def test_its_own_messages_are_recognised_by_their_stamps_others_are_not() -> None:
    link, _ = _link()
    for n in range(OWN_STAMPS + 1):
        link.hand_over(_target(0.0), Time(sec=5, nanosec=n))
    own = JointState()
    own.header.stamp = Time(sec=5, nanosec=OWN_STAMPS)
    oldest = JointState()
    oldest.header.stamp = Time(sec=5, nanosec=0)  # forgotten: beyond OWN_STAMPS
    other = JointState()
    other.header.stamp = Time(sec=5, nanosec=OWN_STAMPS + 7)
    assert link.is_own(own) and not link.is_own(oldest) and not link.is_own(other)


def test_a_publisher_racing_the_hand_over_is_a_conflict_for_the_sender_watch() -> None:
    """The hand-over's numbers never continue a DDS publisher's stream, nor the reverse."""
    watch = SenderWatch()
    ours = [LOCAL_SEQUENCE_BASE + n for n in range(1, 5)]
    assert not any(watch.note(seq, 0.01 * i) for i, seq in enumerate(ours))
    assert not watch.note(3, 0.05)  # a DDS publisher appears: a new stream
    assert watch.note(LOCAL_SEQUENCE_BASE + 5, 0.06)  # and the two interleave
    assert LOCAL_SEQUENCE_BASE > MAX_SEQUENCE_GAP * 1e6


class Measured:
    """The planner's `MeasuredInput`: records the composition and what is handed over."""

    def __init__(self) -> None:
        self.own: Any = None
        self.handed: list[JointState] = []

    def compose(self, own_state: Any) -> None:
        self.own = own_state

    def hand_over(self, msg: JointState) -> None:
        self.handed.append(msg)


def _state(nanosec: int) -> JointState:
    msg = JointState()
    msg.header.stamp = Time(sec=9, nanosec=nanosec)
    return msg


def test_each_joint_state_published_goes_to_the_planner_which_skips_it_on_the_topic() -> None:
    driver = SimpleNamespace(on_joint_state=None)
    planner = SimpleNamespace(measured=Measured())
    link_measured(driver, planner)  # type: ignore[arg-type]
    sent = [_state(n) for n in range(OWN_STAMPS + 1)]
    for msg in sent:
        driver.on_joint_state(msg)
    assert planner.measured.handed == sent
    own = planner.measured.own
    assert own(_state(OWN_STAMPS)) and not own(_state(0))  # the oldest is forgotten
    assert not own(_state(OWN_STAMPS + 5))  # another publisher's
