"""``crawler-motion soak --mission FILE``: missions on the simulated real-time stack for a set
time, with faults injected from a seeded plan, each checked.

The stack is ``crawler-motion sim --split`` (the planner and the driver as two processes, so
each can be hit alone) with the recorder. The mission is sent, sent again when it is done (a
fresh id), and after every fault that ended it. The faults (`fault_plan`): SIGKILL and restart
of the mapper, the navigator, the planner and the driver; SIGSTOP of each for 1-3 s; CAN
garbage bursts; an e-stop; a future-stamped odometry message; a flood of refused goals. After
every fault the soak checks, from the simulator's ``odom`` (the body's true motion):

- **hold**: the body is still (moves < `STILL` over `STILL_WINDOW`) within the fault's stated
  time (`fault_plan.expectation`);
- **no motion during the fault**: from that time to the fault's end the body moves less than
  `MOTION_TOLERANCE`;
- **recovery** by the documented path (`fault_plan.Recovery`): the mission runs again and the
  body walks (`RESUMED` m) within `RECOVERY_TIMEOUT`;
- faults that must not stop the robot (future odometry, refused goals, CAN garbage): the mission
  is not failed by them and the map keeps being fused.

At the end: hull or leg contacts (the simulator's counts: with an obstacle, and in all with
the seabed too, the first of each named), RSS per process over time, and the
recording opened with ``mcap``'s reader and with ``rosbags``. Report and exit status in
`mission_soak_report`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from crawler_motion.tools.fault_inject import Injector, rss_by_process
from crawler_motion.tools.fault_plan import Fault, FaultKind, Recovery, expectation
from crawler_motion.tools.live_nav import LiveNav
from crawler_motion.tools.procstat import rss_mb

#: The body is still when it moves less than this [m] over `STILL_WINDOW` [s].
STILL, STILL_WINDOW = 0.003, 0.5
#: Largest body motion allowed while a fault that holds is active, after the hold [m].
MOTION_TOLERANCE = 0.01
#: A recovered mission walks this far [m] within `RECOVERY_TIMEOUT` [s] of the recovery.
RESUMED, RECOVERY_TIMEOUT = 0.03, 90.0
#: Before an operator's recovery the soak waits this long [s] for a walk that resumes by
#: itself (a pause that clears: docs/safety.md "After a fault").
AUTO_WAIT = 3.0
#: How long a killed process stays dead (and an e-stop is left latched) beyond its fault's
#: hold time [s]; a restarted process gets `SETTLE` [s] before the recovery (as an operator
#: reads the status first).
DEAD_FOR, SETTLE = 1.5, 3.0
#: Before a fault the body must be walking (moved `WALKING` [m] over the last second); the soak
#: waits up to `WALK_WAIT` [s] for it.
WALKING, WALK_WAIT = 0.01, 60.0
#: How long a fault that must not stop the robot is watched [s].
WATCH_FOR = 6.0
#: RSS sampling period [s].
RSS_PERIOD = 15.0


@dataclass
class FaultRecord:
    """What one fault did: when (soak time [s]), the hold time [s] (None: never still), the
    motion while it was active after the hold [m], the recovery's time [s] (None: failed)."""

    name: str
    at: float
    length: float
    hold: bool
    hold_within: float
    held_after: float | None = None
    moved: float = 0.0
    recovery: str = ""
    recovered_after: float | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """Every check of the fault passed."""
        held = not self.hold or (self.held_after is not None
                                 and self.held_after <= self.hold_within)
        return held and self.moved <= MOTION_TOLERANCE and self.recovered_after is not None


@dataclass
class SoakResult:
    """The soak's records, RSS samples (soak time [s], {name@pid: MB}), contact count, the
    missions done and the unexpected mission failures (between faults)."""

    faults: list[FaultRecord] = field(default_factory=list)
    rss: list[tuple[float, dict[str, float]]] = field(default_factory=list)
    contacts: int = 0  # hull or leg contact ticks, the seabed included
    obstacle_contacts: int = 0  # of them, with an obstacle (a collision)
    first_contacts: str = ""
    missions_done: int = 0
    unexpected: list[str] = field(default_factory=list)
    duration: float = 0.0


class MissionFeed:
    """The soak's mission file, sent again and again with a fresh id."""

    def __init__(self, text: str) -> None:
        self.tree = yaml.safe_load(text)
        self.count = 0

    def next(self) -> str:
        """The mission's text with the id ``soak-<n>``."""
        self.count += 1
        return yaml.safe_dump({**self.tree, "id": f"soak-{self.count}"}, sort_keys=False)

    @property
    def id(self) -> str:
        """The id of the mission sent last."""
        return f"soak-{self.count}"


def still_after(path: np.ndarray, t0: float, end: float) -> float | None:
    """The first time after ``t0`` [s] from which the body (``path`` rows t, x, y) stays within
    `STILL` for `STILL_WINDOW` (checked up to ``end``), as seconds after ``t0``; None if never."""
    rows = path[(path[:, 0] >= t0) & (path[:, 0] <= end)]
    for i in range(len(rows)):
        window = rows[(rows[:, 0] >= rows[i, 0]) & (rows[:, 0] <= rows[i, 0] + STILL_WINDOW)]
        if window[-1, 0] - rows[i, 0] < 0.8 * STILL_WINDOW:
            return None
        if np.hypot(*(window[:, 1:] - rows[i, 1:]).T).max() < STILL:
            return float(rows[i, 0] - t0)
    return None


def motion(path: np.ndarray, a: float, b: float) -> float:
    """Largest distance [m] of the body from where it was at ``a`` over ``[a, b]``."""
    rows = path[(path[:, 0] >= a) & (path[:, 0] <= b)]
    if len(rows) < 2:
        return 0.0
    return float(np.hypot(*(rows[:, 1:] - rows[0, 1:]).T).max())


class MissionSoak:
    """One soak run on a started `LiveNav` (``split``, recorded)."""

    def __init__(self, nav: LiveNav, mission: str, seed: int,
                 say: Callable[[str], None] = print) -> None:
        self.nav, self.feed, self.say = nav, MissionFeed(mission), say
        self.inj = Injector(nav.sup, nav.options.bus, nav.env, nav.node, seed)
        self.result = SoakResult()
        self.began = time.monotonic()
        self._rss_at = -RSS_PERIOD

    def now(self) -> float:
        """Soak time [s]."""
        return time.monotonic() - self.began

    def path(self) -> np.ndarray:
        w = self.nav.watch
        with w.lock:
            return np.array(w.path) if w.path else np.zeros((0, 3))

    def mission(self) -> dict[str, Any]:
        return dict(self.nav.watch.mission)

    def send_mission(self) -> bool:
        """Send the mission again (a fresh id) until the navigator reports it."""
        text = self.feed.next()
        return self.inj.send_mission(text, lambda: self.mission().get("mission") == self.feed.id)

    def run(self, plan: list[Fault], duration: float) -> SoakResult:
        """Walk missions for ``duration`` [s], injecting ``plan`` in order while it fits."""
        if not self.send_mission():
            raise RuntimeError("the navigator did not take the mission")
        for fault in plan:
            if self.now() + fault.quiet + 30.0 > duration:
                break
            self.walk(fault.quiet)
            self.result.faults.append(self.inject(fault))
        self.walk(max(0.0, duration - self.now()))
        self.result.contacts = self.nav.watch.contacts
        self.result.obstacle_contacts = self.nav.watch.obstacle_contacts
        self.result.first_contacts = self.nav.watch.first_contacts
        self.result.duration = self.now()
        return self.result

    def walk(self, seconds: float) -> None:
        """Walk missions for ``seconds``: a done mission is sent again, a failed one (no
        fault injected) is noted and recovered; RSS sampled."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            state = self.mission()
            if state.get("mission") == self.feed.id and state.get("state") == "DONE":
                self.result.missions_done += 1
                self.send_mission()
            elif state.get("mission") == self.feed.id and state.get("state") in (
                    "FAILED", "CANCELLED", "REFUSED"):
                self.result.unexpected.append(f"{self.now():.0f} s: {state.get('reason')}")
                self.say(f"soak: unexpected: mission {state.get('state')}: "
                         f"{state.get('reason')}")
                self.inj.recover()
                self.send_mission()
            if self.now() - self._rss_at >= RSS_PERIOD:
                self._rss_at = self.now()
                self.result.rss.append((self.now(), rss_by_process(self.nav.sup, rss_mb)))
            time.sleep(0.2)

    def inject(self, fault: Fault) -> FaultRecord:
        """One fault: inject, watch, end it, recover; its record."""
        exp = expectation(fault)
        rec = FaultRecord(fault.name, round(self.now(), 1), fault.length, exp.hold,
                          exp.hold_within, recovery=exp.recovery.value)
        if not self._walking(WALK_WAIT):
            rec.notes.append("the body was not walking when the fault began")
        path = self.path()
        pose = (float(path[-1, 1]), float(path[-1, 2])) if len(path) else (0.0, 0.0)
        t0 = time.monotonic()
        self.inj.begin(fault, pose)
        if fault.kind in (FaultKind.KILL, FaultKind.ESTOP):
            time.sleep(exp.hold_within + DEAD_FOR)
        self.inj.end(fault, t0)
        t_end = time.monotonic()
        if fault.kind is FaultKind.KILL:
            time.sleep(SETTLE)
        if not exp.hold:
            time.sleep(WATCH_FOR)
        path = self.path()
        rec.held_after = still_after(path, t0, max(t_end, time.monotonic()))
        # after a kill or an e-stop nothing may move until the operator's steps: the window
        # runs to the recovery; a stopped process may resume by itself once continued
        operator = exp.recovery in (Recovery.RECOVER, Recovery.RESEND) and \
            fault.kind is not FaultKind.STOP
        until = time.monotonic() if operator else t_end
        if exp.hold and until > t0 + exp.hold_within:
            rec.moved = motion(path, t0 + exp.hold_within, until)
        rec.recovered_after = self.recover(exp.recovery, rec,
                                           paused=fault.kind is FaultKind.STOP)
        self.say(f"soak: {self.now():6.0f} s  {fault.name:<22} hold "
                 f"{_s(rec.held_after)} (within {exp.hold_within:g} s: "
                 f"{'required' if exp.hold else 'not required'}), moved during it "
                 f"{1000 * rec.moved:.1f} mm, recovery ({exp.recovery.value}) "
                 f"{_s(rec.recovered_after)}{' ' + '; '.join(rec.notes) if rec.notes else ''}"
                 f" -> {'ok' if rec.ok else 'FAILED'}")
        return rec

    def recover(self, recovery: Recovery, rec: FaultRecord, paused: bool = False
                ) -> float | None:
        """The documented recovery; seconds until the mission walks again (None: it did not
        within `RECOVERY_TIMEOUT`, after which the full recovery is run to go on). After a
        stopped process (``paused``) the chain may have only paused, and a walk that resumes
        by itself within `AUTO_WAIT` is the documented way back; after a kill or an e-stop it
        never is (the operator's steps run, and a walk before them fails the fault)."""
        t0 = time.monotonic()
        if recovery is Recovery.RECOVER and paused and self._walking_again(t0, AUTO_WAIT):
            # a pause of the chain (e.g. the manager's heartbeat late while the driver was
            # stopped) clears by itself and the walk resumes from the measured pose
            rec.notes.append("resumed by itself: the pause cleared")
            return time.monotonic() - t0
        if recovery is Recovery.RECOVER and not self.inj.recover():
            rec.notes.append("recovery step failed: " + " / ".join(self.inj.lines[-2:]))
            if self.inj.recover():
                rec.notes.append("a second recover and stand did it")
        if recovery in (Recovery.RECOVER, Recovery.RESEND) and not self.send_mission():
            rec.notes.append("the navigator did not take the mission")
        if recovery in (Recovery.NONE, Recovery.AUTOMATIC) and \
                self.mission().get("state") != "RUNNING":
            rec.notes.append(f"mission {self.mission().get('state')}: "
                             f"{self.mission().get('reason')}")
        if self._walking_again(t0, RECOVERY_TIMEOUT):
            return time.monotonic() - t0
        self.inj.recover()  # go on with the soak
        self.send_mission()
        return None

    def _walking(self, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            now = time.monotonic()
            if motion(self.path(), now - 1.0, now) >= WALKING:
                return True
            time.sleep(0.1)
        return False

    def _walking_again(self, t0: float, timeout: float) -> bool:
        end = t0 + timeout
        while time.monotonic() < end:
            state = self.mission()
            if state.get("state") == "DONE" and state.get("mission") == self.feed.id:
                return True
            if state.get("state") == "RUNNING" and motion(self.path(), t0,
                                                          time.monotonic()) >= RESUMED:
                return True
            time.sleep(0.2)
        return False


def _s(value: float | None) -> str:
    return "never" if value is None else f"{value:.2f} s"


def open_checks(record: Path) -> dict[str, str]:
    """The recording opened by ``mcap``'s own reader and by ``rosbags`` (when installed):
    message counts or the error."""
    out: dict[str, str] = {}
    try:
        from mcap.reader import make_reader

        with open(record, "rb") as stream:
            count = sum(1 for _ in make_reader(stream).iter_messages())
        out["mcap"] = f"{count} messages"
    except Exception as exc:  # any failure of the foreign reader is the figure
        out["mcap"] = f"failed: {exc}"
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        out["rosbags"] = "not installed (pip install rosbags)"
        return out
    try:
        with AnyReader([record], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
            out["rosbags"] = f"{r.message_count} messages"
    except Exception as exc:  # as above
        out["rosbags"] = f"failed: {exc}"
    return out
