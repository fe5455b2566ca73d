"""The CAN log of a run: every frame on the bus in python-can's own log format.

A listener on the recorder's own connection to the bus (so it sees both directions: driver to
manager and back) feeds a `can.Logger` through a `can.Notifier`; the file's suffix picks the
format (``.log`` candump, ``.asc``, ``.blf``), which `can.LogReader` / ``canplayer`` replay.
"""

from __future__ import annotations

from pathlib import Path

import can

from crawler_motion.canbus.bus import open_bus
from crawler_motion.errors import RecordingError

#: File suffixes python-can writes and replays.
LOG_SUFFIXES = (".log", ".asc", ".blf")


class FrameCounter(can.Listener):
    """Counts the frames logged."""

    def __init__(self) -> None:
        self.frames = 0

    def on_message_received(self, msg: can.Message) -> None:
        """Count one frame."""
        self.frames += 1


class CanLog:
    """A bus connection logging every frame to ``path`` until `close`."""

    def __init__(self, path: str | Path, interface: str, channel: str, port: int = 0) -> None:
        self.path = Path(path)
        if self.path.suffix not in LOG_SUFFIXES:
            raise RecordingError(f"CAN log {self.path}: the suffix must be one of "
                                 f"{', '.join(LOG_SUFFIXES)} (candump, ASC, BLF)", path=path)
        try:
            self.writer = can.Logger(str(self.path))
        except OSError as exc:
            raise RecordingError(f"cannot write the CAN log {self.path}: {exc.strerror}",
                                 path=path) from exc
        try:
            self.bus = open_bus(interface, channel, port)
        except Exception:
            self.writer.stop()
            raise
        self.counter = FrameCounter()
        self.notifier = can.Notifier(self.bus, [self.writer, self.counter], timeout=0.1)

    def close(self) -> None:
        """Stop listening, flush and close the log, close the bus."""
        self.notifier.stop()
        self.writer.stop()
        self.bus.shutdown()
