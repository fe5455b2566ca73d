"""The planner node: a thin rclpy shell around `planner.core.PlannerCore`.

Subscribes ``cmd_vel`` (geometry_msgs/Twist; linear.x, linear.y, angular.z used),
``gait_command`` (std_msgs/String, one JSON object, see `commands.parse_gait_command`),
``joint_states`` (sensor_msgs/JointState, measured; composed with the driver, handed over
by it: `measured_input`) and ``/diagnostics``
(diagnostic_msgs/DiagnosticArray: a status whose hardware_id is ``fault_hardware_id`` at level
ERROR pauses the planner until every such status is OK or WARN again; STALE and other robots'
statuses change nothing: `runtime.diagnostic_names`) and ``driver_status`` (std_msgs/String
JSON, transient local: the driver's gate state ends a walk, a new enable epoch resumes it from
the measured pose; see `planner.driver_view`) and ``imu`` (`planner.imu_input`).
Publishes ``joint_commands`` (sensor_msgs/JointState: 12 joints, position + velocity, stamped)
at ``rate`` Hz (nothing in IDLE and ESTOP), and ``planner_status`` (std_msgs/String JSON,
transient local) on every change and at least once a second; the foot contacts estimated from
the joint efforts on ``foot_contacts`` and ``/diagnostics`` (`planner.contact_topics`).

Joint commands come from a `ticker.Ticker` thread on the steady clock (not an rclpy timer);
after each tick it wakes `planning_thread.AheadPlanner`, which plans the next slot ahead
without the lock. Ticks skipped because the process was starved count as ``missed_ticks``.

Parameters: `planner.parameters` (docs/nodes.md). Callbacks share the default callback group
and a lock around the core (a new walk's up-front check runs before it is taken).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from functools import partial
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Twist
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from crawler_motion.errors import CommandError
from crawler_motion.model.calibration_file import config_with_calibration
from crawler_motion.model.config import Config, config_path, load_config
from crawler_motion.model.joint_state import validate_joint_state
from crawler_motion.planner.contact_topics import ContactTopics
from crawler_motion.planner.core import JointTarget, PlannerCore
from crawler_motion.planner.driver_view import parse_driver_status, rate_problem
from crawler_motion.planner.imu_input import ImuInput
from crawler_motion.planner.measured_input import MeasuredInput
from crawler_motion.planner.parameters import (
    CALIBRATION_SPEC,
    PlannerSettings,
    config_file_spec,
    planner_parameters,
    planner_settings,
)
from crawler_motion.planner.planning_thread import AheadPlanner
from crawler_motion.runtime.diagnostic_names import same_robot
from crawler_motion.runtime.log import Severity, Throttle, log
from crawler_motion.runtime.parameters import ParamSpec
from crawler_motion.runtime.ros_main import run_node
from crawler_motion.runtime.ros_parameters import descriptor, parameter_values
from crawler_motion.runtime.ticker import Ticker, set_process_priority

#: Python thread switch interval of the planner process [s] (the default is 5 ms).
GIL_SWITCH_INTERVAL = 0.0005
#: Period of the unconditional status publication [s].
STATUS_PERIOD = 1.0
#: A status change that only counts refusals is published at most once per this long [s]
#: (a flood of bad commands must not become a flood of statuses); others go out at once.
STATUS_MIN_INTERVAL = 0.1
#: Status keys whose change is published at once.
STATUS_URGENT_KEYS = ("state", "paused", "step", "phase", "resuming", "driver", "target")
#: Identical warnings are logged at most once per this many seconds.
LOG_REPEAT_PERIOD = 2.0
#: Distinct messages remembered for `LOG_REPEAT_PERIOD` (the memory is cleared beyond).
LOG_REPEAT_MEMORY = 256
#: How long `destroy_node` waits for each of the node's threads [s].
THREAD_JOIN_TIMEOUT = 2.0


def _level(value: Any) -> int:
    """A DiagnosticStatus level (a ``bytes`` of one byte in rclpy messages) as an int."""
    return value[0] if isinstance(value, (bytes, bytearray)) and value else int(value or 0)


def _severity(level: str) -> Severity:
    """The `Severity` of a core event level (``info``, ``warn`` or ``error``)."""
    return Severity.WARNING if level == "warn" else Severity(level)


def report_priority(node: Node, priority: int, error: str) -> None:
    """Log the tick thread's real-time priority, or why it could not be set."""
    if error:
        node.get_logger().warning(error)
    elif priority:
        node.get_logger().info(f"tick thread at SCHED_FIFO priority {priority}"
                               + (f", the process at {priority - 1}" if priority > 1 else ""))


class FaultLevels:
    """The latest /diagnostics level of each status of the motor manager, and the fault."""

    def __init__(self) -> None:
        self._levels: dict[str, int] = {}

    def clear(self) -> None:
        """Forget every status (the watched hardware_id changed)."""
        self._levels.clear()

    def update(self, statuses: list[DiagnosticStatus], hardware_id: str,
               namespace: str = "/") -> tuple[bool, str]:
        """Record ``statuses`` of ``hardware_id`` from the robot of ``namespace`` (STALE and
        other robots' statuses ignored: `diagnostic_names.same_robot`); returns (faulted,
        reason).

        ``reason`` joins the ERROR statuses of this message ("" if none is new here).
        """
        error = _level(DiagnosticStatus.ERROR)
        reasons = []
        for status in statuses:
            level = _level(status.level)
            if (status.hardware_id != hardware_id or level == _level(DiagnosticStatus.STALE)
                    or not same_robot(status.name, namespace)):
                continue
            self._levels[status.name] = level
            if level >= error:
                reasons.append(f"{status.name}: {status.message}")
        faulted = any(level >= error for level in self._levels.values())
        return faulted, "; ".join(reasons)


class PlannerNode(Node):
    """ROS shell of the planner; ``kwargs`` go to `rclpy.node.Node` (context, overrides)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("planner", **kwargs)
        self._lock = threading.Lock()
        self.cfg, self._specs = self._declare_parameters()
        settings = planner_settings(self._specs, self._parameter_values(), self.cfg)
        priority = settings.tick_priority
        # the process one below the tick thread: a thread holding the GIL (the executor, the
        # planning thread) must not be preempted by ordinary processes while a tick waits
        process_error = set_process_priority(priority - 1) if priority > 1 else ""
        self.core = PlannerCore(self.cfg, settings.rate, defaults=settings.defaults,
                                cmd_vel_timeout=settings.cmd_vel_timeout)
        self.core.contacts.configure(settings.contacts)
        self.core.walk.foothold.configure(settings.foothold, settings.stumble,
                                          settings.attitude)
        self._settings = settings
        self._faults = FaultLevels()
        self._repeats = Throttle(LOG_REPEAT_PERIOD, max_keys=LOG_REPEAT_MEMORY)
        self._status_revision = -1
        self._status_key: tuple[Any, ...] = ()
        self._status_at = -float("inf")
        self._missed_logged = 0
        self._joint_names = list(self.cfg.robot.joint_names)
        self._msg = JointState()
        self._msg.name = list(self._joint_names)
        #: ``on_target(target, stamp)`` runs in the tick thread before each publication.
        self.on_target: Callable[[JointTarget, Time], None] | None = None
        self._create_interfaces()
        self._ahead = AheadPlanner(self.core, self._lock, self._report_failure)
        self._ticker = Ticker(1.0 / settings.rate, self._on_tick, self._after_tick,
                              name="planner-ticker", priority=priority)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self.get_logger().info(
            f"planner ready: {self.cfg.source}, {settings.rate:g} Hz, gait "
            f"{settings.defaults.gait}/{settings.defaults.profile}; IDLE until 'stand'")
        self._publish_status()
        self._ahead.start()
        self.imu.start()
        self._ticker.start()
        report_priority(self, priority, self._ticker.priority_error or process_error)

    def destroy_node(self) -> None:
        """Stop the ticker and planning threads, then destroy the node."""
        self._ticker.stop(timeout=THREAD_JOIN_TIMEOUT)
        self._ahead.stop(THREAD_JOIN_TIMEOUT)
        self.measured.close()
        self.imu.close()
        super().destroy_node()

    # ----------------------------------------------------------------- set-up
    def _declare_parameters(self) -> tuple[Config, tuple[ParamSpec, ...]]:
        """Declare ``config_file`` and ``calibration_file``, load them, then declare the
        parameters they bound."""
        spec = config_file_spec(str(config_path("robot.yaml")))
        config_file = self.declare_parameter(spec.name, spec.default, descriptor(spec)).value
        calibration = self.declare_parameter(CALIBRATION_SPEC.name, CALIBRATION_SPEC.default,
                                             descriptor(CALIBRATION_SPEC)).value
        cfg = config_with_calibration(load_config(config_file), calibration)
        specs = planner_parameters(cfg, config_file)
        for spec in specs[2:]:
            self.declare_parameter(spec.name, spec.default, descriptor(spec))
        return cfg, specs

    def _create_interfaces(self) -> None:
        self._pub_joints = self.create_publisher(JointState, "joint_commands", 10)
        status_qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._pub_status = self.create_publisher(String, "planner_status", status_qos)
        self.create_subscription(Twist, "cmd_vel", self._on_twist, qos_profile_sensor_data)
        self.create_subscription(String, "gait_command", self._on_gait_command, 10)
        self.measured = MeasuredInput(self, self._on_joint_states)  # or the driver, composed
        self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 10)
        self.create_subscription(String, "driver_status", self._on_driver_status, status_qos)
        self._contact_topics = ContactTopics(self, self.core.contacts)
        self.imu = ImuInput(self, self.core, self._lock, partial(self._log, Severity.WARNING))
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._status_timer = self.create_timer(STATUS_PERIOD, self._on_status_timer,
                                               clock=steady)

    # ----------------------------------------------------------------- parameters
    def _parameter_values(self, changes: list[Parameter] | None = None) -> dict[str, Any]:
        return parameter_values(self, self._specs, changes or ())

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        try:
            settings = planner_settings(self._specs, self._parameter_values(params), self.cfg)
            problem = rate_problem(settings.rate, self.core.driver.report)
            if problem:
                raise CommandError(problem)
        except CommandError as exc:
            reason = f"parameters refused: {exc}"
            with self._lock:
                self.core.record_refusal(reason, time.monotonic())
            self._after_core_call()
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, params: list[Parameter]) -> None:
        self._apply_settings(planner_settings(self._specs, self._parameter_values(), self.cfg))

    def _apply_settings(self, settings: PlannerSettings) -> None:
        with self._lock:
            self.core.set_defaults(settings.defaults)
            self.core.set_cmd_vel_timeout(settings.cmd_vel_timeout)
            self.core.contacts.configure(settings.contacts)
            self.core.walk.foothold.configure(settings.foothold, settings.stumble,
                                              settings.attitude)
            self.core.set_rate(settings.rate)
            if settings.rate != self._settings.rate:
                self._ticker.period = 1.0 / settings.rate
            if settings.fault_hardware_id != self._settings.fault_hardware_id:
                self._faults.clear()
                self.core.set_paused(False, time.monotonic())
            self._settings = settings
        self._after_core_call()

    # ----------------------------------------------------------------- inputs
    def _on_gait_command(self, msg: String) -> None:
        _checked(self._lock, lambda: self.core.upfront_job(text=msg.data),
                 lambda: self.core.submit(msg.data, time.monotonic()))
        self._after_core_call()

    def _on_twist(self, msg: Twist) -> None:
        twist = (msg.linear.x, msg.linear.y, msg.angular.z)
        _checked(self._lock, lambda: self.core.upfront_job(twist=twist),
                 lambda: self.core.on_twist(*twist, time.monotonic()))
        self._after_core_call()

    def _on_joint_states(self, msg: JointState, received: float | None = None) -> None:
        """One measured state, received at steady time ``received`` [s] (None: now)."""
        try:
            q = validate_joint_state(msg.name, msg.position, msg.velocity, self._joint_names)
        except CommandError as exc:
            self._log(Severity.WARNING, f"joint_states ignored: {exc}")
            return
        with self._lock:
            self.core.set_measured(q, received if received is not None else (
                self.measured.ages.measured_at(msg, self.get_clock().now().nanoseconds)))
        self._contact_topics.on_joint_state(msg, q)

    def _on_driver_status(self, msg: String) -> None:
        try:
            report = parse_driver_status(msg.data)
        except CommandError as exc:
            self._log(Severity.WARNING, f"driver_status ignored: {exc}")
            return
        with self._lock:
            self.core.on_driver(report, time.monotonic())
            problem = rate_problem(self._settings.rate, report)
        if problem:
            self._log(Severity.ERROR, f"{problem} (set the planner's rate or the driver's "
                                      f"command_timeout)")
        self._after_core_call()

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        with self._lock:
            faulted, reason = self._faults.update(msg.status, self._settings.fault_hardware_id,
                                                  self.get_namespace())
            if faulted:
                self.core.set_paused(True, time.monotonic(), reason or self.core.pause_reason)
            else:
                self.core.set_paused(False, time.monotonic())
        self._after_core_call()

    # ----------------------------------------------------------------- outputs
    def _on_tick(self, now: float) -> None:
        """Ticker thread: one tick of the core, published; errors are logged, never raised."""
        try:
            with self._lock:
                target = self.core.tick(now)
            if target is not None:
                msg = self._msg
                msg.header.stamp = self.get_clock().now().to_msg()
                if self.on_target is not None:  # the composed controller's driver, at once
                    self.on_target(target, msg.header.stamp)
                msg.position = target.position_list()
                msg.velocity = target.velocity_list()
                self._pub_joints.publish(msg)
            self._after_core_call()
            missed = self._ticker.missed
            if missed != self._missed_logged:
                self._missed_logged = missed
                self._log(Severity.WARNING, "ticks skipped: the planner process was starved "
                                            "(see missed_ticks in planner_status)")
        except Exception as exc:  # the ticker must outlive one bad tick
            self._report_failure(f"tick failed: {type(exc).__name__}: {exc}")

    def _after_tick(self, now: float) -> None:
        """Ticker thread, after each tick: the measured states handed over, the ahead planner."""
        try:
            self.measured.take_handed()
        except Exception as exc:  # the ticker must outlive one bad state
            self._report_failure(f"joint state failed: {type(exc).__name__}: {exc}")
        self._ahead.wake(now)

    def _report_failure(self, message: str) -> None:
        """Log a failure of the ticker or planning thread (unless shutting down)."""
        if self.context.ok():
            self._log(Severity.ERROR, message)

    def _after_core_call(self) -> None:
        with self._lock:
            events = self.core.pop_events()
            changed = self.core.revision != self._status_revision
        for level, message in events:
            self._log(_severity(level), message)
        if changed:
            self._publish_status(urgent_only=True)

    def _on_status_timer(self) -> None:
        """Executor, every `STATUS_PERIOD`: recount the joint_states publishers, publish."""
        self.measured.count_publishers()
        self._publish_status()

    def _publish_status(self, urgent_only: bool = False) -> None:
        """Publish the status; with ``urgent_only`` only if a `STATUS_URGENT_KEYS` value
        changed or `STATUS_MIN_INTERVAL` passed (the ticker publishes a held-back change)."""
        now = time.monotonic()
        with self._lock:
            status = self.core.status()
            key = tuple(status[k] for k in STATUS_URGENT_KEYS)
            if urgent_only and key == self._status_key and (
                    now - self._status_at < STATUS_MIN_INTERVAL):
                return
            self._status_revision = status["revision"]
            self._status_key, self._status_at = key, now
        status["missed_ticks"] = self._ticker.missed
        status["joint_states"] = self.measured.report()
        status["imu"] = self.imu.report(now)
        status["time"] = self.get_clock().now().nanoseconds * 1e-9
        self._pub_status.publish(String(data=json.dumps(status)))

    def _log(self, severity: Severity, message: str) -> None:
        """Log ``message``; a warning or error repeated within `LOG_REPEAT_PERIOD` is not."""
        if severity is Severity.INFO or self._repeats.allow(message):
            log(self.get_logger(), severity, message)


def _checked(lock: threading.Lock, job_of: Callable[[], Any], call: Callable[[], Any]
             ) -> None:
    """``call`` the core under ``lock`` after ``job_of``'s up-front check, run without it."""
    with lock:
        job = job_of()
    if job is not None:  # a new walk's tens of ms: the ticks go on
        job()
    with lock:
        try:
            call()
        except CommandError:
            pass


def main(args: list[str] | None = None) -> None:
    """Console script ``planner_node``: spin the planner until Ctrl-C or shutdown."""
    # the ticker thread waits for the GIL at most this long when another thread holds it
    run_node(PlannerNode, "planner_node: error: planner cannot start", args,
             switch_interval=GIL_SWITCH_INTERVAL)


if __name__ == "__main__":
    main()
