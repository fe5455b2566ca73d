"""A simulated multi-axis motor manager speaking `crawler_motion.canbus.protocol` on any CAN bus.

Pure Python (no ROS). Every axis tracks its target at a speed limit [rad/s]; the manager sends
measured efforts (a plant's mean drive torques, else 0 N m; none with ``effort=False``, like a
manager without effort frames), positions and status bits at ``rate`` [Hz] and a heartbeat
every ``heartbeat_period`` [s], and obeys the MM_Control commands (see
`crawler_motion.sim.manager_state`):

- ``disable``: axes unpowered, targets ignored (the start state);
- ``enable``: axes powered, follow the targets (starting from where they are);
- ``hold``: axes powered, hold the current position, targets ignored until ``enable``;
- ``estop``: stop and unpower, latched: every command but ``reset`` is ignored;
- ``reset``: leave ``estop``/``fault`` for ``disabled`` and clear latched fault bits whose
  condition is gone (a fault still present keeps the manager in ``fault``).

While enabled, no fresh target frame for ``command_timeout`` [s] makes the axes hold where they
are and sets every axis's command-timeout bit; the next fresh target frame resumes tracking. A
target frame repeating the previous counter of its group is stale: rejected, it does not feed
the timeout. Undecodable frames are counted as rejected and never stop the manager.

Drive it either deterministically with `MotorManagerSim.step` (tests) or in a background thread
with `MotorManagerSim.start` / `MotorManagerSim.stop` on a monotonic clock;
`crawler_motion.sim.manager_cli` runs it as a process (``motor_manager_sim --help``).
"""

from __future__ import annotations

import logging
import math
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import can
import numpy as np

from crawler_motion.canbus.protocol import ControlFrame, MotorProtocol, TargetFrame
from crawler_motion.errors import ProtocolError
from crawler_motion.sim.manager_loop import PeriodicSchedule, StepLoop
from crawler_motion.sim.manager_model import ManagerModel, Plant
from crawler_motion.sim.manager_state import ManagerState

log = logging.getLogger(__name__)

#: Name of the background thread (and of the console script).
THREAD_NAME = "motor_manager_sim"
DEFAULT_SPEED_LIMIT = 2.0  # [rad/s]
DEFAULT_COMMAND_TIMEOUT = 0.2  # [s]
#: Frames taken off the bus per `step` at most, so a flooding sender cannot stall the manager.
MAX_FRAMES_PER_STEP = 1000
#: Longest sleep of the background loop between simulation steps [s].
MAX_TICK = 0.01
#: Errors of python-can's ``send``/``recv`` that the manager counts instead of raising.
BUS_ERRORS = (can.CanError, OSError, ValueError)


@dataclass(frozen=True)
class SimCounters:
    """Frame counters of the simulated manager."""

    received: int = 0  # frames taken off the bus (or handed to `handle`)
    sent: int = 0  # frames sent
    rejected: int = 0  # undecodable, invalid or stale frames
    ignored: int = 0  # valid frames without effect (feedback echoes, targets while not enabled)
    targets: int = 0  # target frames applied
    commands: int = 0  # control frames received (applied or refused by a latch)
    send_errors: int = 0  # frames the bus refused to send

    def plus(self, **increments: int) -> SimCounters:
        """These counters with ``increments`` (name -> how many) added."""
        return replace(self, **{k: getattr(self, k) + v for k, v in increments.items()})


def _positive(value: float, what: str) -> float:
    number = float(value)
    if not (math.isfinite(number) and number > 0):
        raise ValueError(f"{what} must be a finite number > 0, got {value!r}")
    return number


def _speed_limits(speed_limit: float | Sequence[float], n: int) -> np.ndarray:
    """One speed limit per axis [rad/s] of one value or ``n`` values."""
    speed = np.asarray(speed_limit, dtype=float).reshape(-1)
    if speed.size == 1:
        speed = np.full(n, float(speed[0]))
    if speed.shape != (n,) or not np.all(np.isfinite(speed)) or np.any(speed <= 0):
        raise ValueError(f"speed_limit must be one or {n} finite values > 0 rad/s, "
                         f"got {speed_limit!r}")
    return speed


def _schedules(protocol: MotorProtocol, rate: float | None,
               heartbeat_period: float | None) -> tuple[PeriodicSchedule, PeriodicSchedule]:
    """The feedback and heartbeat schedules: ``rate`` [Hz] and ``heartbeat_period`` [s] when
    given, else the DBC's cycle times, else the defaults."""
    feedback = (1.0 / _positive(rate, "rate [Hz]") if rate is not None
                else protocol.cycle_period("position"))
    heartbeat = _positive(heartbeat_period if heartbeat_period is not None
                          else protocol.cycle_period("heartbeat"),
                          "heartbeat_period [s]")
    return PeriodicSchedule(feedback), PeriodicSchedule(heartbeat)


def feedback_frames(protocol: MotorProtocol, model: ManagerModel, counter: int,
                    effort: bool) -> list[can.Message]:
    """One feedback cycle: the efforts (with ``effort``; before the positions, as their lower
    ids would win arbitration), the positions, the status bits."""
    frames = protocol.encode_efforts(model.efforts(), counter) if effort else []
    frames += protocol.encode_feedback(model.pos, counter)
    return frames + protocol.encode_status(model.flags(), counter)


class MotorManagerSim:
    """The simulated manager on ``bus``; positions are axis positions in axis order [rad].

    ``initial_positions`` are joint angles in joint order [rad] (default: all zero, which is not
    the standing pose); ``speed_limit`` is one value or one per axis [rad/s] (a `Plant` moves
    the axes instead, when given); ``rate`` [Hz], ``heartbeat_period`` [s]: the DBC's default;
    ``effort``: send effort frames (`feedback_frames`)."""

    def __init__(self, bus: can.BusABC, protocol: MotorProtocol, *,
                 speed_limit: float | Sequence[float] = DEFAULT_SPEED_LIMIT,
                 rate: float | None = None, heartbeat_period: float | None = None,
                 command_timeout: float = DEFAULT_COMMAND_TIMEOUT,
                 initial_positions: Sequence[float] | None = None, plant: Plant | None = None,
                 clock: Callable[[], float] = time.monotonic, effort: bool = True) -> None:
        missing = [s.value for s in ManagerState if s.value not in protocol.states]
        if missing:
            raise ProtocolError(f"the DBC's MM_Heartbeat.State lacks the states {missing}")
        self._bus = bus
        self._protocol = protocol
        n = protocol.n_axes
        speed = _speed_limits(speed_limit, n)
        self._feedback, self._heartbeat = _schedules(protocol, rate, heartbeat_period)
        timeout = _positive(command_timeout, "command_timeout [s]")
        pos = protocol.to_axis(np.zeros(n) if initial_positions is None else initial_positions)
        protocol.encode_feedback(pos, 0)  # refuses an initial pose it could not report
        self._model = ManagerModel(pos, speed, timeout, plant)
        self._silent = False
        self._effort = bool(effort)
        self._last_counter: dict[int, int] = {}
        self._feedback_counter = 0
        self._heartbeat_counter = 0
        self._counters = SimCounters()
        self.last_error = ""
        self._lock = threading.RLock()
        self.step_period = min(self.period, self.heartbeat_period, MAX_TICK)  # physics step [s]
        self._loop = StepLoop(THREAD_NAME, self.step_period, clock, self._receive, self.handle,
                              self._advance, self._on_step_error)

    # ---- observation -----------------------------------------------------------------------

    @property
    def state(self) -> ManagerState:
        """Manager state (a `ManagerState`, equal to its name)."""
        with self._lock:
            return self._model.state

    @property
    def positions(self) -> np.ndarray:
        """Measured axis positions in axis order [rad] (a copy)."""
        with self._lock:
            return self._model.pos.copy()

    @property
    def joint_positions(self) -> np.ndarray:
        """Measured positions as joint angles in joint order [rad]."""
        return self._protocol.to_joint(self.positions)

    @property
    def targets(self) -> np.ndarray:
        """Current axis targets in axis order [rad] (a copy)."""
        with self._lock:
            return self._model.target.copy()

    @property
    def time(self) -> float:
        """Simulated time since construction [s]."""
        with self._lock:
            return self._model.time

    @property
    def command_timed_out(self) -> bool:
        """True while the command timeout holds the axes."""
        with self._lock:
            return self._model.machine.timed_out

    @property
    def counters(self) -> SimCounters:
        """A snapshot of the frame counters."""
        with self._lock:
            return self._counters

    @property
    def running(self) -> bool:
        """True while the background thread runs."""
        return self._loop.running

    @property
    def period(self) -> float:
        """Feedback period [s]."""
        return self._feedback.period

    @property
    def heartbeat_period(self) -> float:
        """Heartbeat period [s]."""
        return self._heartbeat.period

    # ---- fault injection -------------------------------------------------------------------

    def inject_axis_fault(self, axis: int, kind: str = "over_current") -> None:
        """Raise a fault condition (a `FaultKind` name) on an axis: the manager stops and enters
        ``fault``."""
        with self._lock:
            self._model.inject_fault(axis, kind)

    def stall_axis(self, axis: int, stalled: bool = True) -> None:
        """Block (or free) an axis: it stops moving and reports the stalled bit."""
        with self._lock:
            self._model.machine.stall(axis, stalled)

    def silence_heartbeat(self, silent: bool = True) -> None:
        """Stop (or resume) sending the heartbeat; positions and status still flow."""
        with self._lock:
            self._silent = bool(silent)

    def clear_faults(self) -> None:
        """Remove every injected fault condition and stall.

        Latched fault bits and the ``fault`` state stay until a ``reset`` command, as on the
        real manager.
        """
        with self._lock:
            self._model.machine.clear()

    # ---- frame handling --------------------------------------------------------------------

    def _count(self, **increments: int) -> None:
        self._counters = self._counters.plus(**increments)

    def handle(self, msg: can.Message) -> None:
        """Process one received frame at the current simulated time; never raises for data."""
        with self._lock:
            self._count(received=1)
            if self._protocol.sender(msg) == "manager":
                self._count(ignored=1)  # our own echo or another manager: not decoded
                return
            try:
                frame = self._protocol.decode(msg)
            except ProtocolError as exc:
                self._reject(str(exc))
                return
            except Exception as exc:  # a malformed Message object must not stop the manager
                self._reject(f"{type(exc).__name__}: {exc}")
                return
            if isinstance(frame, ControlFrame):
                self._command(frame.command)
            elif isinstance(frame, TargetFrame):
                self._on_target(frame)
            else:  # a manager-side frame: our own echo on udp_multicast, or another manager
                self._count(ignored=1)

    def _on_step_error(self, reason: str) -> None:
        self.last_error = reason

    def _reject(self, reason: str) -> None:
        self._count(rejected=1)
        self.last_error = reason
        log.debug("rejected frame: %s", reason)

    def _on_target(self, frame: TargetFrame) -> None:
        if self._last_counter.get(frame.group) == frame.counter:
            self._reject(f"stale target frame of group {frame.group} (counter {frame.counter} "
                         f"repeated)")
            return
        self._last_counter[frame.group] = frame.counter
        if self._model.apply_targets(frame.axes):
            self._count(targets=1)
        else:
            self._count(ignored=1)

    def _command(self, command: str) -> None:
        self._count(commands=1)
        try:
            self._model.command(command)
        except ValueError as exc:
            self._reject(str(exc))

    # ---- time ------------------------------------------------------------------------------

    def step(self, dt: float) -> None:
        """Take every pending frame off the bus, then advance the simulation by ``dt`` [s].

        Deterministic: the simulated time advances by exactly ``dt`` and due frames are sent.
        Not usable while the background thread runs.
        """
        if self.running:
            raise RuntimeError("step() cannot be used while the background thread runs")
        for _ in range(MAX_FRAMES_PER_STEP):
            msg = self._receive(0.0)
            if msg is None:
                break
            self.handle(msg)
        self._advance(dt)

    def _receive(self, timeout: float) -> can.Message | None:
        try:
            return self._bus.recv(timeout=timeout)
        except BUS_ERRORS as exc:
            with self._lock:
                self._reject(f"receive failed: {exc}")
            return None

    def _advance(self, dt: float) -> None:
        with self._lock:
            model = self._model
            model.advance(dt)
            if self._feedback.due(model.time):
                self._send_feedback()
            if self._heartbeat.due(model.time) and not self._silent:
                self._send(self._protocol.encode_heartbeat(model.state,
                                                           self._heartbeat_counter))
                self._heartbeat_counter += 1

    def _send_feedback(self) -> None:
        counter = self._feedback_counter
        try:
            frames = feedback_frames(self._protocol, self._model, counter, self._effort)
        except ProtocolError as exc:  # cannot happen with a validated initial pose; never crash
            self._count(send_errors=1)
            self.last_error = str(exc)
            return
        self._feedback_counter += 1
        for frame in frames:
            self._send(frame)

    def _send(self, msg: can.Message) -> None:
        try:
            self._bus.send(msg)
        except BUS_ERRORS as exc:
            self._count(send_errors=1)
            self.last_error = f"send failed: {exc}"
            log.debug("send failed: %s", exc)
        else:
            self._count(sent=1)

    # ---- background thread -----------------------------------------------------------------

    def start(self) -> None:
        """Run the manager in a background thread on the monotonic clock."""
        self._loop.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the background thread (no-op when not running); the bus stays open."""
        self._loop.stop(timeout)

    def __enter__(self) -> MotorManagerSim:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()


if __name__ == "__main__":  # ``python -m crawler_motion.sim.motor_manager``: the console script
    from crawler_motion.sim.manager_cli import main

    sys.exit(main())
