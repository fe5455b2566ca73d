"""Messages the recorder could not keep up with, from the publishers' sequence numbers (pure).

DDS numbers the messages of each publisher (``publication_sequence_number`` of the message
info). When the recorder falls behind, its subscription's queue (the QoS depth) drops the
oldest: the numbers it then receives skip. `SequenceGaps` follows, per topic, the recent number
streams (one per publisher, as `driver.senders` does for ``joint_commands``) and counts the
numbers skipped within a stream as dropped. A number that continues no stream starts a new one
(a new or restarted publisher) and counts nothing; a message without a number is not checked.
"""

from __future__ import annotations

from collections import Counter

#: A number continues a stream when it is at most this far above the stream's last.
MAX_GAP = 100_000
#: Streams remembered per topic (the newest).
MAX_STREAMS = 16


class SequenceGaps:
    """Dropped messages by topic (`dropped`)."""

    def __init__(self) -> None:
        self._streams: dict[str, list[int]] = {}
        self.dropped: Counter[str] = Counter()

    def note(self, topic: str, sequence: int | None) -> int:
        """One message of ``topic`` numbered ``sequence``: the messages skipped before it in
        its stream (counted in `dropped`)."""
        if not sequence:
            return 0
        streams = self._streams.setdefault(topic, [])
        best = -1
        for i, last in enumerate(streams):
            if last < sequence <= last + MAX_GAP and (best < 0 or last > streams[best]):
                best = i
        if best < 0:
            streams.append(sequence)
            del streams[:-MAX_STREAMS]
            return 0
        lost = sequence - streams[best] - 1
        streams[best] = sequence
        self.dropped[topic] += lost
        return lost

    @property
    def total(self) -> int:
        """Messages dropped on every topic."""
        return sum(self.dropped.values())
