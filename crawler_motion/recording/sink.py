"""The MCAP file of a recording: ROS 2 profile, ``ros2msg`` schemas, CDR messages, small chunks.

Messages arrive already CDR-serialised (as the middleware delivered them), so nothing is
re-encoded. Chunks are small and each is closed and written out (to the operating system) when
full or a second old, so a recording that is killed or runs out of disk keeps everything up to
its last closed chunk: `reader` and ``crawler-motion report`` read it as it is; the standard
MCAP readers need the summary it lacks, so ``crawler-motion record --recover FILE`` writes a
complete copy (`recovery`).
"""

from __future__ import annotations

import time
from collections import Counter
from pathlib import Path
from typing import BinaryIO

from mcap.writer import CompressionType, Writer

from crawler_motion.errors import RecordingError
from crawler_motion.recording.msgdefs import message_definition

#: Chunk size [bytes] and the longest a chunk stays open [s]: a killed recording loses at most
#: this much or this long.
CHUNK_SIZE = 256 * 1024
FLUSH_PERIOD = 1.0
LIBRARY = "crawler_motion recorder"


class McapSink:
    """An MCAP file open for writing; `write` one serialised message at a time."""

    def __init__(self, path: str | Path, chunk_size: int = CHUNK_SIZE) -> None:
        self.path = Path(path)
        try:
            self.stream: BinaryIO = open(self.path, "wb")
        except OSError as exc:
            raise RecordingError(f"cannot write the recording {self.path}: {exc.strerror}",
                                 path=self.path) from exc
        self.writer = Writer(self.stream, chunk_size=chunk_size,
                             compression=CompressionType.ZSTD)
        self.writer.start(profile="ros2", library=LIBRARY)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self.counts: Counter[str] = Counter()
        self.closed = False
        self._flushed = time.monotonic()

    def has_channel(self, topic: str) -> bool:
        """Whether ``topic`` has its channel already."""
        return topic in self._channels

    def channel(self, topic: str, type_name: str, metadata: dict[str, str] | None = None
                ) -> int:
        """The channel id of ``topic`` (registered with its schema and ``metadata``, such as
        ``offered_qos_profiles``, on first use)."""
        if topic not in self._channels:
            if type_name not in self._schemas:
                self._schemas[type_name] = self.writer.register_schema(
                    type_name, "ros2msg", message_definition(type_name).encode())
            self._channels[topic] = self.writer.register_channel(
                topic, "cdr", self._schemas[type_name], metadata=metadata or {})
        return self._channels[topic]

    def write(self, topic: str, type_name: str, data: bytes, log_time: int,
              publish_time: int | None = None) -> None:
        """Append one CDR message of ``topic`` received at ``log_time`` [ns since the epoch];
        a failed write (disk full) raises `RecordingError` and closes the file."""
        channel = self.channel(topic, type_name)
        try:
            self.writer.add_message(channel, log_time, data,
                                    publish_time if publish_time is not None else log_time,
                                    sequence=self.counts[topic])
            if time.monotonic() - self._flushed >= FLUSH_PERIOD:
                self._flushed = time.monotonic()
                self.writer.flush()  # closes the chunk and writes it out
                self.stream.flush()  # to the operating system: a SIGKILL cannot lose it
        except OSError as exc:
            self.abort()
            raise RecordingError(
                f"writing {self.path} failed ({exc.strerror}): recording stopped; the "
                f"{self.messages} messages up to the last closed chunk stay readable",
                path=self.path) from exc
        self.counts[topic] += 1

    @property
    def messages(self) -> int:
        """Messages written so far."""
        return sum(self.counts.values())

    def size(self) -> int:
        """Bytes in the file so far (the file's size once closed)."""
        if not self.stream.closed:
            return self.stream.tell()
        return self.path.stat().st_size if self.path.exists() else 0

    def abort(self) -> None:
        """Close the file without the summary (after a write error)."""
        if not self.stream.closed:
            try:
                self.stream.close()
            except OSError:
                pass
        self.closed = True

    def close(self) -> None:
        """Write the last chunk and the summary and close the file (idempotent)."""
        if self.closed:
            return
        try:
            self.writer.finish()
        except OSError as exc:
            self.abort()
            raise RecordingError(f"finishing {self.path} failed ({exc.strerror}); the "
                                 "chunks written before stay readable", path=self.path) from exc
        self.stream.close()
        self.closed = True
