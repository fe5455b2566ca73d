"""A passive bus tap: a python-can `can.Notifier` feeding `can.Listener`s that count or record."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Iterable
from typing import Any

import can

from crawler_motion.canbus.frames import FrameKind

#: The family of a frame id the protocol does not define.
OTHER = "other"
#: Frame family names: the protocol's (`FrameKind`), then `OTHER`.
FAMILIES = (*(kind.value for kind in FrameKind), OTHER)


def frame_families(protocol: Any) -> dict[int, str]:
    """Frame id -> family name (`FrameKind` value) of every frame ``protocol`` (a
    `MotorProtocol`) defines."""
    return {fid: kind.value for kind in FrameKind for fid in protocol.frame_ids(kind.value)}


class TapListener(can.Listener):
    """A listener whose receive errors are counted, not raised (the tap keeps listening)."""

    def __init__(self) -> None:
        self.errors = 0

    def on_message_received(self, msg: can.Message) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def on_error(self, exc: Exception) -> None:
        """Count a receive (or listener) error and go on."""
        self.errors += 1


class FamilyCounter(TapListener):
    """Counts the frames on the bus by family (see `FAMILIES`)."""

    def __init__(self, protocol: Any) -> None:
        super().__init__()
        self.families = frame_families(protocol)
        self.counts: Counter[str] = Counter()

    def kind(self, msg: can.Message) -> str:
        """The family of ``msg`` (`OTHER` for an id the protocol does not define)."""
        return self.families.get(msg.arbitration_id, OTHER)

    def on_message_received(self, msg: can.Message) -> None:
        self.counts[self.kind(msg)] += 1


class FrameRecorder(TapListener):
    """Keeps every frame with its receive time ``clock(msg.timestamp)`` [s]."""

    def __init__(self, clock: Callable[[float], float] = float) -> None:
        super().__init__()
        self.clock = clock
        self.frames: list[tuple[float, can.Message]] = []

    def on_message_received(self, msg: can.Message) -> None:
        self.frames.append((self.clock(msg.timestamp), msg))


def end_child(proc: Any, stop: Any, grace: float = 2.0) -> None:
    """Ask a listener child process to stop (``stop``: its multiprocessing Event), wait
    ``grace`` [s], then kill it if it still runs."""
    stop.set()
    proc.join(grace)
    if proc.is_alive():
        proc.kill()
        proc.join(grace)


def wall_to_monotonic(wall: float) -> float:
    """A system-clock time [s] (kernel receive stamps, ROS header stamps) on the monotonic
    clock, so scheduling delays of a busy observer do not enter measured times."""
    return wall - (time.time() - time.monotonic())


class BusTap:
    """A bus and the `can.Notifier` that feeds its frames to ``listeners`` in a thread; `stop`
    ends both (idempotent)."""

    def __init__(self, bus: Any, listeners: Iterable[can.Listener],
                 timeout: float = 0.05) -> None:
        self.bus = bus
        self.listeners = list(listeners)
        self._notifier: can.Notifier | None = can.Notifier(bus, self.listeners, timeout=timeout)

    def stop(self) -> None:
        """Stop listening and close the bus."""
        if self._notifier is None:
            return
        self._notifier.stop(timeout=2.0)
        self._notifier = None
        self.bus.shutdown()

    def __enter__(self) -> BusTap:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
