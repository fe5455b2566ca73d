"""Who publishes ``joint_commands``: one sender, or several racing (an ERROR).

DDS numbers the messages of each publisher (``publication_sequence_number`` of rclpy's
message info). One publisher gives one rising sequence; a restarted one starts a new sequence
and never goes back to the old. Two publishers interleave: a message continues a sequence
other than the one the previous message continued. `SenderWatch` follows the recent
sequences (streams) and reports such a switch as a conflict. A message without a number (an
RMW that gives none) is not checked.
"""

from __future__ import annotations

from dataclasses import dataclass

#: A message continues a stream when its number is at most this far above the stream's last
#: (messages lost in between).
MAX_SEQUENCE_GAP = 1000
#: Streams not continued for this long are forgotten [s].
STREAM_MEMORY = 5.0


@dataclass
class _Stream:
    last: int
    time: float


class SenderWatch:
    """Streams of publication sequence numbers, and the conflicts between them."""

    def __init__(self) -> None:
        self._streams: list[_Stream] = []
        self._current: _Stream | None = None
        self.conflicts = 0
        self.last_conflict_time: float | None = None

    @property
    def streams(self) -> int:
        """Streams remembered (publishers seen recently, including restarted ones)."""
        return len(self._streams)

    def note(self, sequence: int | None, now: float) -> bool:
        """A message numbered ``sequence`` arrived at ``now`` [s]; True if it reveals a second
        publisher racing the first (counted)."""
        if sequence is None:
            return False
        self._streams = [s for s in self._streams if now - s.time <= STREAM_MEMORY]
        match = None
        for stream in self._streams:
            if stream.last < sequence <= stream.last + MAX_SEQUENCE_GAP and (
                    match is None or stream.last > match.last):
                match = stream
        if match is None:
            match = _Stream(sequence, now)
            self._streams.append(match)
            switched = False
        else:
            switched = self._current is not None and match is not self._current
            match.last, match.time = sequence, now
        self._current = match
        if switched:
            self.conflicts += 1
            self.last_conflict_time = now
        return switched
