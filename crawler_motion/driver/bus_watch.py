"""What the driver sees on the bus that it did not send: foreign target and control frames.

CAN has no sender address: a frame with the driver's own ids may come from the driver (looped
back by ``udp_multicast``), from a second controller or from an attacker. `BusWatch` keeps
the frames the driver sent during the last `SENT_WINDOW` and calls any other valid
controller-side frame foreign (an invalid one is dropped as garbage: the manager drops it
too). Each foreign frame, and each conflict reported by the feedback (two different frames
with the same counter), raises an alarm that keeps the driver's status at ERROR for
`ALARM_HOLD` after the last one. Everything is counted.
"""

from __future__ import annotations

from collections import deque

import can

#: Own frames are recognised in their loop-back for this long after sending [s].
SENT_WINDOW = 0.5
#: An alarm keeps the status at ERROR (the planner paused) this long after the last one [s].
ALARM_HOLD = 2.0
#: Own frames remembered at most (a flood of sends cannot grow the memory).
MAX_SENT = 4096


class BusWatch:
    """Own frames sent, foreign frames seen, alarms (steady times [s])."""

    def __init__(self, target_ids: frozenset[int], control_ids: frozenset[int]) -> None:
        self.target_ids, self.control_ids = target_ids, control_ids
        self._sent: deque[tuple[float, int, bytes]] = deque(maxlen=MAX_SENT)
        self.counts = dict.fromkeys(("foreign_targets", "foreign_controls", "rx_conflicts"), 0)
        self.last_alarm = ""
        self.alarm_time: float | None = None

    def sent(self, msg: can.Message, now: float) -> None:
        """The driver sent ``msg`` at ``now``."""
        self._sent.append((now, msg.arbitration_id, bytes(msg.data)))

    def own(self, msg: can.Message, now: float) -> bool:
        """True if a controller-side frame received at ``now`` is the loop-back of one the
        driver sent (each sent frame matches once)."""
        while self._sent and now - self._sent[0][0] > SENT_WINDOW:
            self._sent.popleft()
        key = (msg.arbitration_id, bytes(msg.data))
        for i, (_, fid, data) in enumerate(self._sent):
            if (fid, data) == key:
                del self._sent[i]
                return True
        return False

    def foreign(self, msg: can.Message, now: float) -> None:
        """A valid target or control frame the driver did not send: counted and alarmed."""
        kind = "target" if msg.arbitration_id in self.target_ids else "control"
        self.counts[f"foreign_{kind}s"] += 1
        self.alarm(f"foreign {kind} frame 0x{msg.arbitration_id:03X} "
                   f"({bytes(msg.data).hex()}) on the bus: another controller or an attacker",
                   now)

    def conflict(self, text: str, now: float) -> None:
        """Two different frames claimed the same counter (see `feedback.Feedback`)."""
        self.counts["rx_conflicts"] += 1
        self.alarm(text, now)

    def alarm(self, text: str, now: float) -> None:
        """Raise an alarm at ``now`` [s]."""
        self.last_alarm = text
        self.alarm_time = now

    def active_alarm(self, now: float) -> str:
        """The last alarm while it is younger than `ALARM_HOLD`, else ""."""
        if self.alarm_time is None or now - self.alarm_time > ALARM_HOLD:
            return ""
        return f"{self.last_alarm} ({now - self.alarm_time:.1f} s ago)"
