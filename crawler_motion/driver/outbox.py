"""The driver's send queue: the newest manager command and the newest joint targets."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import can


class Outbox:
    """What is still to be sent: one control command (a newer one replaces it) and the frames
    of the newest joint command, sent only while younger than one target period.

    The control command goes first; targets follow once it is out.
    """

    def __init__(self, target_period: float) -> None:
        self.target_period = target_period  # [s]
        self.control: str | None = None
        self.targets: list[can.Message] = []
        self._targets_time = 0.0
        self.last_control: tuple[str, float] | None = None  # (command, steady time [s])
        self.stale = 0  # target commands dropped unsent: older than one period, or superseded

    @property
    def empty(self) -> bool:
        """True when nothing is queued."""
        return self.control is None and not self.targets

    def put_targets(self, frames: Sequence[can.Message], now: float) -> None:
        """Queue the frames of a new joint command (an unsent older one is superseded)."""
        if self.targets:
            self.stale += 1
        self.targets = list(frames)
        self._targets_time = now

    def flush(self, now: float, send: Callable[[can.Message], bool],
              encode: Callable[[str], can.Message], motion_allowed: bool,
              on_sent: Callable[[str, float], None]) -> bool:
        """Send what is queued, in order, until the bus refuses; True when nothing is left.

        ``on_sent(command, now)`` runs for a control command that went out; targets are
        dropped when motion is not allowed or they are older than one target period.
        """
        if self.control is not None:
            command = self.control
            if not send(encode(command)):
                return False
            self.control = None
            self.last_control = (command, now)
            on_sent(command, now)
        if self.targets:
            if not motion_allowed:
                self.targets = []
                return True
            if now - self._targets_time > self.target_period:
                self.stale += 1
                self.targets = []
                return True
            while self.targets:
                if not send(self.targets[0]):
                    return False
                self.targets.pop(0)
        return True
