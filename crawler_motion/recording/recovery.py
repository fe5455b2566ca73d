"""A recording cut short (SIGKILL, power loss, full disk) made whole again.

A killed recording has no summary and no footer, and ends inside a record: the standard MCAP
readers fail on it (the seeking reader reads garbage as the footer; the streaming one, in log
time order, raises at the cut before yielding anything), although its closed chunks hold the
messages. `recover` streams the file from its start in file order (as `reader` does), keeps
every message before the damage with its schema, channel and metadata, and writes them to a
new, complete MCAP file that the standard readers open.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from mcap.reader import NonSeekingReader
from mcap.writer import CompressionType, Writer

from crawler_motion.errors import RecordingError
from crawler_motion.recording.reader import READ_ERRORS
from crawler_motion.recording.sink import CHUNK_SIZE, LIBRARY


@dataclass(frozen=True)
class Recovered:
    """What `recover` kept: messages written, and what stopped the reading (None: intact)."""

    output: Path
    messages: int
    damage: str | None


def recovered_path(source: Path) -> Path:
    """The default output of ``source``: ``<stem>.recovered.mcap`` beside it."""
    return source.with_name(f"{source.stem}.recovered.mcap")


def recover(source: str | Path, output: str | Path | None = None) -> Recovered:
    """Copy every readable message of ``source`` into ``output`` (default `recovered_path`),
    a complete MCAP file. `RecordingError` when ``source`` cannot be read, holds no readable
    message, or ``output`` cannot be written (a half-written output is removed)."""
    src = Path(source)
    dst = Path(output) if output is not None else recovered_path(src)
    if dst.resolve() == src.resolve():
        raise RecordingError(f"recovering {src} onto itself: give another output", path=src)
    try:
        stream, out = open(src, "rb"), open(dst, "wb")
    except OSError as exc:
        raise RecordingError(f"cannot recover {src} into {dst}: {exc.strerror}",
                             path=src) from exc
    try:
        with stream, out:
            count, damage = _copy(stream, out)
    except OSError as exc:
        dst.unlink(missing_ok=True)
        raise RecordingError(f"writing {dst} failed: {exc.strerror}", path=dst) from exc
    if not count:
        dst.unlink(missing_ok=True)
        raise RecordingError(f"{src} holds no readable message ({damage})", path=src)
    return Recovered(dst, count, damage)


def _copy(stream: BinaryIO, out: BinaryIO) -> tuple[int, str | None]:
    """Messages of ``stream`` into a new MCAP ``out``: (messages, damage or None)."""
    writer = Writer(out, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
    writer.start(profile="ros2", library=LIBRARY)
    schemas: dict[int, int] = {}
    channels: dict[int, int] = {}
    count, damage = 0, None
    try:
        reader = NonSeekingReader(stream, validate_crcs=True)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if channel.id not in channels:
                sid = 0
                if schema is not None:
                    if schema.id not in schemas:
                        schemas[schema.id] = writer.register_schema(
                            schema.name, schema.encoding, schema.data)
                    sid = schemas[schema.id]
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, sid, dict(channel.metadata))
            writer.add_message(channels[channel.id], message.log_time, message.data,
                               message.publish_time, message.sequence)
            count += 1
    except READ_ERRORS as exc:
        if isinstance(exc, OSError) and exc.errno is not None:
            raise
        damage = " ".join(str(exc).split()) or type(exc).__name__
    writer.finish()
    return count, damage
