"""The planner node: a thin rclpy shell around `planner_core.PlannerCore`.

Subscribes ``cmd_vel`` (geometry_msgs/Twist; linear.x, linear.y, angular.z used),
``gait_command`` (std_msgs/String, one JSON object, see `commands.parse_gait_command`),
``joint_states`` (sensor_msgs/JointState, measured) and ``/diagnostics``
(diagnostic_msgs/DiagnosticArray: a status whose hardware_id is ``fault_hardware_id`` at level
ERROR pauses the planner until every such status is OK or WARN again; STALE changes nothing).
Publishes ``joint_commands`` (sensor_msgs/JointState: 12 joints, position + velocity, stamped)
at ``rate`` Hz (nothing in IDLE and ESTOP), and ``planner_status`` (std_msgs/String JSON,
transient local) on every change and at least once a second.

Joint commands are published from a `ticker.Ticker` thread on the steady clock, not from an
rclpy timer: the executor also runs every callback, and a busy executor delays or skips timer
ticks. After each tick it wakes a second thread that plans the next gait slot ahead of its
boundary (`PlannerCore.ahead_job`, computed without the lock), so no tick waits for planning.
Ticks skipped because the process was starved are counted (``missed_ticks`` in the status; a
message is logged).

Parameters are validated by `commands.validate_parameters`, at start-up and on every change
(refused with the reason). ``config_file`` is read-only; a new ``rate`` changes the period of
the running timer; new gait defaults apply to the next walk or stand, not to a walk in progress.
All callbacks share the node's default (mutually exclusive) callback group and a lock around
the core, so the node is also safe under a MultiThreadedExecutor and with `set_parameters`
called from another thread. Spin it single-threaded (as `main` does).
"""

from __future__ import annotations

import json
import sys
import threading
import time
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Twist
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from crawler_motion.errors import CommandError, CrawlerMotionError
from crawler_motion.model.config import config_path, load_config
from crawler_motion.planner.commands import (
    PlannerSettings,
    default_parameters,
    parameter_ranges,
    validate_joint_state,
    validate_parameters,
)
from crawler_motion.planner.core import PlannerCore
from crawler_motion.runtime.ticker import Ticker, check_priority, set_process_priority

#: Python thread switch interval of the planner process [s] (the default is 5 ms).
GIL_SWITCH_INTERVAL = 0.0005
#: Period of the unconditional status publication [s].
STATUS_PERIOD = 1.0
#: Identical warnings are logged at most once per this many seconds.
LOG_REPEAT_PERIOD = 2.0
_DESCRIPTIONS = {
    "rate": "joint_commands rate [Hz]; a change applies to the running timer",
    "cmd_vel_timeout": "a cmd_vel walk stops into standing after this long without a twist [s]",
    "fault_hardware_id": "hardware_id of the motor manager in /diagnostics (ERROR pauses)",
    "gait": "default gait of a new walk",
    "profile": "default swing profile of a new walk",
    "stride": "default stride of a new walk [m]",
    "lift": "default lift of a new walk [m]",
    "arc": "default arc (apex above the lift) of a new walk [m]",
    "swing_time": "default swing time of a new walk [s]",
    "body_height": "default standing body height (stand without body_height) [m]",
}


def _level(value: Any) -> int:
    return value[0] if isinstance(value, (bytes, bytearray)) and value else int(value or 0)


class PlannerNode(Node):
    """ROS shell of the planner; ``kwargs`` go to `rclpy.node.Node` (context, overrides)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("planner", **kwargs)
        self._lock = threading.Lock()
        shipped = str(config_path("robot.yaml"))
        config_file = self.declare_parameter(
            "config_file", shipped,
            ParameterDescriptor(type=ParameterType.PARAMETER_STRING, read_only=True,
                                description="robot.yaml (geometry, limits, gait ranges)"),
        ).value
        self.cfg = load_config(config_file)
        ranges = parameter_ranges(self.cfg)
        for name, default in default_parameters(self.cfg, config_file).items():
            if name == "config_file":
                continue
            descriptor = ParameterDescriptor(description=_DESCRIPTIONS[name])
            if name in ranges:
                descriptor.type = ParameterType.PARAMETER_DOUBLE
                lo, hi = ranges[name]
                descriptor.floating_point_range = [
                    FloatingPointRange(from_value=float(lo), to_value=float(hi), step=0.0)]
                default = float(default)
            else:
                descriptor.type = ParameterType.PARAMETER_STRING
                if name == "gait":
                    descriptor.additional_constraints = f"one of {sorted(self.cfg.gait.gaits)}"
                elif name == "profile":
                    descriptor.additional_constraints = (
                        f"one of {sorted(self.cfg.gait.profiles)}")
            self.declare_parameter(name, default, descriptor)
        priority = self.declare_parameter(
            "tick_priority", 0,
            ParameterDescriptor(type=ParameterType.PARAMETER_INTEGER, read_only=True,
                                integer_range=[IntegerRange(from_value=0, to_value=99, step=1)],
                                description="0: normal scheduling; 1-99: SCHED_FIFO priority "
                                            "of the tick thread, the rest of the process one "
                                            "below (needs CAP_SYS_NICE)"),
        ).value
        try:
            check_priority(priority)
        except ValueError as exc:
            raise CommandError(str(exc)) from None
        # the process one below the tick thread: a thread holding the GIL (the executor, the
        # planning thread) must not be preempted by ordinary processes while a tick waits
        process_error = set_process_priority(max(0, priority - 1)) if priority > 1 else ""
        settings = validate_parameters(self._parameter_values(), self.cfg)
        self.core = PlannerCore(self.cfg, settings.rate, defaults=settings.defaults,
                                cmd_vel_timeout=settings.cmd_vel_timeout)
        self._settings = settings
        self._joint_names = list(self.cfg.robot.joint_names)
        self._diag_levels: dict[str, int] = {}
        self._logged: dict[str, float] = {}
        self._status_revision = -1
        self._msg = JointState()
        self._msg.name = list(self._joint_names)

        self._pub_joints = self.create_publisher(JointState, "joint_commands", 10)
        status_qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._pub_status = self.create_publisher(String, "planner_status", status_qos)
        self.create_subscription(Twist, "cmd_vel", self._on_twist, qos_profile_sensor_data)
        self.create_subscription(String, "gait_command", self._on_gait_command, 10)
        self.create_subscription(JointState, "joint_states", self._on_joint_states,
                                 qos_profile_sensor_data)
        self.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 10)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._ticker = Ticker(1.0 / settings.rate, self._on_tick, self._wake_planning,
                              name="planner-ticker", priority=priority)
        self._missed_logged = 0
        self._ahead_now = 0.0
        self._ahead_wake = threading.Event()
        self._ahead_stop = threading.Event()
        self._ahead_thread = threading.Thread(target=self._ahead_loop, name="planner-ahead",
                                              daemon=True)
        self._status_timer = self.create_timer(STATUS_PERIOD, self._publish_status,
                                               clock=steady)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self.get_logger().info(
            f"planner ready: {self.cfg.source}, {settings.rate:g} Hz, gait "
            f"{settings.defaults.gait}/{settings.defaults.profile}; IDLE until 'stand'")
        self._publish_status()
        self._ahead_thread.start()
        self._ticker.start()
        if self._ticker.priority_error or process_error:
            self.get_logger().warning(self._ticker.priority_error or process_error)
        elif priority:
            self.get_logger().info(f"tick thread at SCHED_FIFO priority {priority}"
                                   + (f", the process at {priority - 1}" if priority > 1
                                      else ""))

    def destroy_node(self) -> None:
        """Stop the ticker and planning threads, then destroy the node."""
        self._ticker.stop(timeout=2.0)
        self._ahead_stop.set()
        self._ahead_wake.set()
        if self._ahead_thread.is_alive():
            self._ahead_thread.join(timeout=2.0)
        super().destroy_node()

    # ----------------------------------------------------------------- parameters
    def _parameter_values(self, changes: list[Parameter] | None = None) -> dict[str, Any]:
        values = {name: self.get_parameter(name).value
                  for name in default_parameters(self.cfg, "")}
        for param in changes or []:
            values[param.name] = param.value
        return values

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        try:
            validate_parameters(self._parameter_values(params), self.cfg)
        except CommandError as exc:
            reason = f"parameters refused: {exc}"
            with self._lock:
                self.core.record_refusal(reason, time.monotonic())
            self._after_core_call()
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, params: list[Parameter]) -> None:
        settings = validate_parameters(self._parameter_values(), self.cfg)
        self._apply_settings(settings)

    def _apply_settings(self, settings: PlannerSettings) -> None:
        with self._lock:
            self.core.set_defaults(settings.defaults)
            self.core.set_cmd_vel_timeout(settings.cmd_vel_timeout)
            self.core.set_rate(settings.rate)
            if settings.rate != self._settings.rate:
                self._ticker.period = 1.0 / settings.rate
            if settings.fault_hardware_id != self._settings.fault_hardware_id:
                self._diag_levels.clear()
                self.core.set_paused(False, time.monotonic())
            self._settings = settings
        self._after_core_call()

    # ----------------------------------------------------------------- inputs
    def _on_gait_command(self, msg: String) -> None:
        with self._lock:
            try:
                self.core.submit(msg.data, time.monotonic())
            except CommandError:
                pass  # recorded by the core: status + events
        self._after_core_call()

    def _on_twist(self, msg: Twist) -> None:
        with self._lock:
            try:
                self.core.on_twist(msg.linear.x, msg.linear.y, msg.angular.z, time.monotonic())
            except CommandError:
                pass
        self._after_core_call()

    def _on_joint_states(self, msg: JointState) -> None:
        try:
            q = validate_joint_state(msg.name, msg.position, msg.velocity, self._joint_names)
        except CommandError as exc:
            self._log("warn", f"joint_states ignored: {exc}")
            return
        with self._lock:
            self.core.set_measured(q, time.monotonic())

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        fault_id = self._settings.fault_hardware_id
        reasons = []
        with self._lock:
            for status in msg.status:
                if status.hardware_id != fault_id:
                    continue
                level = _level(status.level)
                if level == _level(DiagnosticStatus.STALE):
                    continue
                self._diag_levels[status.name] = level
                if level >= _level(DiagnosticStatus.ERROR):
                    reasons.append(f"{status.name}: {status.message}")
            errors = [name for name, lvl in self._diag_levels.items()
                      if lvl >= _level(DiagnosticStatus.ERROR)]
            if errors:
                reason = "; ".join(reasons) if reasons else self.core.pause_reason
                self.core.set_paused(True, time.monotonic(), reason)
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
                msg.position = target.positions.tolist()
                msg.velocity = target.velocities.tolist()
                self._pub_joints.publish(msg)
            self._after_core_call()
            missed = self._ticker.missed
            if missed != self._missed_logged:
                self._missed_logged = missed
                self._log("warn", "ticks skipped: the planner process was starved (see "
                                  "missed_ticks in planner_status)")
        except Exception as exc:  # the ticker must outlive one bad tick
            if self.context.ok():
                self._log("error", f"tick failed: {type(exc).__name__}: {exc}")

    def _wake_planning(self, now: float) -> None:
        """Ticker thread, right after a tick: wake the planning thread (costs nothing)."""
        self._ahead_now = now
        self._ahead_wake.set()

    def _ahead_loop(self) -> None:
        """Planning thread: plans the next slot before its boundary without
        holding the core's lock while it computes, so the ticks go on meanwhile."""
        while True:
            self._ahead_wake.wait()
            self._ahead_wake.clear()
            if self._ahead_stop.is_set():
                return
            try:
                with self._lock:
                    job = self.core.ahead_job(self._ahead_now)
                if job is None:
                    continue
                ahead = job.run()
                with self._lock:
                    self.core.store_ahead(ahead)
            except Exception as exc:  # the boundary tick plans it itself if needed
                if self.context.ok():
                    self._log("error", f"planning ahead failed: {type(exc).__name__}: {exc}")

    def _after_core_call(self) -> None:
        with self._lock:
            events = self.core.pop_events()
            changed = self.core.revision != self._status_revision
        for level, message in events:
            self._log(level, message)
        if changed:
            self._publish_status()

    def _publish_status(self) -> None:
        with self._lock:
            status = self.core.status()
            self._status_revision = status["revision"]
        status["missed_ticks"] = self._ticker.missed
        status["time"] = self.get_clock().now().nanoseconds * 1e-9
        self._pub_status.publish(String(data=json.dumps(status)))

    def _log(self, level: str, message: str) -> None:
        now = time.monotonic()
        if level != "info":
            last = self._logged.get(message)
            if last is not None and now - last < LOG_REPEAT_PERIOD:
                return
            self._logged[message] = now
            if len(self._logged) > 256:
                self._logged.clear()
        # one call site per severity: rclpy's logger ties a severity to its call site
        logger = self.get_logger()
        if level == "error":
            logger.error(message)
        elif level == "warn":
            logger.warning(message)
        else:
            logger.info(message)


def main(args: list[str] | None = None) -> None:
    """Console script ``planner_node``: spin the planner until Ctrl-C or shutdown."""
    # the ticker thread waits for the GIL at most this long when another thread holds it
    sys.setswitchinterval(GIL_SWITCH_INTERVAL)
    rclpy.init(args=args)
    node = None
    try:
        node = PlannerNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (CrawlerMotionError, ParameterException) as exc:
        rclpy.logging.get_logger("planner").fatal(f"planner cannot start: {exc}")
        raise SystemExit(1) from None
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
