"""The driver's bus side: joint commands through the motion gate onto the bus, feedback back.

Pure Python (no ROS): `DriverCore` works on any python-can `can.BusABC`, handed over directly or
built by a factory, so it can be unit-tested on a ``virtual`` bus or a stub that raises. The ROS
node (`crawler_motion.driver.node`) only converts messages and calls it. It composes the bus link
(`link`: bounded send retries, reopening), the send queue (`outbox`), the motion gate (`gate`:
lifecycle, enable, e-stop latch, command watchdog), the feedback bookkeeping (`feedback`) and the
diagnostic texts (`diagnostics`).

Commands. `submit` validates one joint command by `JointStateRule` (names, lengths, finite
values, joint limits: refused, never clipped), encodes it with `MotorProtocol.encode_targets` and
sends it at once. Only the newest command is kept: a command that could not be sent is retried by
`tick` while it is younger than one target period (the DBC's cycle time), never sent late.

E-stop. `estop` latches within the call and sends the e-stop frame (retried until it goes out,
re-sent after a reopen and whenever the heartbeat reports the manager out of ``estop``). Only
`reset` clears the latch, and the motors then need `enable` again.

Nothing blocks: sends use a zero timeout, and receiving waits only in `poll` (called by the
background thread of `start`, with `tick` for the watchdog and reopening).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import can
import numpy as np

from crawler_motion.canbus.protocol import AxisFlags, Heartbeat, MotorProtocol
from crawler_motion.driver.bus_watch import BusWatch
from crawler_motion.driver.control import CommandResult, MotionControl
from crawler_motion.driver.diagnostics import DriverDiagnostics, StatusEntry
from crawler_motion.driver.feedback import Feedback
from crawler_motion.driver.gate import MotionGate
from crawler_motion.driver.link import BusLink
from crawler_motion.driver.outbox import Outbox
from crawler_motion.driver.senders import SenderWatch
from crawler_motion.driver.settings import DriverSettings
from crawler_motion.runtime.log import Severity, Throttle, log
from crawler_motion.runtime.loop import BackgroundLoop

#: Frames taken off the bus per `DriverCore.poll` at most (a flooding bus cannot stall the loop).
MAX_FRAMES_PER_POLL = 500
#: Commands are refused this long after two publishers of joint_commands were seen racing [s].
SENDER_CONFLICT_HOLD = 2.0
#: Period of the background loop of `DriverCore.start` [s]: watchdog and reopen resolution.
TICK_PERIOD = 0.005


@dataclass(frozen=True)
class DriverCounters:
    """Counters of the driver core (monotonic while it lives)."""

    tx: int = 0  # frames sent
    tx_errors: int = 0  # send attempts the bus refused (each retry counts)
    tx_stale: int = 0  # commands dropped unsent: older than one period, or superseded
    rx_malformed: int = 0  # datagrams / frames the interface could not unpack (dropped)
    rx: int = 0  # frames received
    rx_dropped: int = 0  # undecodable frames: unknown id, wrong DLC, checksum, range...
    rx_ignored: int = 0  # controller-side frames the driver sent itself (loop-back)
    foreign_targets: int = 0  # target frames with the driver's ids it did not send
    foreign_controls: int = 0  # control frames the driver did not send
    rx_conflicts: int = 0  # two different position / status frames with one counter
    sender_conflicts: int = 0  # joint_commands from more than one publisher, interleaved
    commands: int = 0  # joint commands accepted and encoded
    refused: int = 0  # joint commands refused as invalid
    step_refused: int = 0  # joint commands refused: a step beyond the step bound
    blocked: int = 0  # valid joint commands not sent: e-stop, watchdog, not enabled
    inactive: int = 0  # joint commands dropped while inactive
    feedback: int = 0  # complete joint-state vectors emitted
    bus_failures: int = 0  # times the bus was taken as down
    reopens: int = 0  # successful reopen attempts
    reopen_failures: int = 0  # failed reopen attempts
    watchdog_trips: int = 0
    estops: int = 0  # e-stop requests


class DriverCore:
    """The driver's bus side for one `MotorProtocol`.

    Give exactly one of ``bus`` (not owned: never shut down by the core) or ``bus_factory``
    (called by `open` and by every reopen; the core shuts those buses down). ``clock`` is a
    steady clock [s]; ``on_feedback(positions, efforts)`` receives each complete joint-state
    vector in joint order [rad] with the joint efforts of the same cycle [N m], or an empty
    array when the manager did not report all of them (from the thread calling `poll`).
    ``logger`` is a `logging.Logger` or an rclpy logger. Thread-safe: `start` runs `poll` and
    `tick` in a background thread.
    """

    def __init__(self, protocol: MotorProtocol, bus: can.BusABC | None = None, *,
                 bus_factory: Callable[[], can.BusABC] | None = None,
                 settings: DriverSettings | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 on_feedback: Callable[[np.ndarray, np.ndarray], None] | None = None,
                 logger: Any = None) -> None:
        self.protocol = protocol
        self._settings = settings or DriverSettings()
        self._clock = clock
        self._on_feedback = on_feedback
        self._log = logger or logging.getLogger(__name__)
        self._throttle = Throttle()
        self._lock = threading.RLock()
        self._loop = BackgroundLoop("crawler-driver-can", self._step, self._loop_error,
                                    TICK_PERIOD)
        self._link = BusLink(self._lock, clock, bus=bus, factory=bus_factory,
                             retries=lambda: self._settings.send_retries,
                             reopen_period=lambda: self._settings.reopen_period,
                             say=self._say, on_back=lambda: self._control.bus_back(),
                             on_rx_error=self._feedback_error)
        self._hb_period = protocol.cycle_period("heartbeat")
        self._gate = MotionGate()
        self._outbox = Outbox(protocol.cycle_period("target"))
        self._watch = BusWatch(frozenset(protocol.frame_ids("target")),
                               frozenset(protocol.frame_ids("control")))
        self._link.on_sent = lambda msg: self._watch.sent(msg, self._clock())
        self._senders = SenderWatch()
        self._feedback = Feedback(protocol, self._watch)
        self._diagnostics = DriverDiagnostics(self._link, self._gate, self._feedback,
                                              self._outbox, self._hb_period, self._watch)
        self._control = MotionControl(protocol, self._link, self._gate, self._outbox,
                                      lambda: self._settings, clock, self._say,
                                      lambda: self._feedback.positions)

    # ---- observation -----------------------------------------------------------------------

    settings = property(lambda self: self._settings, doc="The current settings.")
    is_open = property(lambda self: self._link.is_open,
                       doc="True between `open` and `close` (also while the bus is down).")
    bus_ok = property(lambda self: self._link.ok, doc="True while the bus is open and up.")
    active = property(lambda self: self._gate.active,
                      doc="True between `activate` and `deactivate`.")
    enabled = property(lambda self: self._gate.enabled,
                       doc="True while the driver has the motors enabled.")
    estop_latched = property(lambda self: self._gate.latched,
                             doc="True from `estop` until `reset`.")
    estop_reason = property(lambda self: self._gate.estop_reason or "",
                            doc="Why the ESTOP was latched (\"\" when it is not).")
    gate_state = property(lambda self: self._gate.state.value,
                          doc="The motion gate's state (`gate.GateState` value).")
    enable_epoch = property(lambda self: self._gate.enable_epoch,
                            doc="Number of enables sent so far (the planner resumes on it).")
    watchdog_tripped = property(lambda self: self._gate.tripped,
                                doc="True from a watchdog trip until `enable` / `activate`.")
    motion_allowed = property(lambda self: self._gate.motion_allowed,
                              doc="True when a valid command would be sent now.")
    last_tx_error = property(lambda self: self._link.last_tx_error, doc="The last send error.")
    last_rx_error = property(lambda self: self._feedback.last_rx_error,
                             doc="The last receive or decode error.")
    last_refusal = property(lambda self: self._control.last_refusal,
                            doc="Why the last refused joint command was refused.")

    @property
    def counters(self) -> DriverCounters:
        """A snapshot of the counters."""
        with self._lock:
            return DriverCounters(**self._link.counts, **self._feedback.counts,
                                  **self._watch.counts, tx_stale=self._outbox.stale,
                                  sender_conflicts=self._senders.conflicts,
                                  **self._control.counts)

    @property
    def positions(self) -> np.ndarray:
        """Last measured joint angles in joint order [rad] (NaN where none was received)."""
        with self._lock:
            return self._feedback.positions.copy()

    @property
    def heartbeat(self) -> Heartbeat | None:
        """The last heartbeat, None before the first one."""
        return self._feedback.heartbeat

    @property
    def axis_flags(self) -> dict[int, AxisFlags]:
        """The last status bits per axis index."""
        with self._lock:
            return dict(self._feedback.flags)

    def heartbeat_timeout(self) -> float:
        """Silence after which the manager is reported lost [s]."""
        return self._settings.heartbeat_timeout_periods * self._hb_period

    def status(self) -> list[StatusEntry]:
        """Diagnostic entries: the manager/driver state, the bus, one per axis."""
        with self._lock:
            counts = asdict(self.counters)
            return self._diagnostics.entries(self._clock(), self._settings, counts,
                                             self._control.last_refusal)

    def update_settings(self, settings: DriverSettings) -> None:
        """Apply new settings (takes effect at the next command / tick)."""
        with self._lock:
            self._settings = settings

    # ---- bus life cycle and background loop ------------------------------------------------

    def open(self) -> None:
        """Open the bus; `DriverError` if it cannot be opened (nothing is left open then)."""
        with self._lock:
            if not self._link.is_open:
                self._link.open()
                self._feedback.reset()

    def close(self) -> None:
        """Stop the background thread, forget the motion state and close an owned bus."""
        self.stop()
        with self._lock:
            self._gate.close()
            self._outbox.targets, self._outbox.control = [], None
            closing = self._link.close()
        for bus in closing:
            BusLink.shutdown(bus)

    def start(self) -> None:
        """Run `poll` and `tick` in a background thread until `stop` / `close`."""
        self._loop.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the background thread (no-op when it does not run)."""
        self._loop.stop(timeout)

    running = property(lambda self: self._loop.running,
                       doc="True while the background thread of `start` runs.")

    def _step(self) -> None:
        self.poll(TICK_PERIOD)
        self.tick()

    def _loop_error(self, exc: Exception) -> None:
        self._say("loop", Severity.ERROR, f"driver loop error: {type(exc).__name__}: {exc}")

    def _feedback_error(self, text: str) -> None:
        self._feedback.last_rx_error = text

    def _say(self, key: str, severity: Severity, message: str) -> None:
        """Log (at most once a second per non-empty ``key``); never raises."""
        if not key or self._throttle.allow(key):
            log(self._log, severity, message)

    # ---- time and receiving ----------------------------------------------------------------

    def tick(self) -> None:
        """Watchdog, retries of queued frames, e-stop re-assertion and bus reopening."""
        self._link.reopen()
        with self._lock:
            if self._link.is_open:
                self._control.tick(self._clock())

    def poll(self, timeout: float = 0.0) -> int:
        """Take pending frames off the bus (waiting up to ``timeout`` [s] for the first one).

        Returns the number of frames handled. Feedback callbacks run outside the lock.
        """
        handled = 0
        wait = max(float(timeout), 0.0)
        while handled < MAX_FRAMES_PER_POLL:
            msg = self._link.recv(wait, self._loop.stopping.wait)
            if msg is None:
                with self._lock:
                    self._feedback.listened = self._clock()
                return handled
            wait, handled = 0.0, handled + 1
            with self._lock:
                now = self._clock()
                heartbeat, emit = self._feedback.handle(msg, now)
                if heartbeat is not None:
                    self._control.on_heartbeat(heartbeat.state, now, self._hb_period)
            if emit is not None and self._on_feedback is not None:
                self._on_feedback(*emit)
        return handled

    # ---- lifecycle and safety commands, joint commands (see `MotionControl`) ---------------

    def activate(self) -> tuple[bool, str]:
        """Enable the motors and start forwarding commands; (ok, why not / what happened)."""
        with self._lock:
            return self._control.activate()

    def deactivate(self) -> str:
        """Stop forwarding and send ``on_deactivate`` (only ``disable`` if not enabled)."""
        with self._lock:
            return self._control.deactivate()

    def enable(self) -> tuple[bool, str]:
        """Re-enable after a watchdog trip, a reset or an ``on_timeout: disable``."""
        with self._lock:
            return self._control.enable()

    def estop(self, reason: str = "requested") -> bool:
        """Latch ESTOP and send the e-stop frame; True when the frame went out now."""
        with self._lock:
            return self._control.estop(reason)

    def reset(self) -> tuple[bool, str]:
        """Clear the ESTOP latch and send ``reset``; the motors then need `enable`."""
        with self._lock:
            return self._control.reset()

    def submit(self, names: Sequence[str], positions: Sequence[float],
               velocities: Sequence[float] = (), efforts: Sequence[float] = (),
               sequence: int | None = None) -> CommandResult:
        """Validate, encode and send one joint command (names and positions [rad]);
        ``sequence`` is its publisher's message number (`senders.SenderWatch`): commands of
        two racing publishers raise an alarm and none is sent while it lasts."""
        with self._lock:
            now = self._clock()
            if self._senders.note(sequence, now):
                self._watch.alarm("joint_commands from more than one publisher (interleaved "
                                  "sequence numbers): none is sent while this lasts", now)
                self._say("senders", Severity.ERROR, self._watch.last_alarm)
            if self._senders.last_conflict_time is not None and (
                    now - self._senders.last_conflict_time <= SENDER_CONFLICT_HOLD):
                self._control.counts["blocked"] += 1
                return CommandResult(False, "refused: joint_commands from more than one "
                                            "publisher")
            return self._control.submit(names, positions, velocities, efforts)
