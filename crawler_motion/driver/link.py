"""The driver's bus link: open, close, send with bounded retries, take down, reopen."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from enum import Enum

import can

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.runtime.log import Severity

#: Timeout handed to ``bus.send``: never wait for a full transmit queue [s].
SEND_TIMEOUT = 0.0
#: Frames in a row that could not be sent (after their retries) before the bus is taken as down.
FAILED_FRAMES_BEFORE_REOPEN = 3


def is_malformed_frame(exc: BaseException) -> bool:
    """True if a receive error is one bad datagram, not a broken transport.

    python-can's ``udp_multicast`` raises ``CanOperationError("could not unpack received
    message")`` for a datagram that is not a packed CAN message, with the decoding error as its
    cause; the socket is fine. A cause that is an ``OSError`` (or none) is a transport error.
    """
    cause = exc.__cause__
    return (isinstance(exc, can.CanOperationError) and cause is not None
            and not isinstance(cause, OSError))


class DriverError(CrawlerMotionError):
    """The driver cannot do what was asked (e.g. the CAN bus cannot be opened)."""


class BusState(str, Enum):
    """The state of the link: closed, open and working, or down (being reopened)."""

    CLOSED = "closed"
    UP = "up"
    DOWN = "down"


class BusLink:
    """One CAN bus, given (``bus``: never shut down here) or built by ``factory`` (called by
    `open` and by every reopen; those buses are shut down here).

    Every send is tried ``1 + retries()`` times without waiting; each refusal is counted. A
    malformed received frame (`is_malformed_frame`) is counted and dropped. A transport
    receive error, or `FAILED_FRAMES_BEFORE_REOPEN` frames in a row that could not be sent,
    take the bus down: an owned bus is shut down and rebuilt every ``reopen_period()``, a given
    bus is simply tried again after it.

    Callers hold ``lock`` around every method but `recv` and `reopen`, which take it themselves
    (receiving waits, the factory may block). ``retries()`` gives the immediate retries of a
    frame, ``reopen_period()`` the period of reopen attempts [s]; ``say(key, severity,
    message)`` logs throttled by key; ``on_back()`` runs (lock held) when a down bus works
    again; ``on_rx_error(text)`` (lock held) when receiving fails.
    """

    def __init__(self, lock: threading.RLock, clock: Callable[[], float], *,
                 bus: can.BusABC | None, factory: Callable[[], can.BusABC] | None,
                 retries: Callable[[], int], reopen_period: Callable[[], float],
                 say: Callable[[str, Severity, str], None],
                 on_back: Callable[[], None], on_rx_error: Callable[[str], None]) -> None:
        if (bus is None) == (factory is None):
            raise ValueError("give exactly one of bus and bus_factory")
        self._lock = lock
        self._clock = clock
        self._given = bus
        self._factory = factory
        self._retries = retries
        self._reopen_period = reopen_period
        self._say = say
        self._on_back = on_back
        self._on_rx_error = on_rx_error
        self.bus: can.BusABC | None = None
        self.state = BusState.CLOSED
        self._to_close: can.BusABC | None = None
        self.down_since: float | None = None
        self._next_reopen = 0.0
        self._failed_frames = 0
        self.open_time: float | None = None
        self.last_tx_error = ""
        self.on_sent: Callable[[can.Message], None] | None = None  # each frame that went out
        self.counts = dict.fromkeys(("tx", "tx_errors", "rx_malformed", "bus_failures",
                                     "reopens", "reopen_failures"), 0)

    @property
    def is_open(self) -> bool:
        """True between `open` and `close` (also while down and being reopened)."""
        return self.state is not BusState.CLOSED

    @property
    def ok(self) -> bool:
        """True while open and not taken as down."""
        return self.state is BusState.UP

    def open(self) -> None:
        """Open the bus; `DriverError` if it cannot be opened (nothing is left open then)."""
        if self.is_open:
            return
        if self._given is not None:
            bus = self._given
        else:
            try:
                bus = self._factory()
            except Exception as exc:
                raise DriverError(f"cannot open the CAN bus: {type(exc).__name__}: "
                                  f"{exc}") from exc
        self.bus = bus
        self.state = BusState.UP
        self.down_since = None
        self._failed_frames = 0
        self.open_time = self._clock()

    def close(self) -> list[can.BusABC]:
        """Mark the link closed; the owned buses the caller shuts down (outside the lock)."""
        closing = [b for b in (self.bus, self._to_close) if b is not None]
        self.state = BusState.CLOSED
        self.bus = None
        self._to_close = None
        return closing if self._factory is not None else []

    @staticmethod
    def shutdown(bus: can.BusABC) -> None:
        """Shut one bus down; a broken bus may fail to close and is dropped either way."""
        try:
            bus.shutdown()
        except Exception:
            logging.getLogger(__name__).debug("bus shutdown failed", exc_info=True)

    def recv(self, timeout: float, sleep: Callable[[float], object]) -> can.Message | None:
        """Receive one frame, waiting up to ``timeout`` [s] (lock not held on entry).

        None when nothing came, when the bus is not up (after ``sleep(timeout)``) or when
        receiving failed (which takes the bus down).
        """
        with self._lock:
            bus = self.bus if self.ok else None
        if bus is None:
            if timeout > 0:
                sleep(timeout)
            return None
        try:
            return bus.recv(timeout=timeout)
        except Exception as exc:  # bus gone / interface down, or one malformed datagram
            with self._lock:
                text = f"receive failed: {type(exc).__name__}: {exc}"
                self._on_rx_error(text)
                if is_malformed_frame(exc):
                    self.counts["rx_malformed"] += 1
                    self._say("rx", Severity.WARNING, f"malformed frame dropped: {text} "
                              f"({exc.__cause__!r})")
                elif bus is self.bus:
                    self.fail(text)
            return None

    def send(self, msg: can.Message) -> bool:
        """Send one frame with bounded immediate retries; True when it went out.

        Frames failing `FAILED_FRAMES_BEFORE_REOPEN` times in a row take the bus down.
        """
        if not self.ok or self.bus is None:
            return False
        attempts = 1 + self._retries()
        if self._send_internal(self.bus, msg, attempts):
            self._failed_frames = 0
            return True
        self._failed_frames += 1
        self._say("tx", Severity.WARNING, f"frame 0x{msg.arbitration_id:03X} not sent after "
                  f"{attempts} attempts: {self.last_tx_error}")
        if self._failed_frames >= FAILED_FRAMES_BEFORE_REOPEN:
            self.fail(f"{self._failed_frames} frames in a row could not be sent: "
                      f"{self.last_tx_error}")
        return False

    def _send_internal(self, bus: can.BusABC, msg: can.Message, attempts: int) -> bool:
        """Up to ``attempts`` zero-timeout sends; counts every refusal."""
        for _ in range(attempts):
            try:
                bus.send(msg, timeout=SEND_TIMEOUT)
            except Exception as exc:  # CanError, OSError, ... from any interface
                self.counts["tx_errors"] += 1
                self.last_tx_error = f"{type(exc).__name__}: {exc}"
                continue
            self.counts["tx"] += 1
            if self.on_sent is not None:
                self.on_sent(msg)
            return True
        return False

    def fail(self, reason: str) -> None:
        """Take the bus as down; the next `reopen` closes it and reopens it when due."""
        if not self.ok:
            return
        now = self._clock()
        self.state = BusState.DOWN
        self.down_since = now
        self._next_reopen = now + self._reopen_period()
        self.counts["bus_failures"] += 1
        if self._factory is not None:
            self._to_close, self.bus = self.bus, None
        self._say("bus", Severity.ERROR, f"CAN bus down ({reason}); reopening every "
                  f"{self._reopen_period():g} s")

    def reopen(self) -> None:
        """Close a failed bus and try to open it again when due (lock not held on entry)."""
        with self._lock:
            closing, self._to_close = self._to_close, None
            now = self._clock()
            due = self.state is BusState.DOWN and now >= self._next_reopen
            if due:
                self._next_reopen = now + self._reopen_period()
        if closing is not None:
            self.shutdown(closing)
        if not due:
            return
        bus = None
        if self._factory is not None:
            try:
                bus = self._factory()
            except Exception as exc:
                with self._lock:
                    self.counts["reopen_failures"] += 1
                    self.last_tx_error = f"reopen failed: {type(exc).__name__}: {exc}"
                return
        with self._lock:
            if self.state is BusState.DOWN:
                if bus is not None:
                    self.bus, bus = bus, None
                self._back()
        if bus is not None:  # closed (or reopened) meanwhile
            self.shutdown(bus)

    def _back(self) -> None:
        self.state = BusState.UP
        self._failed_frames = 0
        self.counts["reopens"] += 1
        down = self._clock() - (self.down_since or self._clock())
        self.down_since = None
        self._say("", Severity.INFO, f"CAN bus back after {down:.3f} s")
        self._on_back()
