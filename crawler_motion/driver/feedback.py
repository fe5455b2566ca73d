"""Decoding the manager's frames into joint positions, axis flags and the last heartbeat."""

from __future__ import annotations

import can
import numpy as np

from crawler_motion.canbus.protocol import (
    AxisFlags,
    AxisStatus,
    Heartbeat,
    MotorProtocol,
    PositionFeedback,
)


class Feedback:
    """What the manager reported: positions, per-axis flags, the heartbeat (steady times [s]).

    `handle` emits a joint-state vector (joint order [rad]) once every position group has been
    received since the last one, so each vector is one complete, fresh measurement. Position
    and status frames whose counter repeats the previous one of their group are stale and
    dropped; undecodable frames are dropped; controller-side frames are ignored; all counted.
    """

    def __init__(self, protocol: MotorProtocol) -> None:
        self.protocol = protocol
        self._index = {name: i for i, name in enumerate(protocol.joint_names)}
        self._position_groups = len(protocol.frame_ids("position"))
        self.counts = dict.fromkeys(("rx", "rx_dropped", "rx_ignored", "feedback"), 0)
        self.last_rx_error = ""
        self.reset()

    def reset(self) -> None:
        """Forget everything received (a new bus)."""
        self.positions = np.full(self.protocol.n_axes, np.nan)
        self._fresh: set[int] = set()
        self._last_counter: dict[tuple[type, int], int] = {}  # (frame type, group) -> counter
        self.position_time: float | None = None
        self.flags: dict[int, AxisFlags] = {}
        self.flags_time: dict[int, float] = {}
        self.heartbeat: Heartbeat | None = None
        self.heartbeat_time: float | None = None

    def handle(self, msg: can.Message, now: float) -> tuple[Heartbeat | None, np.ndarray | None]:
        """Take one received frame: (the heartbeat it was, the vector it completed)."""
        self.counts["rx"] += 1
        if self.protocol.sender(msg) == "controller":
            self.counts["rx_ignored"] += 1  # our own echo or another controller: not decoded
            return None, None
        try:
            frame = self.protocol.decode(msg)
        except Exception as exc:  # ProtocolError, or a malformed Message object
            return self._drop(str(exc))
        if isinstance(frame, (PositionFeedback, AxisStatus)):
            key = (type(frame), frame.group)
            if self._last_counter.get(key) == frame.counter:  # stuck sender or replay
                return self._drop(f"{type(frame).__name__} group {frame.group}: counter "
                                  f"{frame.counter} repeated (stale frame)")
            self._last_counter[key] = frame.counter
        if isinstance(frame, PositionFeedback):
            return None, self._positions(frame, now)
        if isinstance(frame, AxisStatus):
            for axis, flags in frame.axes.items():
                self.flags[axis] = flags
                self.flags_time[axis] = now
        elif isinstance(frame, Heartbeat):
            self.heartbeat = frame
            self.heartbeat_time = now
            return frame, None
        else:  # a target or control frame: our own echo or another controller
            self.counts["rx_ignored"] += 1
        return None, None

    def _drop(self, reason: str) -> tuple[None, None]:
        self.counts["rx_dropped"] += 1
        self.last_rx_error = reason
        return None, None

    def _positions(self, frame: PositionFeedback, now: float) -> np.ndarray | None:
        for joint, value in frame.positions.items():
            self.positions[self._index[joint]] = value
        self._fresh.add(frame.group)
        if len(self._fresh) < self._position_groups:
            return None
        self._fresh.clear()
        self.position_time = now
        self.counts["feedback"] += 1
        return self.positions.copy()
