"""Bus handling, command watchdog, e-stop latch and feedback bookkeeping of the driver node.

Pure Python (no ROS): `DriverCore` works on any python-can `can.BusABC`, handed over directly or
built by a factory, so it can be unit-tested on a ``virtual`` bus or a stub that raises. The ROS
node (`crawler_motion.driver.node`) only converts messages and calls it.

Motion gate. Target frames go out only while the core is *active* (lifecycle), *enabled* (an
``enable`` was sent by `activate` or `enable`), no e-stop is latched and the command watchdog has
not tripped. Nothing but an e-stop (and the deactivation command) is ever sent while inactive.

Commands. `submit` validates one joint command (names, lengths, finite values, joint limits:
refused, never clipped), encodes it with `MotorProtocol.encode_targets` and sends it at once.
Only the newest command is kept: a command that could not be sent is retried by `tick` while it
is younger than one target period (the DBC's cycle time) and dropped after that, never sent late.

Watchdog (steady clock). It arms with the first command accepted after an ``enable``; then no
accepted command for ``command_timeout`` sends ``hold`` (or ``disable``) and blocks motion until
`enable` (or `activate`). An unarmed watchdog (enabled, no command yet) does nothing: the manager
holds its position anyway, and the planner is not punished for starting after the driver.

E-stop. `estop` latches within the call and sends the e-stop frame (retried until it goes out,
re-sent after a reopen and whenever the heartbeat reports the manager out of ``estop``). Only
`reset` clears the latch, and the motors then need `enable` again.

An ``enable`` is confirmed by the first heartbeat reporting ``enabled``. Until then, a heartbeat
reporting ``disabled`` (the manager came up after the enable, or the frame was lost) makes the
core send ``enable`` again, at most `MAX_ENABLE_RESENDS` times; a manager that confirmed and later
fell back to ``disabled`` (e.g. rebooted) is reported as an ERROR and needs an explicit `enable`.

Bus faults. Every send is tried ``1 + send_retries`` times without waiting; errors are counted.
A receive error, or `FAILED_FRAMES_BEFORE_REOPEN` frames in a row that could not be sent, mark
the bus down: an owned bus (from the factory) is shut down and rebuilt every ``reopen_period``,
an injected bus is simply tried again after ``reopen_period``. Nothing blocks: sends use a zero
timeout, and receiving waits only in `poll` (called by the background thread of `start`).

Feedback. A joint-state vector (joint order, joint space) is emitted through ``on_feedback``
once every position group (``MM_Position_<g>``) has been received since the last one, so each
emitted vector is one complete, fresh measurement of all joints. Status and heartbeat frames
update the state behind `status`. Frames that cannot be decoded (unknown id, wrong DLC, bad
checksum, out-of-range values...) are dropped and counted, never emitted.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import can
import numpy as np
from can.interfaces.udp_multicast import UdpMulticastBus

from crawler_motion.canbus.protocol import (
    AxisFlags,
    AxisStatus,
    Heartbeat,
    MotorProtocol,
    PositionFeedback,
)
from crawler_motion.errors import CrawlerMotionError, ProtocolError
from crawler_motion.planner.commands import as_float

#: Diagnostic levels (the values of diagnostic_msgs/DiagnosticStatus).
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR", STALE: "STALE"}

#: Timeout handed to ``bus.send``: never wait for a full transmit queue.
SEND_TIMEOUT = 0.0
#: Frames in a row that could not be sent (after their retries) before the bus is taken as down.
FAILED_FRAMES_BEFORE_REOPEN = 3
#: Frames taken off the bus per `DriverCore.poll` at most (a flooding bus cannot stall the loop).
MAX_FRAMES_PER_POLL = 500
#: Re-sends of an ``enable`` the manager never confirmed (it reports ``disabled`` instead).
MAX_ENABLE_RESENDS = 3
#: Period of the background loop of `DriverCore.start` [s]: watchdog and reopen resolution.
TICK_PERIOD = 0.005
#: Used when the DBC gives no cycle time.
DEFAULT_TARGET_PERIOD = 0.01
DEFAULT_HEARTBEAT_PERIOD = 0.1

ON_DEACTIVATE_CHOICES = ("disable", "hold")
ON_TIMEOUT_CHOICES = ("hold", "disable")


class DriverError(CrawlerMotionError):
    """The driver cannot do what was asked (e.g. the CAN bus cannot be opened)."""


# --------------------------------------------------------------------------------------------
# Parameters (one table for the node's descriptors and the validator)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ParamSpec:
    """One driver parameter: default, meaning, bounds; the node builds its descriptor from it."""

    name: str
    default: bool | int | float | str
    description: str
    read_only: bool = False
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[str, ...] = ()


PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("can_interface", "udp_multicast",
              "python-can interface: udp_multicast (cross-process on loopback), socketcan "
              "(vcan0 / can0), virtual (in-process), ...", read_only=True),
    ParamSpec("can_channel", UdpMulticastBus.DEFAULT_GROUP_IPv4,
              "bus channel: multicast group for udp_multicast, interface name for socketcan",
              read_only=True),
    ParamSpec("can_port", 0, "UDP port of udp_multicast; 0 = the interface default (43113)",
              read_only=True, minimum=0, maximum=65535),
    ParamSpec("bitrate", 1_000_000, "CAN bitrate [bit/s] for interfaces that set it",
              read_only=True, minimum=10_000, maximum=1_000_000),
    ParamSpec("dbc_file", "", "DBC file of the motor-manager protocol (default: the shipped "
              "config/motor_manager.dbc)", read_only=True),
    ParamSpec("axes_file", "", "joint-to-axis map YAML (default: the shipped config/axes.yaml)",
              read_only=True),
    ParamSpec("config_file", "", "robot.yaml with joint names and limits (default: the shipped "
              "config/robot.yaml)", read_only=True),
    ParamSpec("autostart", False, "configure and activate right after start-up",
              read_only=True),
    ParamSpec("priority", 0, "0: normal scheduling; 1-99: SCHED_FIFO priority of the driver "
              "process, as real-time drivers run (needs CAP_SYS_NICE)", read_only=True,
              minimum=0, maximum=99),
    ParamSpec("on_deactivate", "hold", "manager command sent on deactivation: hold (axes "
              "powered, holding) or disable (axes unpowered)", choices=ON_DEACTIVATE_CHOICES),
    ParamSpec("command_timeout", 0.2, "command watchdog [s]: no joint_commands for this long "
              "sends on_timeout and blocks motion until ~/enable", minimum=0.02, maximum=10.0),
    ParamSpec("on_timeout", "hold", "manager command sent when the watchdog trips: hold or "
              "disable", choices=ON_TIMEOUT_CHOICES),
    ParamSpec("heartbeat_timeout_periods", 3, "heartbeat periods without a heartbeat before "
              "the manager is reported lost (ERROR)", minimum=1, maximum=100),
    ParamSpec("diagnostics_period", 1.0, "period of /diagnostics [s]", minimum=0.05,
              maximum=60.0),
    ParamSpec("send_retries", 2, "immediate retries of a frame the bus refused (bounded; no "
              "waiting)", minimum=0, maximum=10),
    ParamSpec("reopen_period", 0.2, "period of reopen attempts while the bus is down [s]",
              minimum=0.01, maximum=1.0),
)
PARAMETER_SPECS: dict[str, ParamSpec] = {p.name: p for p in PARAMETERS}
#: File parameters whose empty default means "the shipped file" (see `default_files`).
FILE_PARAMETERS = {"dbc_file": "motor_manager.dbc", "axes_file": "axes.yaml",
                   "config_file": "robot.yaml"}


def default_files() -> dict[str, str]:
    """The shipped configuration files, as the defaults of the file parameters."""
    from crawler_motion.model.config import config_path

    return {name: str(config_path(file)) for name, file in FILE_PARAMETERS.items()}


def validate_parameter(name: str, value: Any) -> str | None:
    """Why ``value`` is not acceptable for the parameter ``name``; None when it is."""
    spec = PARAMETER_SPECS.get(name)
    if spec is None:
        return f"unknown parameter {name!r}; the driver knows {sorted(PARAMETER_SPECS)}"
    kind = type(spec.default)
    if kind is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    else:
        ok = type(value) is kind
    if not ok:
        return f"{name} must be a {kind.__name__}, got {value!r}"
    if kind is str:
        if name in FILE_PARAMETERS or name == "can_channel":
            if not value.strip():
                return f"{name} must not be empty"
        if spec.choices and value not in spec.choices:
            return f"{name} must be one of {list(spec.choices)}, got {value!r}"
        if name == "can_interface" and value not in can.VALID_INTERFACES:
            return (f"can_interface {value!r} is not a python-can interface; use one of "
                    f"{sorted(can.VALID_INTERFACES)}")
        return None
    if kind in (int, float):
        if not math.isfinite(value):
            return f"{name} must be finite, got {value!r}"
        if spec.minimum is not None and spec.maximum is not None and not (
                spec.minimum <= value <= spec.maximum):
            return f"{name} must be within [{spec.minimum:g}, {spec.maximum:g}], got {value!r}"
    return None


def validate_parameters(values: Mapping[str, Any]) -> list[str]:
    """Every reason why ``values`` (name -> value) is not acceptable; empty when all are."""
    return [reason for name, value in values.items()
            if (reason := validate_parameter(name, value)) is not None]


def bus_kwargs(interface: str, channel: str, port: int = 0,
               bitrate: int = 1_000_000) -> dict[str, Any]:
    """Keyword arguments of ``can.Bus`` for the driver's bus parameters."""
    kwargs: dict[str, Any] = {"interface": interface, "channel": channel}
    if interface == "udp_multicast":
        kwargs["receive_own_messages"] = False
        if port:
            kwargs["port"] = int(port)
    elif interface not in ("virtual", "socketcan"):  # socketcan's bitrate is set by ip link
        kwargs["bitrate"] = int(bitrate)
    return kwargs


def make_bus_factory(interface: str, channel: str, port: int = 0,
                     bitrate: int = 1_000_000) -> Callable[[], can.BusABC]:
    """A factory opening the driver's bus from its parameters."""
    kwargs = bus_kwargs(interface, channel, port, bitrate)

    def factory() -> can.BusABC:
        return can.Bus(**kwargs)

    return factory


@dataclass(frozen=True)
class DriverSettings:
    """The run-time settings of `DriverCore` (the changeable driver parameters)."""

    command_timeout: float = 0.2
    on_timeout: str = "hold"
    on_deactivate: str = "hold"
    heartbeat_timeout_periods: int = 3
    send_retries: int = 2
    reopen_period: float = 0.2

    def __post_init__(self) -> None:
        reasons = validate_parameters({f.name: getattr(self, f.name) for f in fields(self)})
        if reasons:
            raise ValueError("; ".join(reasons))

    @classmethod
    def from_parameters(cls, values: Mapping[str, Any]) -> DriverSettings:
        """Settings from a parameter mapping (other keys are ignored)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in values.items() if k in names})


# --------------------------------------------------------------------------------------------
# Results and reports
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CommandResult:
    """What `DriverCore.submit` did with a command: ``sent``, or why not."""

    accepted: bool  # valid and allowed to move (sent, or pending a retry)
    reason: str = ""
    sent: bool = False  # every target frame went out within the call


@dataclass(frozen=True)
class DriverCounters:
    """Counters of the driver core (monotonic while it lives)."""

    tx: int = 0  # frames sent
    tx_errors: int = 0  # send attempts the bus refused (each retry counts)
    tx_stale: int = 0  # commands dropped unsent: older than one period, or superseded
    rx: int = 0  # frames received
    rx_dropped: int = 0  # undecodable frames: unknown id, wrong DLC, checksum, range...
    rx_ignored: int = 0  # valid controller-side frames (our own echo, another controller)
    commands: int = 0  # joint commands accepted and encoded
    refused: int = 0  # joint commands refused as invalid
    blocked: int = 0  # valid joint commands not sent: e-stop, watchdog, not enabled
    inactive: int = 0  # joint commands dropped while inactive
    feedback: int = 0  # complete joint-state vectors emitted
    bus_failures: int = 0  # times the bus was taken as down
    reopens: int = 0  # successful reopen attempts
    reopen_failures: int = 0  # failed reopen attempts
    watchdog_trips: int = 0
    estops: int = 0  # e-stop requests


@dataclass(frozen=True)
class StatusEntry:
    """One diagnostic status: ``level`` is one of OK, WARN, ERROR, STALE."""

    name: str
    level: int
    message: str
    values: tuple[tuple[str, str], ...]


def _age(now: float, then: float | None) -> str:
    return "never" if then is None else f"{now - then:.3f}"


# --------------------------------------------------------------------------------------------
# The core
# --------------------------------------------------------------------------------------------


class DriverCore:
    """The driver's bus side for one `MotorProtocol`.

    Give exactly one of ``bus`` (not owned: never shut down by the core) or ``bus_factory``
    (called by `open` and by every reopen; the core shuts those buses down). ``clock`` is a
    steady clock [s]; ``on_feedback(positions)`` receives each complete joint-state vector in
    joint order [rad] (from the thread calling `poll`). ``logger`` needs ``info``, ``warning``
    and ``error`` taking one string (a `logging.Logger` or an rclpy logger).

    Thread-safe: the public methods may be called from any thread; `start` runs `poll` and
    `tick` in a background thread.
    """

    def __init__(self, protocol: MotorProtocol, bus: can.BusABC | None = None, *,
                 bus_factory: Callable[[], can.BusABC] | None = None,
                 settings: DriverSettings | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 on_feedback: Callable[[np.ndarray], None] | None = None,
                 logger: Any = None) -> None:
        if (bus is None) == (bus_factory is None):
            raise ValueError("give exactly one of bus and bus_factory")
        self.protocol = protocol
        self._given_bus = bus
        self._factory = bus_factory
        self._settings = settings or DriverSettings()
        self._clock = clock
        self._on_feedback = on_feedback
        self._log = logger or logging.getLogger(__name__)
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        names = protocol.joint_names
        self._index = {name: i for i, name in enumerate(names)}
        self._lower = protocol.lower
        self._upper = protocol.upper
        self._target_period = protocol.period("target") or DEFAULT_TARGET_PERIOD
        self._hb_period = protocol.period("heartbeat") or DEFAULT_HEARTBEAT_PERIOD
        self._position_groups = len(protocol.frame_ids("position"))
        self._n = dict.fromkeys((f.name for f in fields(DriverCounters)), 0)
        # bus
        self._bus: can.BusABC | None = None
        self._opened = False
        self._bus_ok = False
        self._to_close: can.BusABC | None = None
        self._down_since: float | None = None
        self._next_reopen = 0.0
        self._failed_frames = 0
        self._open_time: float | None = None
        self.last_tx_error = ""
        self.last_rx_error = ""
        self.last_refusal = ""
        # motion state
        self._active = False
        self._enabled = False
        self._estop = False
        self._estop_reason = ""
        self._tripped = False
        self._last_command: float | None = None
        self._armed = False
        self._counter = 0
        self._pending_targets: list[can.Message] = []
        self._pending_time = 0.0
        self._pending_control: str | None = None
        self._last_control: tuple[str, float] | None = None
        self._last_estop_tx = -math.inf
        self._last_enable_tx = -math.inf
        self._enable_confirmed = False
        self._enable_resends = 0
        # feedback
        self._reset_feedback()
        self._log_times: dict[str, float] = {}

    def _reset_feedback(self) -> None:
        n = self.protocol.n_axes
        self._positions = np.full(n, np.nan)
        self._fresh: set[int] = set()
        self._last_counter: dict[tuple[type, int], int] = {}  # (frame type, group) -> counter
        self._position_time: float | None = None
        self._flags: dict[int, AxisFlags] = {}
        self._flags_time: dict[int, float] = {}
        self._heartbeat: Heartbeat | None = None
        self._heartbeat_time: float | None = None

    # ---- observation -----------------------------------------------------------------------

    @property
    def settings(self) -> DriverSettings:
        """The current settings."""
        return self._settings

    @property
    def counters(self) -> DriverCounters:
        """A snapshot of the counters."""
        with self._lock:
            return DriverCounters(**self._n)

    @property
    def is_open(self) -> bool:
        """True between `open` and `close` (also while the bus is down and being reopened)."""
        return self._opened

    @property
    def bus_ok(self) -> bool:
        """True while the bus is open and not taken as down."""
        return self._opened and self._bus_ok

    @property
    def active(self) -> bool:
        """True between `activate` and `deactivate`."""
        return self._active

    @property
    def enabled(self) -> bool:
        """True while the driver has the motors enabled (an ``enable`` was sent)."""
        return self._enabled

    @property
    def estop_latched(self) -> bool:
        """True from `estop` until `reset`."""
        return self._estop

    @property
    def estop_reason(self) -> str:
        """Why the ESTOP was latched ("" when it is not)."""
        return self._estop_reason

    @property
    def watchdog_tripped(self) -> bool:
        """True from a watchdog trip until `enable` / `activate`."""
        return self._tripped

    @property
    def motion_allowed(self) -> bool:
        """True when a valid command would be sent now."""
        return self._active and self._enabled and not self._estop and not self._tripped

    @property
    def positions(self) -> np.ndarray:
        """Last measured joint angles in joint order [rad] (NaN where none was received)."""
        with self._lock:
            return self._positions.copy()

    @property
    def heartbeat(self) -> Heartbeat | None:
        """The last heartbeat, None before the first one."""
        return self._heartbeat

    @property
    def axis_flags(self) -> dict[int, AxisFlags]:
        """The last status bits per axis index."""
        with self._lock:
            return dict(self._flags)

    def update_settings(self, settings: DriverSettings) -> None:
        """Apply new settings (takes effect at the next command / tick)."""
        with self._lock:
            self._settings = settings

    # ---- bus life cycle --------------------------------------------------------------------

    def open(self) -> None:
        """Open the bus; `DriverError` if it cannot be opened (nothing is left open then)."""
        with self._lock:
            if self._opened:
                return
            if self._given_bus is not None:
                bus = self._given_bus
            else:
                try:
                    bus = self._factory()
                except Exception as exc:
                    raise DriverError(f"cannot open the CAN bus: {type(exc).__name__}: "
                                      f"{exc}") from exc
            self._bus = bus
            self._opened = True
            self._bus_ok = True
            self._down_since = None
            self._failed_frames = 0
            self._open_time = self._clock()
            self._reset_feedback()

    def close(self) -> None:
        """Stop the background thread, forget the motion state and close an owned bus."""
        self.stop()
        with self._lock:
            self._opened = False
            self._bus_ok = False
            self._active = False
            self._enabled = False
            self._tripped = False
            self._pending_targets = []
            self._pending_control = None
            closing = [b for b in (self._bus, self._to_close) if b is not None]
            self._bus = None
            self._to_close = None
        if self._factory is not None:
            for bus in closing:
                self._shutdown(bus)

    @staticmethod
    def _shutdown(bus: can.BusABC) -> None:
        try:
            bus.shutdown()
        except Exception:  # a broken bus may fail to close; it is dropped either way
            logging.getLogger(__name__).debug("bus shutdown failed", exc_info=True)

    def _bus_failed(self, reason: str) -> None:
        """Take the bus as down (lock held); the next `tick` closes it and reopens later."""
        if not self._bus_ok:
            return
        now = self._clock()
        self._bus_ok = False
        self._down_since = now
        self._next_reopen = now + self._settings.reopen_period
        self._n["bus_failures"] += 1
        if self._factory is not None:
            self._to_close, self._bus = self._bus, None
        self._throttled("bus", "error", f"CAN bus down ({reason}); reopening every "
                        f"{self._settings.reopen_period:g} s")

    def _reopen(self) -> None:
        """Close a failed bus and try to open it again when due (no lock held on entry)."""
        with self._lock:
            closing, self._to_close = self._to_close, None
            now = self._clock()
            due = self._opened and not self._bus_ok and now >= self._next_reopen
            if due:
                self._next_reopen = now + self._settings.reopen_period
        if closing is not None:
            self._shutdown(closing)
        if not due:
            return
        if self._factory is None:  # an injected bus: try it again
            with self._lock:
                if self._opened and not self._bus_ok:
                    self._bus_back()
            return
        try:
            bus = self._factory()
        except Exception as exc:
            with self._lock:
                self._n["reopen_failures"] += 1
                self.last_tx_error = f"reopen failed: {type(exc).__name__}: {exc}"
            return
        with self._lock:
            if not self._opened or self._bus_ok:  # closed (or reopened) meanwhile
                stale = bus
            else:
                stale = None
                self._bus = bus
                self._bus_back()
        if stale is not None:
            self._shutdown(stale)

    def _bus_back(self) -> None:
        self._bus_ok = True
        self._failed_frames = 0
        self._n["reopens"] += 1
        down = self._clock() - (self._down_since or self._clock())
        self._down_since = None
        self._say("info", f"CAN bus back after {down:.3f} s")
        if self._estop and self._pending_control is None:
            self._pending_control = "estop"  # the manager may have missed it
        self._flush(self._clock())

    # ---- background loop -------------------------------------------------------------------

    def start(self) -> None:
        """Run `poll` and `tick` in a background thread until `stop` / `close`."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="crawler-driver-can",
                                        daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the background thread (no-op when it does not run)."""
        thread = self._thread
        if thread is None:
            return
        self._stop.set()
        if thread is not threading.current_thread():
            thread.join(timeout)
        self._thread = None

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self.poll(TICK_PERIOD)
                self.tick()
            except Exception as exc:  # the loop must outlive any surprise; the log tells
                self._throttled("loop", "error", f"driver loop error: {type(exc).__name__}: "
                                f"{exc}")
                self._stop.wait(TICK_PERIOD)

    # ---- sending ---------------------------------------------------------------------------

    def _send_frame(self, msg: can.Message) -> bool:
        """Send one frame with bounded immediate retries (lock held); True when it went out."""
        bus = self._bus
        if bus is None or not self._bus_ok:
            return False
        for _ in range(1 + self._settings.send_retries):
            try:
                bus.send(msg, timeout=SEND_TIMEOUT)
            except Exception as exc:  # CanError, OSError, ... from any interface
                self._n["tx_errors"] += 1
                self.last_tx_error = f"{type(exc).__name__}: {exc}"
                continue
            self._n["tx"] += 1
            self._failed_frames = 0
            return True
        self._failed_frames += 1
        self._throttled("tx", "warning", f"frame 0x{msg.arbitration_id:03X} not sent after "
                        f"{1 + self._settings.send_retries} attempts: {self.last_tx_error}")
        if self._failed_frames >= FAILED_FRAMES_BEFORE_REOPEN:
            self._bus_failed(f"{self._failed_frames} frames in a row could not be sent: "
                             f"{self.last_tx_error}")
        return False

    def _control(self, command: str) -> bool:
        """Queue a manager command (replacing a queued one) and try to send it (lock held)."""
        self._pending_control = command
        return self._flush(self._clock())

    def _flush(self, now: float) -> bool:
        """Send the queued control command, then the queued targets (lock held).

        Returns True when nothing is left queued.
        """
        if self._pending_control is not None:
            command = self._pending_control
            if not self._send_frame(self.protocol.encode_control(command)):
                return False
            self._pending_control = None
            self._last_control = (command, now)
            if command == "estop":
                self._last_estop_tx = now
            elif command == "enable":
                self._last_enable_tx = now
                self._enable_confirmed = False
        if self._pending_targets:
            if not self.motion_allowed:
                self._pending_targets = []
                return True
            if now - self._pending_time > self._target_period:
                self._n["tx_stale"] += 1
                self._pending_targets = []
                return True
            while self._pending_targets:
                if not self._send_frame(self._pending_targets[0]):
                    return False
                self._pending_targets.pop(0)
        return True

    # ---- lifecycle and safety commands -----------------------------------------------------

    def activate(self) -> tuple[bool, str]:
        """Enable the motors and start forwarding commands; (ok, why not / what happened)."""
        with self._lock:
            if not self._opened:
                return False, "the bus is not open (configure first)"
            if self._estop:
                return False, (f"ESTOP is latched ({self._estop_reason}); call ~/reset "
                               f"before activating")
            self._active = True
            return self._enable_locked()

    def deactivate(self) -> str:
        """Stop forwarding and send ``on_deactivate`` (only ``disable`` if not enabled)."""
        with self._lock:
            was_active, self._active = self._active, False
            self._pending_targets = []
            if not (self._opened and was_active) or self._estop:
                return "nothing sent"
            command = self._settings.on_deactivate
            if command == "hold" and not self._enabled:
                command = "disable"  # hold would power unpowered axes
            self._enabled = False
            self._tripped = False
            sent = self._control(command)
            return f"{command} {'sent' if sent else 'queued (bus down)'}"

    def enable(self) -> tuple[bool, str]:
        """Re-enable after a watchdog trip, a reset or an ``on_timeout: disable``."""
        with self._lock:
            if not self._opened:
                return False, "not configured"
            if not self._active:
                return False, "not active: activate the driver"
            if self._estop:
                return False, f"ESTOP is latched ({self._estop_reason}); call ~/reset first"
            return self._enable_locked()

    def _enable_locked(self) -> tuple[bool, str]:
        self._enable_resends = 0
        self._enabled = True
        self._tripped = False
        self._armed = False
        self._last_command = None
        self._pending_targets = []
        sent = self._control("enable")
        return True, "enable sent" if sent else "enable queued (bus down); retrying"

    def estop(self, reason: str = "requested") -> bool:
        """Latch ESTOP and send the e-stop frame; True when the frame went out now."""
        with self._lock:
            self._n["estops"] += 1
            if not self._estop:
                self._estop_reason = reason
                self._say("error", f"ESTOP latched: {reason}")
            self._estop = True
            self._enabled = False
            self._pending_targets = []
            if not self._opened:
                return False
            return self._control("estop")

    def reset(self) -> tuple[bool, str]:
        """Clear the ESTOP latch and send ``reset``; the motors then need `enable`."""
        with self._lock:
            self._estop = False
            self._estop_reason = ""
            self._enabled = False
            self._tripped = False
            self._pending_targets = []
            if not self._opened:
                return True, "latch cleared (no bus open)"
            sent = self._control("reset")
            return True, ("reset sent" if sent else "reset queued (bus down)") + (
                "; motors disabled: call ~/enable")

    # ---- commands --------------------------------------------------------------------------

    def submit(self, names: Sequence[str], positions: Sequence[float],
               velocities: Sequence[float] = (), efforts: Sequence[float] = ()) -> CommandResult:
        """Validate, encode and send one joint command (names and positions [rad])."""
        with self._lock:
            if not self._active:
                self._n["inactive"] += 1
                return CommandResult(False, "inactive: commands are dropped")
            try:
                q = self._validate(names, positions, velocities, efforts)
                frames = self.protocol.encode_targets(q, self._counter + 1)
            except ProtocolError as exc:
                self._n["refused"] += 1
                self.last_refusal = str(exc)
                return CommandResult(False, str(exc))
            if not self.motion_allowed:
                self._n["blocked"] += 1
                return CommandResult(False, self._blocked_reason())
            now = self._clock()
            self._counter += 1
            self._n["commands"] += 1
            self._last_command = now
            self._armed = True
            if self._pending_targets:  # an older command never went out: superseded
                self._n["tx_stale"] += 1
            self._pending_targets = list(frames)
            self._pending_time = now
            done = self._flush(now)
            return CommandResult(True, "sent" if done else "queued: bus busy or down",
                                 sent=done and not self._pending_targets)

    def _blocked_reason(self) -> str:
        if self._estop:
            return f"ESTOP latched ({self._estop_reason}): ~/reset then ~/enable"
        if self._tripped:
            return "command watchdog tripped: call ~/enable (or deactivate + activate)"
        return "motors not enabled: call ~/enable"

    def _validate(self, names: Sequence[str], positions: Sequence[float],
                  velocities: Sequence[float], efforts: Sequence[float]) -> np.ndarray:
        names = [str(n) for n in names]
        if len(positions) != len(names):
            raise ProtocolError(f"joint command has {len(names)} names but {len(positions)} "
                                f"positions")
        for values, what in ((velocities, "velocities"), (efforts, "efforts")):
            if len(values) not in (0, len(names)):
                raise ProtocolError(f"joint command has {len(names)} names but "
                                    f"{len(values)} {what} (0 or {len(names)} allowed)")
        counts = Counter(names)
        duplicate = sorted(n for n, c in counts.items() if c > 1)
        missing = [j for j in self.protocol.joint_names if j not in counts]
        extra = sorted(n for n in counts if n not in self._index)
        if duplicate or missing or extra:
            raise ProtocolError(f"joint command must name each of the {len(self._index)} "
                                f"joints once; duplicate {duplicate}, missing {missing}, "
                                f"unknown {extra}")
        q = np.empty(len(self._index))
        for name, value in zip(names, positions, strict=True):
            number = as_float(value)
            if number is None:
                raise ProtocolError(f"joint command positions must be numbers [rad], got "
                                    f"{value!r:.40} for {name}")
            q[self._index[name]] = number
        bad = [f"{self.protocol.joint_names[i]}={q[i]}" for i in np.flatnonzero(~np.isfinite(q))]
        if bad:
            raise ProtocolError(f"joint command has non-finite positions: {', '.join(bad)}")
        # velocities are not sent, but a NaN or a string means a broken sender
        for name, value in zip(names, velocities, strict=False):  # 0 or n of them
            number = as_float(value)
            if number is None or not math.isfinite(number):
                raise ProtocolError(f"joint command velocities must be finite numbers [rad/s], "
                                    f"got {value!r:.40} for {name}")
        out = [f"{self.protocol.joint_names[i]}={q[i]:.6g} not in [{self._lower[i]:g}, "
               f"{self._upper[i]:g}]" for i in np.flatnonzero((q < self._lower)
                                                               | (q > self._upper))]
        if out:
            raise ProtocolError(f"joint command outside the joint limits (refused, not "
                                f"clipped): {', '.join(out)} rad")
        return q

    # ---- time ------------------------------------------------------------------------------

    def tick(self) -> None:
        """Watchdog, retries of queued frames, e-stop re-assertion and bus reopening."""
        self._reopen()
        with self._lock:
            if not self._opened:
                return
            now = self._clock()
            s = self._settings
            if (self._active and self._enabled and not self._estop and not self._tripped
                    and self._armed and self._last_command is not None
                    and now - self._last_command > s.command_timeout):
                self._tripped = True
                self._n["watchdog_trips"] += 1
                self._pending_targets = []
                if s.on_timeout == "disable":
                    self._enabled = False
                self._say("error", f"command watchdog: no joint_commands for "
                                f"{now - self._last_command:.3f} s (> {s.command_timeout:g} "
                                f"s); sent {s.on_timeout}, call ~/enable to resume")
                self._control(s.on_timeout)
            elif self._pending_control is not None or self._pending_targets:
                self._flush(now)

    # ---- receiving -------------------------------------------------------------------------

    def poll(self, timeout: float = 0.0) -> int:
        """Take pending frames off the bus (waiting up to ``timeout`` for the first one).

        Returns the number of frames handled. Feedback callbacks run outside the lock.
        """
        handled = 0
        wait = max(float(timeout), 0.0)
        while handled < MAX_FRAMES_PER_POLL:
            with self._lock:
                bus = self._bus if (self._opened and self._bus_ok) else None
            if bus is None:
                if wait > 0:
                    self._stop.wait(wait)
                return handled
            try:
                msg = bus.recv(timeout=wait)
            except Exception as exc:  # bus gone / interface down
                with self._lock:
                    self.last_rx_error = f"receive failed: {type(exc).__name__}: {exc}"
                    if bus is self._bus:
                        self._bus_failed(self.last_rx_error)
                return handled
            if msg is None:
                return handled
            wait = 0.0
            handled += 1
            with self._lock:
                emit = self._handle(msg, self._clock())
            if emit is not None and self._on_feedback is not None:
                self._on_feedback(emit)
        return handled

    def _handle(self, msg: can.Message, now: float) -> np.ndarray | None:
        self._n["rx"] += 1
        if self.protocol.sender(msg) == "controller":
            self._n["rx_ignored"] += 1  # our own echo or another controller: not decoded
            return None
        try:
            frame = self.protocol.decode(msg)
        except Exception as exc:  # ProtocolError, or a malformed Message object
            self._n["rx_dropped"] += 1
            self.last_rx_error = str(exc)
            return None
        if isinstance(frame, (PositionFeedback, AxisStatus)):
            key = (type(frame), frame.group)
            if self._last_counter.get(key) == frame.counter:  # stuck sender or replay: stale
                self._n["rx_dropped"] += 1
                self.last_rx_error = (f"{type(frame).__name__} group {frame.group}: counter "
                                      f"{frame.counter} repeated (stale frame)")
                return None
            self._last_counter[key] = frame.counter
        if isinstance(frame, PositionFeedback):
            for joint, value in frame.positions.items():
                self._positions[self._index[joint]] = value
            self._fresh.add(frame.group)
            if len(self._fresh) >= self._position_groups:
                self._fresh.clear()
                self._position_time = now
                self._n["feedback"] += 1
                return self._positions.copy()
        elif isinstance(frame, AxisStatus):
            for axis, flags in frame.axes.items():
                self._flags[axis] = flags
                self._flags_time[axis] = now
        elif isinstance(frame, Heartbeat):
            self._heartbeat = frame
            self._heartbeat_time = now
            if (self._estop and frame.state != "estop" and self._pending_control is None
                    and now - self._last_estop_tx > self._hb_period):
                self._control("estop")  # the manager left (or never saw) the e-stop
            elif frame.state == "enabled":
                self._enable_confirmed = True
            elif (frame.state == "disabled" and self._enabled and not self._enable_confirmed
                  and not self._tripped and self._pending_control is None
                  and now - self._last_enable_tx > self._hb_period
                  and self._enable_resends < MAX_ENABLE_RESENDS):
                # our enable never arrived (the manager came up after it): send it again; a
                # manager that had confirmed it and fell back to disabled needs ~/enable
                self._enable_resends += 1
                self._control("enable")
        else:  # a target or control frame: our own echo or another controller
            self._n["rx_ignored"] += 1
        return None

    # ---- reporting -------------------------------------------------------------------------

    def _say(self, level: str, message: str) -> None:
        """Log without ever raising: logging must not break the safety path.

        One call line per severity: rclpy's logger refuses a call site whose severity changes.
        """
        try:
            if level == "error":
                self._log.error(message)
            elif level == "warning":
                self._log.warning(message)
            else:
                self._log.info(message)
        except Exception:
            logging.getLogger(__name__).debug("logging failed", exc_info=True)

    def _throttled(self, key: str, level: str, message: str, period: float = 1.0) -> None:
        now = time.monotonic()
        if now - self._log_times.get(key, -math.inf) >= period:
            self._log_times[key] = now
            self._say(level, message)

    def heartbeat_timeout(self) -> float:
        """Silence after which the manager is reported lost [s]."""
        return self._settings.heartbeat_timeout_periods * self._hb_period

    def status(self) -> list[StatusEntry]:
        """Diagnostic entries: the manager/driver state, the bus, one per axis."""
        with self._lock:
            now = self._clock()
            return [self._manager_status(now), self._bus_status(now),
                    *self._axis_statuses(now)]

    def _manager_status(self, now: float) -> StatusEntry:
        errors: list[str] = []
        warnings: list[str] = []
        hb_timeout = self.heartbeat_timeout()
        state = self._heartbeat.state if self._heartbeat else "unknown"
        if not self._opened:
            warnings.append("not configured")
        elif not self._bus_ok:
            errors.append(f"CAN bus down for {now - (self._down_since or now):.3f} s")
        if self._opened:
            if self._heartbeat_time is None:
                silent = now - (self._open_time or now)
                if silent > hb_timeout:
                    errors.append(f"no heartbeat from the motor manager for {silent:.3f} s")
                else:
                    warnings.append("waiting for the first heartbeat")
            elif now - self._heartbeat_time > hb_timeout:
                errors.append(f"heartbeat missing for {now - self._heartbeat_time:.3f} s "
                              f"(> {self._settings.heartbeat_timeout_periods} periods of "
                              f"{self._hb_period:g} s)")
            elif state in ("estop", "fault"):
                errors.append(f"motor manager in state {state}")
            elif (self._enabled and not self._tripped and state == "disabled"
                  and self._heartbeat_time - self._last_enable_tx > self._hb_period):
                errors.append("motor manager is disabled although the driver enabled it; "
                              "call ~/enable")
        faults = [self.protocol.axis_map[self._index_of_axis(a)].joint
                  for a, f in sorted(self._flags.items()) if f.fault]
        if faults:
            errors.append(f"fault bits on {', '.join(faults)}")
        stalled = [self.protocol.axis_map[self._index_of_axis(a)].joint
                   for a, f in sorted(self._flags.items()) if f.stalled and not f.fault]
        if stalled:
            errors.append(f"stalled (not following the target): {', '.join(stalled)}")
        if self._estop:
            errors.append(f"ESTOP latched ({self._estop_reason}): ~/reset then ~/enable")
        if self._tripped:
            errors.append(f"command watchdog tripped ({self._settings.on_timeout} sent): "
                          f"call ~/enable")
        if self._opened and not self._active:
            warnings.append("inactive: joint_commands are dropped")
        elif self._active and not self._enabled and not self._estop:
            errors.append("motors not enabled: call ~/enable")  # motion blocked: gait pauses
        level = ERROR if errors else WARN if warnings else OK
        message = "; ".join(errors + warnings) or "enabled, forwarding joint_commands"
        hb_age = _age(now, self._heartbeat_time)
        control = self._last_control
        values = (
            ("manager_state", state),
            ("heartbeat_age", hb_age),
            ("heartbeat_timeout", f"{hb_timeout:g}"),
            ("command_age", _age(now, self._last_command)),
            ("command_timeout", f"{self._settings.command_timeout:g}"),
            ("feedback_age", _age(now, self._position_time)),
            ("active", str(self._active)),
            ("enabled", str(self._enabled)),
            ("estop_latched", str(self._estop)),
            ("estop_reason", self._estop_reason),
            ("watchdog_tripped", str(self._tripped)),
            ("last_control", f"{control[0]} ({now - control[1]:.3f} s ago)" if control
             else "none"),
            ("pending_control", self._pending_control or "none"),
            ("commands", str(self._n["commands"])),
            ("refused", str(self._n["refused"])),
            ("blocked", str(self._n["blocked"])),
            ("dropped_inactive", str(self._n["inactive"])),
            ("last_refusal", self.last_refusal),
        )
        return StatusEntry("motor manager", level, message, values)

    def _bus_status(self, now: float) -> StatusEntry:
        if not self._opened:
            level, message = WARN, "closed"
        elif not self._bus_ok:
            level, message = ERROR, (f"down for {now - (self._down_since or now):.3f} s, "
                                     f"reopening every {self._settings.reopen_period:g} s")
        else:
            level, message = OK, "open"
        values = (("bus_open", str(self.bus_ok)),
                  *((name, str(value)) for name, value in self._n.items()),
                  ("last_tx_error", self.last_tx_error),
                  ("last_rx_error", self.last_rx_error))
        return StatusEntry("CAN bus", level, message, values)

    def _index_of_axis(self, axis: int) -> int:
        for i, m in enumerate(self.protocol.axis_map):
            if m.axis == axis:
                return i
        raise KeyError(axis)

    def _axis_statuses(self, now: float) -> list[StatusEntry]:
        entries = []
        stale_after = self.heartbeat_timeout()
        for i, m in enumerate(self.protocol.axis_map):
            flags = self._flags.get(m.axis)
            seen = self._flags_time.get(m.axis)
            position = self._positions[i]
            values: list[tuple[str, str]] = [
                ("joint", m.joint), ("axis", str(m.axis)),
                ("position", "unknown" if math.isnan(position) else f"{position:.4f}"),
                ("status_age", _age(now, seen))]
            if flags is None:
                level, message = STALE, "no status frame yet"
            else:
                values.extend((attr, str(getattr(flags, attr))) for attr in (
                    "enabled", "tracking", "over_current", "over_temp", "encoder_fault",
                    "stalled", "command_timeout"))
                bits = [a for a in ("over_current", "over_temp", "encoder_fault")
                        if getattr(flags, a)]
                if bits:
                    level, message = ERROR, f"fault: {', '.join(bits)}"
                elif seen is not None and now - seen > stale_after:
                    level, message = STALE, f"no status for {now - seen:.3f} s"
                elif flags.stalled:
                    level, message = ERROR, "stalled: not following the target"
                elif flags.command_timeout:
                    level, message = WARN, "manager command timeout: holding"
                else:
                    level, message = OK, "tracking" if flags.tracking else (
                        "powered" if flags.enabled else "unpowered")
            entries.append(StatusEntry(f"axis {m.axis:02d} {m.joint}", level, message,
                                       tuple(values)))
        return entries
