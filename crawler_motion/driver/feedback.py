"""Decoding the manager's frames into joint positions and efforts, axis flags and the last
heartbeat."""

from __future__ import annotations

import can
import numpy as np

from crawler_motion.canbus.protocol import (
    AxisFlags,
    AxisStatus,
    EffortFeedback,
    Heartbeat,
    MotorProtocol,
    PositionFeedback,
)
from crawler_motion.driver.bus_watch import BusWatch


class Feedback:
    """What the manager reported: positions, efforts, per-axis flags, the heartbeat (steady
    times [s]).

    `handle` emits a joint-state vector (joint order [rad]) once every position group has been
    received since the last one, so each vector is one complete, fresh measurement. With it go
    the joint efforts (joint order [N m]) when every effort group was received since the last
    vector too (the manager sends them before the positions of a cycle), else an empty array:
    a missing or incomplete effort set is never filled in. Position, effort, status and
    heartbeat frames whose counter repeats the previous one of their group are
    dropped (a heartbeat whose counter does not advance is no sign of life): as
    stale when identical, as a conflict (two senders claiming one counter: an attack, alarmed
    on ``watch``) when they differ. Undecodable frames are dropped; controller-side frames go
    to ``watch`` (own loop-back or foreign); all counted.
    """

    def __init__(self, protocol: MotorProtocol, watch: BusWatch) -> None:
        self.protocol = protocol
        self.watch = watch
        self._index = {name: i for i, name in enumerate(protocol.joint_names)}
        self._position_groups = len(protocol.frame_ids("position"))
        self._effort_groups = len(protocol.frame_ids("effort"))
        self.counts = dict.fromkeys(("rx", "rx_dropped", "rx_ignored", "feedback"), 0)
        self.last_rx_error = ""
        self.reset()

    def reset(self) -> None:
        """Forget everything received (a new bus)."""
        self.positions = np.full(self.protocol.n_axes, np.nan)
        self.efforts = np.full(self.protocol.n_axes, np.nan)  # latest per joint [N m]
        self._fresh: set[int] = set()
        self._fresh_efforts: set[int] = set()
        self.effort_time: float | None = None  # last complete effort set
        # (frame type, group) -> (counter, data) of the last frame taken
        self._last_counter: dict[tuple[type, int], tuple[int, bytes]] = {}
        self.position_time: float | None = None
        self.flags: dict[int, AxisFlags] = {}
        self.flags_time: dict[int, float] = {}
        self.heartbeat: Heartbeat | None = None
        self.heartbeat_time: float | None = None
        # when the receiver last took every pending frame off the bus: a heartbeat that was
        # not heard while the driver was not listening (its process stalled) is not missing
        self.listened: float | None = None

    def handle(self, msg: can.Message, now: float
               ) -> tuple[Heartbeat | None, tuple[np.ndarray, np.ndarray] | None]:
        """Take one received frame: (the heartbeat it was, the (positions, efforts) it
        completed; efforts empty when not all of them came since the last vector)."""
        self.counts["rx"] += 1
        controller = self.protocol.sender(msg) == "controller"
        if controller and self.watch.own(msg, now):
            self.counts["rx_ignored"] += 1  # our own loop-back: not decoded
            return None, None
        try:
            frame = self.protocol.decode(msg)
        except Exception as exc:  # ProtocolError, or a malformed Message object
            return self._drop(str(exc))
        if controller:  # valid, and not ours: another controller or an attacker
            self.watch.foreign(msg, now)
            return None, None
        if isinstance(frame, (PositionFeedback, EffortFeedback, AxisStatus, Heartbeat)):
            key, data = (type(frame), getattr(frame, "group", 0)), bytes(msg.data)
            last = self._last_counter.get(key)
            if last is not None and last[0] == frame.counter:
                what = f"{type(frame).__name__} group {key[1]}: counter {frame.counter}"
                if last[1] != data:  # two senders claim the counter: neither is trusted
                    self.watch.conflict(f"{what} sent twice with different data (a forged "
                                        f"frame on the bus)", now)
                    return self._drop(f"{what} conflicting")
                return self._drop(f"{what} repeated (stale frame)")  # stuck sender or replay
            self._last_counter[key] = (frame.counter, data)
        if isinstance(frame, PositionFeedback):
            return None, self._positions(frame, now)
        if isinstance(frame, EffortFeedback):
            for joint, value in frame.efforts.items():
                self.efforts[self._index[joint]] = value
            self._fresh_efforts.add(frame.group)
        if isinstance(frame, AxisStatus):
            for axis, flags in frame.axes.items():
                self.flags[axis] = flags
                self.flags_time[axis] = now
        elif isinstance(frame, Heartbeat):
            self.heartbeat = frame
            self.heartbeat_time = now
            return frame, None
        return None, None

    def _drop(self, reason: str) -> tuple[None, None]:
        self.counts["rx_dropped"] += 1
        self.last_rx_error = reason
        return None, None

    def _positions(self, frame: PositionFeedback, now: float
                   ) -> tuple[np.ndarray, np.ndarray] | None:
        for joint, value in frame.positions.items():
            self.positions[self._index[joint]] = value
        self._fresh.add(frame.group)
        if len(self._fresh) < self._position_groups:
            return None
        self._fresh.clear()
        self.position_time = now
        self.counts["feedback"] += 1
        efforts = np.empty(0)
        if self._effort_groups and len(self._fresh_efforts) == self._effort_groups:
            efforts = self.efforts.copy()
            self.effort_time = now
        self._fresh_efforts.clear()
        return self.positions.copy(), efforts
