"""Reading a recording back: every readable message of an MCAP file, decoded, by topic.

The file is streamed from its start (no index needed), so a recording that was killed or is
truncated yields the messages before the damage; the damage itself is reported, not raised.
"""

from __future__ import annotations

import struct
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader
from mcap_ros2.decoder import DecoderFactory

from crawler_motion.errors import RecordingError

#: What a damaged file raises while it is streamed.
READ_ERRORS = (McapError, EOFError, ValueError, KeyError, IndexError, OSError, TypeError,
               AssertionError, struct.error)


@dataclass
class Recording:
    """The decoded messages of a recording: topic -> [(log time [ns], message)], the schema
    names by topic, ``damage`` (what stopped the reading) when the file is not intact, and what
    was computed from the messages once (``derived``, by name)."""

    path: Path
    messages: dict[str, list[tuple[int, Any]]] = field(default_factory=lambda: defaultdict(list))
    types: dict[str, str] = field(default_factory=dict)
    damage: str | None = None
    derived: dict[str, Any] = field(default_factory=dict)  # computed once by name (the mosaic)

    @property
    def count(self) -> int:
        """Messages read."""
        return sum(len(m) for m in self.messages.values())

    def start(self) -> int:
        """Log time of the first message [ns] (0 when empty)."""
        return min((m[0][0] for m in self.messages.values() if m), default=0)

    def duration(self) -> float:
        """Time from the first to the last message [s]."""
        last = max((m[-1][0] for m in self.messages.values() if m), default=0)
        return max(0.0, (last - self.start()) * 1e-9)

    def topic(self, name: str) -> list[tuple[int, Any]]:
        """The messages of ``name`` (``/name`` too), empty when not recorded."""
        return self.messages.get(name) or self.messages.get(f"/{name.lstrip('/')}", [])


def read_recording(path: str | Path) -> Recording:
    """Every readable message of ``path``; an unreadable file (nothing decodable, not MCAP)
    raises `RecordingError` naming it."""
    path = Path(path)
    out = Recording(path)
    try:
        stream = open(path, "rb")
    except OSError as exc:
        raise RecordingError(f"cannot read {path}: {exc.strerror}", path=path) from exc
    with stream:
        try:
            reader = NonSeekingReader(stream, validate_crcs=True,
                                      decoder_factories=[DecoderFactory()])
            for schema, channel, message, decoded in reader.iter_decoded_messages(
                    log_time_order=False):  # file order: keeps what precedes damage
                out.types[channel.topic] = schema.name if schema else ""
                out.messages[channel.topic].append((message.log_time, decoded))
        except READ_ERRORS as exc:
            detail = " ".join(str(exc).split()) or type(exc).__name__
            if not out.count:
                raise RecordingError(f"{path} is not a readable MCAP recording: {detail}",
                                     path=path) from exc
            out.damage = f"{path} is damaged after {out.count} readable messages: {detail}"
    return out
