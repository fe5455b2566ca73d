"""``crawler-motion console recover``: bring planner and driver back to where ``stand`` works.

What the state needs, in order, each step printed: the planner's e-stop ``reset``; the
driver's ``~/reset`` (a latched e-stop or a manager fault) and ``~/enable`` (motors not
enabled, watchdog tripped, a manager state the driver did not command). It refuses, saying
which, while a cause is still there: the driver not active, the CAN bus down, the heartbeat
missing, an attack alarm, or the manager still in e-stop after the reset (the hardware e-stop
pressed). Nothing moves: the operator sends ``stand`` afterwards.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from crawler_motion.runtime.diagnostic_names import same_robot
from crawler_motion.tools.console import Console, json_object

#: Driver diagnostics that reset / enable cannot cure, as (text in the message, what to do).
PERSISTENT_CAUSES: tuple[tuple[str, str], ...] = (
    ("CAN bus down", "the CAN bus is down: check the cable / interface"),
    ("heartbeat missing", "the motor manager's heartbeat is missing: is it powered?"),
    ("no heartbeat", "no heartbeat from the motor manager: is it powered?"),
    ("heartbeat without positions", "the manager sends no positions: it is frozen or its "
                                    "heartbeat is forged"),
    ("foreign", "foreign frames on the bus: another controller or an attacker"),
    ("forged", "forged feedback frames on the bus"),
    ("more than one publisher", "a second publisher of joint_commands"),
    ("stalled", "an axis is stalled (blocked)"),
)
#: Driver gate states that ``~/enable`` (after ``~/reset`` for estop) clears.
NEEDS_ENABLE = ("disabled", "holding", "tripped", "estop")
#: How long each step waits for its effect [s].
STEP_WAIT = 3.0


def persistent_cause(message: str) -> str:
    """What still holds the driver at ERROR that reset / enable cannot clear ("" if none)."""
    return "; ".join(why for text, why in PERSISTENT_CAUSES if text in message)


class DriverState:
    """The driver's ``driver_status`` and its ``motor manager`` diagnostic, on a console node."""

    def __init__(self, console: Console) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String

        self.console = console
        self.status: dict[str, Any] | None = None
        self.manager: tuple[int, str, dict[str, str]] | None = None  # level, message, values
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        console.node.create_subscription(String, "driver_status", self._on_status, qos)
        console.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, 10)

    def _on_status(self, msg: Any) -> None:
        status = json_object(msg.data)
        if status is not None:
            self.status = status

    def _on_diag(self, msg: Any) -> None:
        for s in msg.status:
            if (s.name.endswith(": motor manager") and s.hardware_id == "motor_manager"
                    and same_robot(s.name, self.console.node.get_namespace())):
                level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
                self.manager = (level, s.message, {kv.key: kv.value for kv in s.values})

    @property
    def state(self) -> str:
        """The driver's gate state ("unknown" before the first status)."""
        return str((self.status or {}).get("state", "unknown"))

    def manager_state(self) -> str:
        """The manager state of the last heartbeat the driver reported."""
        return self.manager[2].get("manager_state", "unknown") if self.manager else "unknown"

    def trigger(self, service: str, timeout: float) -> tuple[bool, str]:
        """Call the driver's ``~/<service>`` (std_srvs/Trigger): (success, message)."""
        from std_srvs.srv import Trigger

        node = self.console.node
        client = node.create_client(Trigger, f"driver/{service}")
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                return False, f"no driver/{service} service"
            future = client.call_async(Trigger.Request())
            if not self.console.wait_until(future.done, timeout):
                return False, f"driver/{service} did not answer"
            response = future.result()
            return bool(response.success), str(response.message)
        finally:
            node.destroy_client(client)


def recover(console: Console, driver: DriverState, say: Callable[[str], None],
            timeout: float = STEP_WAIT) -> tuple[bool, str]:
    """Run the recovery (see the module docstring); (ok, final message)."""
    console.wait_until(lambda: driver.status is not None and driver.manager is not None,
                       timeout)
    if driver.status is None:
        return False, "no driver_status: is the driver running?"
    if driver.status.get("lifecycle") != "active":
        return False, f"the driver is {driver.status.get('lifecycle')}: activate it first"
    def cause() -> str:
        return persistent_cause(driver.manager[1] if driver.manager else "")

    # a cause may be a report from just before the driver (re)started or the bus came back:
    # it refuses only if it is still there after ``timeout``
    if not console.wait_until(lambda: not cause(), timeout):
        return False, f"refused: {cause()}"
    if (console.status or {}).get("state") == "ESTOP":
        ok, message = console.run({"command": "reset"}, timeout)
        say(f"planner reset: {message}")
        if not ok:
            return False, f"planner reset failed: {message}"
    if driver.state == "estop" or driver.manager_state() in ("estop", "fault"):
        ok, message = driver.trigger("reset", timeout)
        say(f"driver reset: {message}")
        if not ok or not console.wait_until(
                lambda: driver.manager_state() not in ("estop", "fault"), timeout):
            return False, (f"refused: the motor manager is still in {driver.manager_state()} "
                           f"after the reset (hardware e-stop pressed, or a fault that stays)")
    error = driver.manager is not None and driver.manager[0] >= 2
    if driver.state in NEEDS_ENABLE or error:
        ok, message = driver.trigger("enable", timeout)
        say(f"driver enable: {message}")
        if not ok:
            return False, f"driver enable refused: {message}"
    if not console.wait_until(lambda: driver.state == "enabled" and driver.manager is not None
                              and driver.manager[0] < 2, timeout):
        why = driver.manager[1] if driver.manager else "no diagnostics"
        return False, f"refused: the driver is still {driver.state}: {why}"
    return True, "recovered: planner and driver ready; send stand"


def run_driver_action(console: Console, action: str, args: Any, prog: str) -> int:
    """``console status`` (planner and driver state for ``args.duration``) or ``console
    recover``; the exit status."""
    driver = DriverState(console)
    if action == "status":
        printed = ""

        def show() -> bool:
            nonlocal printed
            if driver.status is not None:
                level, message = driver.manager[:2] if driver.manager else (None, "")
                line = (f"driver {driver.state} ({driver.status.get('lifecycle')}), manager "
                        f"{driver.manager_state()}" + (f": {message}" if level else ""))
                if line != printed:
                    printed = line
                    console.printer(line)
            return False

        console.wait_until(show, args.duration)
        return 0
    ok, message = recover(console, driver, console.printer)
    print(f"{prog}: {message}")
    return 0 if ok else 1
