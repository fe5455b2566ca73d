"""Racing publishers of joint_commands told from one (restarted) publisher (pure)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from crawler_motion.driver.senders import MAX_SEQUENCE_GAP, STREAM_MEMORY, SenderWatch


@pytest.mark.parametrize("sequence, conflicts", [
    ([1, 2, 3, 4], 0),
    ([1, 2, 5, 9], 0),  # lost messages
    ([1, 2, 2 + MAX_SEQUENCE_GAP], 0),  # boundary: still the same stream
    ([100, 101, 1, 2, 3], 0),  # a restarted publisher
    ([100, 101, 1, 102], 1),  # a second publisher, then the first again
    ([100, 1, 101, 2, 102], 3),  # two racing
    ([None, None, 5, None, 6], 0),  # no numbers: not checked
])
def test_conflicts(sequence, conflicts):
    watch = SenderWatch()
    for i, seq in enumerate(sequence):
        watch.note(seq, i * 0.01)
    assert watch.conflicts == conflicts


def test_old_streams_are_forgotten():
    watch = SenderWatch()
    watch.note(100, 0.0)
    watch.note(1, 0.1)
    assert not watch.note(101, STREAM_MEMORY + 1.0)  # the old stream is gone: a new one


@given(st.integers(0, 10**6), st.lists(st.integers(1, 50), max_size=200))
def test_one_publisher_never_conflicts(start, steps):
    watch = SenderWatch()
    seq = start
    for i, step in enumerate(steps):
        seq += step
        assert not watch.note(seq, i * 0.01)
