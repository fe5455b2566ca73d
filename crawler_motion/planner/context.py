"""What the planner's parts share: state, held pose, body pose, pause flag and the status
journal."""

from __future__ import annotations

from typing import TYPE_CHECKING, NoReturn

import numpy as np

from crawler_motion.errors import CommandError
from crawler_motion.motion.body_pose import NEUTRAL, BodyPose
from crawler_motion.planner.state import IDLE, PlannerState

if TYPE_CHECKING:
    from crawler_motion.planner.next_slot import Slowed

#: Events kept for `Journal.pop_events` (the oldest are dropped).
MAX_EVENTS = 100


class JointTarget:
    """Joint positions [rad] and velocities [rad/s], ``(12,)`` each, in joint-name order.

    Built from arrays or from plain lists of floats (the walk's tick: its fast path computes
    lists); `positions` / `velocities` are arrays (made from the lists on first use, then
    kept), `position_list` / `velocity_list` the values as lists (what a message takes), so a
    tick that is only published never builds an array. Read-only by convention: no setters.
    """

    __slots__ = ("_p", "_pa", "_v", "_va")

    def __init__(self, positions: np.ndarray | list[float],
                 velocities: np.ndarray | list[float]) -> None:
        self._p, self._v = positions, velocities
        self._pa = positions if isinstance(positions, np.ndarray) else None
        self._va = velocities if isinstance(velocities, np.ndarray) else None

    @property
    def positions(self) -> np.ndarray:
        """Joint positions [rad] as an array."""
        if self._pa is None:
            self._pa = np.array(self._p, dtype=float)
        return self._pa

    @property
    def velocities(self) -> np.ndarray:
        """Joint velocities [rad/s] as an array."""
        if self._va is None:
            self._va = np.array(self._v, dtype=float)
        return self._va

    def position_list(self) -> list[float]:
        """Joint positions [rad] as a list of floats."""
        p = self._p
        return p.tolist() if isinstance(p, np.ndarray) else list(p)

    def velocity_list(self) -> list[float]:
        """Joint velocities [rad/s] as a list of floats."""
        v = self._v
        return v.tolist() if isinstance(v, np.ndarray) else list(v)

    def __repr__(self) -> str:
        return f"JointTarget(positions={self.positions!r}, velocities={self.velocities!r})"


class Journal:
    """Status revision and stamp, refusals and the event queue of the planner."""

    def __init__(self) -> None:
        self.revision = 0
        self.stamp = 0.0
        self.refusals = 0
        self.twist_refusals = 0  # of them, refusals of a cmd_vel twist
        self.last_refusal: str | None = None
        #: The twist (vx, vy, wz) of the last refusal of a twist beyond the walk's limits, so a
        #: navigator can tell its own twists from another publisher's.
        self.refused_twist: list[float] | None = None
        self.last_event: str | None = None
        self._events: list[tuple[str, str]] = []
        self.slowed_slots = 0  # slots planned slower than asked (`next_slot.SLOWED_SHARES`)
        self.slowed_share = 1.0  # the share of the asked stride of the walk's last slot
        self._slowed_said = False  # this walk's first slowed slot was logged

    def touch(self, now: float) -> None:
        """Mark a status change at steady time ``now`` [s]."""
        self.revision += 1
        self.stamp = float(now)

    def event(self, level: str, message: str) -> None:
        """Queue an event; ``level`` is info, warn or error."""
        self.last_event = message
        self._events.append((level, message))
        del self._events[:-MAX_EVENTS]

    def slowed(self, slowed: Slowed | None, now: float) -> None:
        """The slot planned at ``now`` [s] was slowed (``slowed``) or not (None): counted in
        the status; a walk's first slowed slot is also an event (a navigator steering along
        a wall may slow every other slot: the counter tells, not the log)."""
        share = 1.0 if slowed is None else slowed.share
        if slowed is not None:
            self.slowed_slots += 1
            if not self._slowed_said:
                self._slowed_said = True
                self.event("warn", f"slot slowed to {share:.0%} of the asked stride and turn "
                                   f"(further slowed slots of this walk are counted in "
                                   f"planner_status): {slowed.why}")
        if share != self.slowed_share or slowed is not None:
            self.touch(now)
        self.slowed_share = share

    def end_slowed(self) -> None:
        """The walk ended (or starts): no slot of it is slowed (`slowed_share` 1)."""
        self.slowed_share, self._slowed_said = 1.0, False

    def record_refusal(self, reason: str, now: float) -> None:
        """Count and report a refusal at ``now`` [s]."""
        self.last_refusal = reason
        self.refused_twist = None
        self.refusals += 1
        self.touch(now)
        self.event("warn", f"refused: {reason}")

    def refuse(self, reason: str, now: float) -> NoReturn:
        """Record a refusal and raise it as `CommandError`."""
        self.record_refusal(reason, now)
        raise CommandError(reason)

    def pop_events(self) -> list[tuple[str, str]]:
        """Events since the last call, as ``(level, message)``."""
        events, self._events = self._events, []
        return events


class PlannerContext:
    """State, the held pose, the last target, the pause flag and the journal of one planner.

    ``n_joints`` is the number of joints of the targets. ``body_pose`` is the standing body's
    pose (`body_pose.BodyPose`, relative to the standing height): set by pose moves (their
    last target's pose while one runs), neutral again after a stand or sit joint move.
    """

    def __init__(self, n_joints: int) -> None:
        self.n_joints = n_joints
        self.state: PlannerState = IDLE
        self.paused = False
        self.pause_reason = ""
        self.hold: JointTarget | None = None
        self.last_target: JointTarget | None = None
        self.body_pose: BodyPose = NEUTRAL
        self.journal = Journal()
        self.zero = np.zeros(n_joints)
        self.zero.setflags(write=False)

    def hold_pose(self, positions: np.ndarray) -> JointTarget:
        """A target holding ``positions`` [rad] still (read-only arrays)."""
        pos = np.array(positions, dtype=float).reshape(self.n_joints)
        pos.setflags(write=False)
        return JointTarget(pos, self.zero)

    def enter(self, state: PlannerState, now: float) -> None:
        """Switch to ``state`` at ``now`` [s] (a status change)."""
        self.state = state
        self.journal.touch(now)

    def set_paused(self, paused: bool, now: float, reason: str = "") -> None:
        """Pause (a motor-manager fault, ``reason``) or resume at ``now`` [s]; reported as an
        event when it changes."""
        paused = bool(paused)
        if paused == self.paused and (not paused or reason == self.pause_reason):
            return
        was = self.paused
        self.paused = paused
        self.pause_reason = reason if paused else ""
        self.journal.touch(now)
        if paused and not was:
            why = reason or "no reason given"
            self.journal.event("warn", f"paused: motor manager fault ({why}); no new gait slot "
                                       f"starts until it clears")
        elif not paused:
            self.journal.event("info", "pause cleared: motor manager OK again")

    def paused_reason(self) -> str:
        """Why a motion is refused while paused, and what to do."""
        return (f"paused: motor manager fault ({self.pause_reason or 'no reason given'}); "
                f"retry when it clears")
