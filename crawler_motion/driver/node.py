"""The driver node: joint commands in, CAN frames to the motor manager out, feedback back.

A `rclpy.lifecycle.LifecycleNode` around `crawler_motion.driver.core.DriverCore` (all bus
handling, the watchdog, the e-stop latch and the feedback bookkeeping live there; this file only
converts messages).

Lifecycle: ``configure`` loads robot.yaml, the DBC and the axis map, checks them against the 12
joint names and opens the bus (a failure is logged and leaves nothing open); ``activate`` sends
``enable`` and starts forwarding ``joint_commands``; ``deactivate`` sends ``on_deactivate`` and
stops forwarding; ``cleanup`` / ``shutdown`` close the bus. Nothing is sent before activation but
an e-stop. ``joint_states`` and ``/diagnostics`` are published whenever the bus is open (also
while inactive, so the measured pose is known before the motors are enabled).

Topics: sub ``joint_commands`` (sensor_msgs/JointState, depth 1, best effort: only the newest
command matters; taken by a thread of its own, `command_input`), ``estop`` (std_msgs/Bool,
true latches), ``planner_status`` (std_msgs/String JSON; ``"state": "ESTOP"`` latches); pub
``joint_states`` (sensor_msgs/JointState, measured, joint order, stamped on reception of a
complete position cycle; ``effort`` [N m] when the manager sent every effort frame of the
cycle, else empty), ``/diagnostics`` (statuses named ``<namespace/node>: <what>``),
``driver_status`` (std_msgs/String JSON, transient local: ``state`` the motion gate's state,
``enable_epoch`` the number of enables sent, ``lifecycle``, ``reason``; on every change within
`LEVEL_WATCH_PERIOD` and every ``diagnostics_period``; the planner ends a walk on a state other
than ``enabled`` and resumes from the measured pose on a new epoch).
Services: ``~/enable``, ``~/estop``, ``~/reset`` (std_srvs/Trigger) and the lifecycle services.
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Callable, Mapping
from typing import Any

import can
import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger

from crawler_motion.canbus.bus import make_bus_factory
from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.driver.command_input import CommandInput
from crawler_motion.driver.core import DriverCore
from crawler_motion.driver.diagnostics import StatusEntry, unconfigured_entry
from crawler_motion.driver.messages import diagnostic_array, driver_status
from crawler_motion.driver.rclpy_workarounds import guard_change_state, publish_unless_shut_down
from crawler_motion.driver.settings import PARAMETERS, DriverSettings, default_files
from crawler_motion.errors import ConfigError, CrawlerMotionError, ProtocolError
from crawler_motion.model.config import load_config
from crawler_motion.runtime.diagnostic_names import status_prefix
from crawler_motion.runtime.parameters import validate_parameters
from crawler_motion.runtime.ros_main import run_node
from crawler_motion.runtime.ros_parameters import descriptor
from crawler_motion.runtime.ticker import set_process_priority

NODE_NAME = "driver"
N_JOINTS = 12
#: Period of the check for changed diagnostic levels, published at once when one changed [s].
LEVEL_WATCH_PERIOD = 0.05
STATUS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
SUCCESS, FAILURE = TransitionCallbackReturn.SUCCESS, TransitionCallbackReturn.FAILURE


def load_protocol(values: Mapping[str, Any]) -> MotorProtocol:
    """The motor protocol of the file parameters, checked against the robot's 12 joints."""
    config = load_config(values["config_file"])
    joints = config.robot.joint_names
    if len(joints) != N_JOINTS:
        raise ConfigError(f"{values['config_file']} gives {len(joints)} joints; the "
                          f"motor manager drives {N_JOINTS}")
    protocol = MotorProtocol.from_config(config.robot, values["dbc_file"], values["axes_file"])
    if protocol.joint_names != joints or protocol.n_axes != N_JOINTS:
        raise ProtocolError(f"the protocol drives {list(protocol.joint_names)}, the "
                            f"robot has {list(joints)}")
    return protocol


def apply_priority(priority: int, logger: Any) -> None:
    """Run the process at SCHED_FIFO ``priority`` (0: unchanged); logs what happened.

    Every thread of the process, and those created later, inherit it.
    """
    if priority:
        problem = set_process_priority(priority)
        if problem:
            logger.warning(f"{problem}; running at normal priority")
        else:
            logger.info(f"process at SCHED_FIFO priority {priority}")


class DriverNode(LifecycleNode):
    """The lifecycle driver node; ``bus_factory`` replaces the bus the parameters describe."""

    def __init__(self, node_name: str = NODE_NAME, *,
                 bus_factory: Callable[[], can.BusABC] | None = None, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        guard_change_state(self, self.get_logger().error)
        self._bus_factory = bus_factory
        self._declare_parameters()
        self._core: DriverCore | None = None
        self._joint_names: tuple[str, ...] = ()
        self._label = "unconfigured"  # the lifecycle state, as the transitions left it
        self._latched = ""  # ESTOP latched while no core exists (kept across cleanup)
        self._configure_error = ""
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._joint_state_pub = self.create_publisher(JointState, "joint_states", 10)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._driver_status_pub = self.create_publisher(String, "driver_status", STATUS_QOS)
        self._driver_status, self._instance = "", uuid.uuid4().hex[:12]  # new at every start
        self.commands = CommandInput(self, lambda: self._core)  # topic and direct hand-over
        #: ``on_joint_state(msg)`` receives each published joint state (composed controller).
        self.on_joint_state: Callable[[JointState], None] | None = None
        self.create_subscription(Bool, "estop", self._on_estop_topic, 10)
        self.create_subscription(String, "planner_status", self._on_planner_status, 10)
        self.create_service(Trigger, "~/enable", self._on_enable)
        self.create_service(Trigger, "~/estop", self._on_estop_service)
        self.create_service(Trigger, "~/reset", self._on_reset)
        self._diagnostics_timer = self.create_timer(
            self._value("diagnostics_period"), self._publish_diagnostics, clock=self._steady)
        # a level change goes out at once: the planner pauses on ERROR without waiting a period
        self._published_levels: tuple[tuple[str, int], ...] = ()
        self.create_timer(LEVEL_WATCH_PERIOD, self._watch_levels, clock=self._steady)
        self.commands.start()
        if self._value("autostart") and self.trigger_configure() == SUCCESS:
            self.trigger_activate()

    # ---- parameters ------------------------------------------------------------------------

    def _declare_parameters(self) -> None:
        files = default_files()
        for spec in PARAMETERS:
            self.declare_parameter(spec.name, files.get(spec.name, spec.default),
                                   descriptor(spec))
        reasons = validate_parameters(PARAMETERS, self._values())
        if reasons:
            raise ConfigError(f"invalid driver parameters: {'; '.join(reasons)}")
        apply_priority(self._value("priority"), self.get_logger())
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)

    def _value(self, name: str) -> Any:
        return self.get_parameter(name).value

    def _values(self) -> dict[str, Any]:
        return {spec.name: self._value(spec.name) for spec in PARAMETERS}

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        names = {spec.name for spec in PARAMETERS}
        reasons = validate_parameters(PARAMETERS, {p.name: p.value for p in parameters
                                                   if p.name in names})
        return SetParametersResult(successful=not reasons, reason="; ".join(reasons))

    def _after_set_parameters(self, parameters: list[Parameter]) -> None:
        if self._core is not None:
            self._core.update_settings(DriverSettings.from_parameters(self._values()))
        if "diagnostics_period" in {p.name for p in parameters}:
            self.destroy_timer(self._diagnostics_timer)
            self._diagnostics_timer = self.create_timer(
                self._value("diagnostics_period"), self._publish_diagnostics,
                clock=self._steady)

    # ---- lifecycle -------------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Load the protocol, check it against the joints, open the bus."""
        values = self._values()
        core = None
        try:
            protocol = load_protocol(values)
            factory = self._bus_factory or make_bus_factory(
                values["can_interface"], values["can_channel"], values["can_port"],
                values["bitrate"], own_frames=False)  # as SocketCAN: no own loop-back
            core = DriverCore(protocol, bus_factory=factory,
                              settings=DriverSettings.from_parameters(values),
                              on_feedback=self._publish_joint_state, logger=self.get_logger())
            core.open()
        except (CrawlerMotionError, ValueError, OSError) as exc:
            if core is not None:
                core.close()
            self._configure_error = f"configure failed: {exc}"
            self.get_logger().error(self._configure_error)
            return FAILURE
        self._configure_error = ""
        self._joint_names = protocol.joint_names
        self._core = core
        core.start()
        if self._latched:
            core.estop(self._latched)
        where = "injected bus" if self._bus_factory else (
            f"{values['can_interface']} {values['can_channel']}")
        self.get_logger().info(f"configured: {len(self._joint_names)} joints on {where}")
        self._label = "inactive"
        return SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Send ``enable`` and start forwarding joint_commands."""
        if self._core is None:
            return FAILURE
        ok, message = self._core.activate()
        if not ok:
            self.get_logger().error(f"activate refused: {message}")
            return FAILURE
        self.get_logger().info(f"active: {message}")
        self._label = "active"
        return SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Send ``on_deactivate`` (hold or disable) and stop forwarding."""
        if self._core is not None:
            self.get_logger().info(f"inactive: {self._core.deactivate()}")
        self._label = "inactive"
        return SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Close the bus (an ESTOP latch survives)."""
        return self._close_core("unconfigured")

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Deactivate if active, then close the bus."""
        return self._close_core("finalized")

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Close the bus and go back to unconfigured."""
        return self._close_core("unconfigured")

    def _close_core(self, label: str) -> TransitionCallbackReturn:
        self._label = label
        core, self._core = self._core, None
        if core is not None:
            if core.active:
                core.deactivate()
            if core.estop_latched:
                self._latched = core.estop_reason
            core.close()
        return SUCCESS

    def destroy_node(self) -> None:
        """Stop taking joint_commands, close the bus (deactivating first), destroy the node."""
        self.commands.close()
        self._close_core(self._label)
        super().destroy_node()

    # ---- commands and safety ---------------------------------------------------------------

    def _latch(self, reason: str) -> bool:
        """Latch ESTOP now; True when the e-stop frame went out within this call."""
        if self._core is not None:
            return self._core.estop(reason)
        if not self._latched:
            self.get_logger().error(f"ESTOP latched (no bus open): {reason}")
        self._latched = reason
        return False

    def _on_estop_topic(self, msg: Bool) -> None:
        if msg.data:
            self._latch("estop topic")

    def _on_planner_status(self, msg: String) -> None:
        try:
            state = json.loads(msg.data).get("state")
        except (ValueError, AttributeError):
            self.get_logger().warning("planner_status is not a JSON object with 'state'",
                                      throttle_duration_sec=5.0)
            return
        if isinstance(state, str) and state.upper() == "ESTOP":
            latched = self._core.estop_latched if self._core else bool(self._latched)
            if not latched:
                self._latch("planner reported ESTOP")

    def _on_estop_service(self, request: Trigger.Request,
                          response: Trigger.Response) -> Trigger.Response:
        sent = self._latch("~/estop service")
        response.success = True
        response.message = "ESTOP latched; " + (
            "e-stop frame sent" if sent else "e-stop frame queued (bus not open or down)")
        return response

    def _answer(self, service: str, response: Trigger.Response,
                result: tuple[bool, str]) -> Trigger.Response:
        response.success, response.message = result
        self._publish_driver_status(always=False)  # the planner learns it before the caller
        self.get_logger().info(f"~/{service}: {response.message}")
        return response

    def _on_reset(self, request: Trigger.Request,
                  response: Trigger.Response) -> Trigger.Response:
        self._latched = ""
        return self._answer("reset", response, (True, "latch cleared (not configured)")
                            if self._core is None else self._core.reset())

    def _on_enable(self, request: Trigger.Request,
                   response: Trigger.Response) -> Trigger.Response:
        return self._answer("enable", response, (False, "not configured")
                            if self._core is None else self._core.enable())

    # ---- publishing ------------------------------------------------------------------------

    def _publish_joint_state(self, positions: np.ndarray, efforts: np.ndarray) -> None:
        """Publish one measured joint state, efforts [N m] empty when not reported, and hand it
        to `on_joint_state` (called from the core's receive thread)."""
        def make() -> JointState:
            msg = JointState(name=list(self._joint_names), position=positions.tolist(),
                             effort=efforts.tolist())
            msg.header.stamp = self.get_clock().now().to_msg()
            return msg

        msg = publish_unless_shut_down(self._joint_state_pub, make, self.context)
        if msg is not None and self.on_joint_state is not None:
            try:
                self.on_joint_state(msg)
            except Exception as exc:  # the CAN thread must outlive a failing receiver
                self.get_logger().error(f"joint state hand-over failed: {type(exc).__name__}: "
                                        f"{exc}", throttle_duration_sec=1.0)

    def _publish_driver_status(self, always: bool) -> None:
        text = json.dumps(driver_status(self._core, self._label, self._latched,
                                        self._configure_error, self._instance))
        if always or text != self._driver_status:
            self._driver_status = text
            self._driver_status_pub.publish(String(data=text))

    def _watch_levels(self) -> None:
        self._publish_driver_status(always=False)
        if self._core is not None:
            entries = self._core.status()
            if tuple((e.name, e.level) for e in entries) != self._published_levels:
                self._publish_diagnostics(entries)

    def _publish_diagnostics(self, entries: list[StatusEntry] | None = None) -> None:
        self._publish_driver_status(always=entries is None)  # periodic: driver_status too
        if self._core is None:
            entries = [unconfigured_entry(self._label, self._configure_error, self._latched,
                                          self.commands.dropped_unconfigured)]
        elif entries is None:
            entries = self._core.status()
        self._published_levels = tuple((e.name, e.level) for e in entries)
        array = diagnostic_array(entries, status_prefix(self.get_namespace(), self.get_name()),
                                 self._label)
        array.header.stamp = self.get_clock().now().to_msg()
        self._diagnostics_pub.publish(array)


def main(args: list[str] | None = None) -> None:
    """Run the driver node until Ctrl-C / shutdown (``driver_node --ros-args -p ...``)."""
    # the CAN thread and the executor share the GIL: hand it over within 0.5 ms, not 5 ms
    run_node(DriverNode, "driver_node: error", args, switch_interval=0.0005)


if __name__ == "__main__":
    main()
