"""A simulated multi-axis motor manager speaking `crawler_motion.canbus.protocol` on any CAN bus.

Pure Python (no ROS). Every axis tracks its target at a speed limit [rad/s]; the manager sends
measured positions and status bits at ``rate`` [Hz] and a heartbeat every ``heartbeat_period``
[s], and obeys the MM_Control commands:

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
with `MotorManagerSim.start` / `MotorManagerSim.stop` on a monotonic clock; ``main`` runs it as
a process (``motor_manager_sim --help``).
"""

from __future__ import annotations

import logging
import math
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from types import FrameType
from typing import Any

import can
import numpy as np
from can.interfaces.udp_multicast import UdpMulticastBus

from crawler_motion.canbus.protocol import (
    AxisFlags,
    ControlFrame,
    MotorProtocol,
    TargetFrame,
)
from crawler_motion.errors import CrawlerMotionError, ProtocolError
from crawler_motion.tools.args import OneLineParser

log = logging.getLogger(__name__)

PROG = "motor_manager_sim"
FAULT_KINDS: tuple[str, ...] = ("over_current", "over_temp", "encoder_fault")
STATES: tuple[str, ...] = ("disabled", "enabled", "hold", "estop", "fault")
DEFAULT_SPEED_LIMIT = 2.0  # [rad/s]
DEFAULT_COMMAND_TIMEOUT = 0.2  # [s]
DEFAULT_RATE = 100.0  # [Hz] when the DBC gives no cycle time
DEFAULT_HEARTBEAT_PERIOD = 0.1  # [s] when the DBC gives no cycle time
#: Frames taken off the bus per `step` at most, so a flooding sender cannot stall the manager.
MAX_FRAMES_PER_STEP = 1000


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


def _positive(value: float, what: str) -> float:
    number = float(value)
    if not (math.isfinite(number) and number > 0):
        raise ValueError(f"{what} must be a finite number > 0, got {value!r}")
    return number


class MotorManagerSim:
    """The simulated manager on ``bus``; positions are axis positions in axis order [rad].

    ``initial_positions`` are joint angles in joint order [rad] (default: all zero, which is not
    the standing pose); ``speed_limit`` is one value or one per axis [rad/s]; ``rate`` [Hz] and
    ``heartbeat_period`` [s] default to the DBC's cycle times.
    """

    def __init__(self, bus: can.BusABC, protocol: MotorProtocol, *,
                 speed_limit: float | Sequence[float] = DEFAULT_SPEED_LIMIT,
                 rate: float | None = None, heartbeat_period: float | None = None,
                 command_timeout: float = DEFAULT_COMMAND_TIMEOUT,
                 initial_positions: Sequence[float] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        missing = [s for s in STATES if s not in protocol.states]
        if missing:
            raise ProtocolError(f"the DBC's MM_Heartbeat.State lacks the states {missing}")
        self._bus = bus
        self._protocol = protocol
        self._clock = clock
        n = protocol.n_axes
        speed = np.asarray(speed_limit, dtype=float).reshape(-1)
        if speed.size == 1:
            speed = np.full(n, float(speed[0]))
        if speed.shape != (n,) or not np.all(np.isfinite(speed)) or np.any(speed <= 0):
            raise ValueError(f"speed_limit must be one or {n} finite values > 0 rad/s, "
                             f"got {speed_limit!r}")
        self._speed = speed
        feedback_period = protocol.period("position")
        self._period = 1.0 / _positive(rate, "rate [Hz]") if rate is not None else (
            feedback_period or 1.0 / DEFAULT_RATE)
        self._heartbeat_period = _positive(
            heartbeat_period if heartbeat_period is not None
            else protocol.period("heartbeat") or DEFAULT_HEARTBEAT_PERIOD,
            "heartbeat_period [s]")
        self._command_timeout = _positive(command_timeout, "command_timeout [s]")
        q0 = np.zeros(n) if initial_positions is None else initial_positions
        self._pos = protocol.to_axis(q0)
        protocol.encode_feedback(self._pos, 0)  # refuses an initial pose it could not report
        self._target = self._pos.copy()
        self._state = "disabled"
        self._faults: list[set[str]] = [set() for _ in range(n)]  # active (injected) conditions
        self._latched: list[set[str]] = [set() for _ in range(n)]  # reported until reset
        self._stalled: set[int] = set()
        self._silent = False
        self._timed_out = False
        self._time = 0.0
        self._last_target_time = 0.0
        self._last_counter: dict[int, int] = {}
        self._next_feedback = 0.0
        self._next_heartbeat = 0.0
        self._feedback_counter = 0
        self._heartbeat_counter = 0
        self._counters = SimCounters()
        self.last_error = ""
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ---- observation -----------------------------------------------------------------------

    @property
    def state(self) -> str:
        """Manager state: one of `STATES`."""
        with self._lock:
            return self._state

    @property
    def positions(self) -> np.ndarray:
        """Measured axis positions in axis order [rad] (a copy)."""
        with self._lock:
            return self._pos.copy()

    @property
    def joint_positions(self) -> np.ndarray:
        """Measured positions as joint angles in joint order [rad]."""
        return self._protocol.to_joint(self.positions)

    @property
    def targets(self) -> np.ndarray:
        """Current axis targets in axis order [rad] (a copy)."""
        with self._lock:
            return self._target.copy()

    @property
    def time(self) -> float:
        """Simulated time since construction [s]."""
        with self._lock:
            return self._time

    @property
    def command_timed_out(self) -> bool:
        """True while the command timeout holds the axes."""
        with self._lock:
            return self._timed_out

    @property
    def counters(self) -> SimCounters:
        """A snapshot of the frame counters."""
        with self._lock:
            return self._counters

    @property
    def running(self) -> bool:
        """True while the background thread runs."""
        return self._thread is not None and self._thread.is_alive()

    @property
    def period(self) -> float:
        """Feedback period [s]."""
        return self._period

    @property
    def heartbeat_period(self) -> float:
        """Heartbeat period [s]."""
        return self._heartbeat_period

    # ---- fault injection -------------------------------------------------------------------

    def _axis(self, axis: int) -> int:
        if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or not (
                0 <= axis < self._protocol.n_axes):
            raise ValueError(f"axis must be an integer 0..{self._protocol.n_axes - 1}, "
                             f"got {axis!r}")
        return int(axis)

    def inject_axis_fault(self, axis: int, kind: str = "over_current") -> None:
        """Raise a fault condition on an axis: the manager stops and enters ``fault``."""
        if kind not in FAULT_KINDS:
            raise ValueError(f"fault kind must be one of {list(FAULT_KINDS)}, got {kind!r}")
        with self._lock:
            a = self._axis(axis)
            self._faults[a].add(kind)
            self._latched[a].add(kind)
            self._target = self._pos.copy()
            self._timed_out = False
            if self._state != "estop":
                self._state = "fault"

    def stall_axis(self, axis: int, stalled: bool = True) -> None:
        """Block (or free) an axis: it stops moving and reports the stalled bit."""
        with self._lock:
            a = self._axis(axis)
            if stalled:
                self._stalled.add(a)
            else:
                self._stalled.discard(a)

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
            for active in self._faults:
                active.clear()
            self._stalled.clear()

    # ---- frame handling --------------------------------------------------------------------

    def _count(self, **increments: int) -> None:
        counters = self._counters
        self._counters = replace(counters, **{k: getattr(counters, k) + v
                                              for k, v in increments.items()})

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
        if self._state != "enabled":
            self._count(ignored=1)
            return
        for axis, value in frame.axes.items():
            self._target[axis] = value
        self._last_target_time = self._time
        self._timed_out = False
        self._count(targets=1)

    def _command(self, command: str) -> None:
        self._count(commands=1)
        state = self._state
        if command == "estop":
            self._enter("estop")
        elif command == "reset":
            for active, latched in zip(self._faults, self._latched, strict=True):
                latched.intersection_update(active)
            if state in ("estop", "fault"):
                self._enter("fault" if any(self._faults) else "disabled")
        elif state in ("estop", "fault"):
            log.debug("command %s ignored in latched state %s", command, state)
        elif command == "enable":
            self._enter("enabled")
            self._last_target_time = self._time
        elif command == "disable":
            self._enter("disabled")
        elif command == "hold":
            self._enter("hold")
        else:  # a command the DBC knows but this manager does not implement
            self._reject(f"unsupported command {command!r}")

    def _enter(self, state: str) -> None:
        self._state = state
        self._target = self._pos.copy()
        self._timed_out = False

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
        except (can.CanError, OSError, ValueError) as exc:
            with self._lock:
                self._reject(f"receive failed: {exc}")
            return None

    def _advance(self, dt: float) -> None:
        if not (math.isfinite(dt) and dt >= 0):
            raise ValueError(f"dt must be a finite time >= 0 s, got {dt!r}")
        with self._lock:
            self._time += dt
            if (self._state == "enabled" and not self._timed_out
                    and self._time - self._last_target_time > self._command_timeout):
                self._timed_out = True
                self._target = self._pos.copy()
                log.debug("command timeout at t=%.3f s: holding", self._time)
            if self._state == "enabled" and not self._timed_out:
                step = np.clip(self._target - self._pos, -self._speed * dt, self._speed * dt)
                for axis in self._stalled:
                    step[axis] = 0.0
                self._pos += step
            if self._time >= self._next_feedback - 1e-9:
                self._send_feedback()
                self._next_feedback += self._period
                if self._next_feedback <= self._time:  # fell behind: do not burst
                    self._next_feedback = self._time + self._period
            if self._time >= self._next_heartbeat - 1e-9:
                if not self._silent:
                    self._send(self._protocol.encode_heartbeat(self._state,
                                                               self._heartbeat_counter))
                    self._heartbeat_counter += 1
                self._next_heartbeat += self._heartbeat_period
                if self._next_heartbeat <= self._time:
                    self._next_heartbeat = self._time + self._heartbeat_period

    def _flags(self) -> list[AxisFlags]:
        powered = self._state in ("enabled", "hold")
        following = self._state == "enabled" and not self._timed_out
        flags = []
        for axis in range(self._protocol.n_axes):
            latched = self._latched[axis]
            stalled = axis in self._stalled
            flags.append(AxisFlags(
                enabled=powered, tracking=following and not stalled,
                over_current="over_current" in latched, over_temp="over_temp" in latched,
                encoder_fault="encoder_fault" in latched, stalled=stalled,
                command_timeout=self._timed_out))
        return flags

    def _send_feedback(self) -> None:
        try:
            frames = self._protocol.encode_feedback(self._pos, self._feedback_counter)
            frames += self._protocol.encode_status(self._flags(), self._feedback_counter)
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
        except (can.CanError, OSError, ValueError) as exc:
            self._count(send_errors=1)
            self.last_error = f"send failed: {exc}"
            log.debug("send failed: %s", exc)
        else:
            self._count(sent=1)

    # ---- background thread -----------------------------------------------------------------

    def start(self) -> None:
        """Run the manager in a background thread on the monotonic clock."""
        if self.running:
            raise RuntimeError("the simulated manager is already running")
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=PROG, daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the background thread (no-op when not running); the bus stays open."""
        thread = self._thread
        if thread is None:
            return
        self._stop.set()
        thread.join(timeout)
        if thread.is_alive():
            raise RuntimeError(f"the simulated manager thread did not stop within {timeout} s")
        self._thread = None

    def __enter__(self) -> MotorManagerSim:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def _run(self) -> None:
        tick = min(self._period, self._heartbeat_period, 0.01)
        last = self._clock()
        next_tick = last
        while not self._stop.is_set():
            wait = next_tick - self._clock()
            if wait > 0:
                msg = self._receive(wait)
                if msg is not None:
                    self.handle(msg)
                    continue
            now = self._clock()
            try:
                self._advance(max(now - last, 0.0))
            except Exception as exc:  # keep the manager alive; the counters tell
                log.exception("simulation step failed")
                self.last_error = f"step failed: {exc}"
            last = now
            next_tick = now + tick


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------


def _parser() -> OneLineParser:
    default_group = UdpMulticastBus.DEFAULT_GROUP_IPv4
    parser = OneLineParser(prog=PROG, description="Simulated multi-axis motor manager of the "
                           "crawler: speaks config/motor_manager.dbc on a CAN bus until "
                           "SIGINT/SIGTERM.")
    parser.add_argument("--interface", default="udp_multicast",
                        help="python-can interface (default: %(default)s; e.g. socketcan)")
    parser.add_argument("--channel", default=None,
                        help=f"bus channel (default: {default_group} for udp_multicast, vcan0 "
                        f"for socketcan)")
    parser.add_argument("--port", type=int, default=43113,
                        help="UDP port of udp_multicast (default: %(default)s)")
    parser.add_argument("--rate", type=float, default=None,
                        help="feedback rate [Hz] (default: the DBC cycle time, 100 Hz)")
    parser.add_argument("--speed-limit", type=float, default=DEFAULT_SPEED_LIMIT,
                        help="axis speed limit [rad/s] (default: %(default)s)")
    parser.add_argument("--command-timeout", type=float, default=DEFAULT_COMMAND_TIMEOUT,
                        help="hold after this long without target frames [s] "
                        "(default: %(default)s)")
    parser.add_argument("--heartbeat-period", type=float, default=None,
                        help="heartbeat period [s] (default: the DBC cycle time, 0.1 s)")
    parser.add_argument("--initial-pose", choices=("mid", "zero"), default="mid",
                        help="joint angles at power-up: 'mid' = the middle of every joint's "
                             "limits (default), 'zero' = all zero (outside the knee limit)")
    parser.add_argument("--dbc", default=None, help="DBC file (default: the shipped one)")
    parser.add_argument("--axes", default=None, help="axis map YAML (default: the shipped one)")
    parser.add_argument("--config", default=None,
                        help="robot.yaml for joint names and limits (default: the shipped one)")
    return parser


def _open_bus(interface: str, channel: str | None, port: int) -> tuple[can.BusABC, str]:
    """Open the bus; returns it and a description such as ``udp_multicast 239.74.163.2:43113``."""
    kwargs: dict[str, Any] = {}
    if interface == "udp_multicast":
        default = UdpMulticastBus.DEFAULT_GROUP_IPv4
        channel = channel or default
        kwargs.update(port=port, receive_own_messages=False)
    elif interface == "socketcan":
        channel = channel or "vcan0"
    elif channel is None:
        raise ValueError(f"--channel is required for interface {interface!r}")
    where = f"{interface} {channel}" + (f":{port}" if interface == "udp_multicast" else "")
    try:
        return can.Bus(interface=interface, channel=channel, **kwargs), where
    except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as exc:
        # python-can warns "... was not properly shut down" when a half-built bus is collected
        logging.getLogger("can.bus").setLevel(logging.ERROR)
        raise ValueError(f"cannot open the CAN bus {where}: {exc}") from exc


def main(argv: Sequence[str] | None = None) -> int:
    """Run the simulated manager until SIGINT/SIGTERM; returns the exit code."""
    parser = _parser()
    args = parser.parse_args(argv)
    for name in ("rate", "speed_limit", "command_timeout", "heartbeat_period"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            parser.error(f"--{name.replace('_', '-')} must be a finite number > 0, "
                         f"got {value}")
    if not 0 < args.port < 65536:
        parser.error(f"--port must be 1..65535, got {args.port}")
    from crawler_motion.model.config import load_config  # heavy only when actually running

    try:
        config = load_config(args.config)
        protocol = MotorProtocol.from_config(config.robot, args.dbc, args.axes)
        bus, where = _open_bus(args.interface, args.channel, args.port)
    except (CrawlerMotionError, can.CanError, OSError, ValueError, ImportError,
            NotImplementedError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    stop = threading.Event()

    def _on_signal(signum: int, _frame: FrameType | None) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    sim: MotorManagerSim | None = None
    try:
        initial = (None if args.initial_pose == "zero"
                   else (protocol.lower + protocol.upper) / 2.0)
        sim = MotorManagerSim(bus, protocol, speed_limit=args.speed_limit, rate=args.rate,
                              initial_positions=initial,
                              heartbeat_period=args.heartbeat_period,
                              command_timeout=args.command_timeout)
        sim.start()
        print(f"{PROG}: running on {where}, feedback every "
              f"{sim.period:g} s, heartbeat every {sim.heartbeat_period:g} s", flush=True)
        while not stop.wait(0.2):
            if not sim.running:
                print(f"{PROG}: error: the manager thread stopped: {sim.last_error}",
                      file=sys.stderr)
                return 1
        sim.stop()
        print(f"{PROG}: stopped; {sim.counters}", flush=True)
        return 0
    except (CrawlerMotionError, ValueError, RuntimeError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    finally:
        if sim is not None and sim.running:
            sim.stop()
        bus.shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


if __name__ == "__main__":
    sys.exit(main())
