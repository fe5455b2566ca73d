"""A ``stand`` sent before the first measured joint state: held, then started or refused (pure).

A script or an operator that sends ``stand`` right after start-up would otherwise be refused
("no measured joint_states yet") and get a robot that never stands. The planner holds such a
stand for up to `STAND_HOLD`: the first measured joint state starts it (from that measured
pose); when the hold runs out first, it is refused with the reason, and nothing starts later
by itself. Any later command replaces it.
"""

from __future__ import annotations

from crawler_motion.planner.context import Journal

#: How long a ``stand`` received before the first measured joint state is held [s].
STAND_HOLD = 1.0


class HeldStand:
    """The held ``stand``, if any: its body height [m] and when it was sent [s]."""

    def __init__(self) -> None:
        self._pending: tuple[float, float] | None = None

    @property
    def pending(self) -> bool:
        """True while a stand is held."""
        return self._pending is not None

    def hold(self, height: float, now: float, journal: Journal) -> None:
        """Hold a stand at ``height`` [m] sent at ``now`` [s]."""
        self._pending = (float(height), float(now))
        journal.event("info", f"stand held: it starts when the first measured joint_states "
                              f"arrives (up to {STAND_HOLD:g} s)")

    def clear(self) -> None:
        """Forget the held stand (a later command replaces it)."""
        self._pending = None

    def take(self, now: float, journal: Journal) -> float | None:
        """The held stand's height [m] if it is still due at ``now`` [s] (it is then no longer
        held); None if there is none or it ran out (refused with the reason)."""
        if self._pending is None or self.expire(now, journal):
            return None
        height = self._pending[0]
        self._pending = None
        return height

    def expire(self, now: float, journal: Journal) -> bool:
        """Refuse and forget a stand held longer than `STAND_HOLD` at ``now`` [s]; True if
        it did."""
        if self._pending is None or now - self._pending[1] <= STAND_HOLD:
            return False
        self._pending = None
        journal.record_refusal(f"stand refused: no measured joint_states within {STAND_HOLD:g} "
                               f"s of the command; is the driver running? send stand again",
                               now)
        return True
