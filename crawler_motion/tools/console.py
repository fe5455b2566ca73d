"""``crawler-motion console``: send gait commands and twists, follow the planner's status.

For a person at a terminal or a script: every command waits until the planner reaches the
state it asked for and prints each status change (state, step k of N) on the way. Exit status:
0 done, 1 refused / timed out / planner not found, 2 bad options.

    crawler-motion console stand
    crawler-motion console walk --steps 4 --gait wave
    crawler-motion console pose --x 0.01 --roll 0.05
    crawler-motion console twist --vx 0.03 --duration 4
    crawler-motion console estop
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from crawler_motion.motion.walk_options import OPTIONS
from crawler_motion.planner.commands import COMMAND_KEYS
from crawler_motion.runtime.cli_args import OneLineParser, finite_number, split_ros_args
from crawler_motion.tools.args import add_walk_options

PROG = "crawler-motion console"

#: State reached when a command is done (None: return once the planner accepted it).
DONE_STATES: dict[str, tuple[str, ...]] = {
    "stand": ("STANDING",), "sit": ("SITTING",), "stop": ("STANDING",), "estop": ("ESTOP",),
    "reset": ("IDLE",), "pose": ("STANDING",),
}
#: Words of the planner's refusals that clear by themselves (`Console.run_when_ready`): a
#: pause, a resume from the measured pose after it, no measurement yet.
TRANSIENT_REFUSALS = ("paused", "resum", "no measured")
#: Help of the actions that are more than one gait command sent as it is.
ACTION_HELP: dict[str, str] = {
    "stand": "stand up from the measured pose",
    "walk": "walk N steps (absent: until stopped) and wait for it",
    "pose": "shift and tilt the standing body, every foot fixed (options left out: 0)",
}


def build_parser() -> argparse.ArgumentParser:
    """Arguments of the console."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("--timeout", type=finite_number("timeout", positive=True), default=60.0,
                        help="give up after this long [s] (default 60)")
    parser.add_argument("--quiet", action="store_true", help="print only the outcome")
    sub = parser.add_subparsers(dest="action", required=True, parser_class=OneLineParser)
    for name, keys in COMMAND_KEYS.items():
        p = sub.add_parser(name, help=ACTION_HELP.get(name, f'send {{"command": "{name}"}}'))
        add_walk_options(p, keys)
    p = sub.add_parser("twist", help="publish cmd_vel for a while, then a zero twist")
    p.add_argument("--vx", type=finite_number("vx"), default=0.0, help="forward speed [m/s]")
    p.add_argument("--vy", type=finite_number("vy"), default=0.0, help="left speed [m/s]")
    p.add_argument("--wz", type=finite_number("wz"), default=0.0, help="yaw rate [rad/s]")
    p.add_argument("--duration", type=finite_number("duration", positive=True), default=3.0)
    p.add_argument("--rate", type=finite_number("rate", positive=True), default=20.0)
    sub.add_parser("recover", help="after an e-stop or a watchdog trip: reset the planner, "
                   "reset and enable the driver as needed, so that stand works")
    p = sub.add_parser("status", help="print status changes (planner and driver) for a while")
    p.add_argument("--duration", type=finite_number("duration", positive=True), default=5.0)
    p = sub.add_parser("goto", help="send the navigator a goal and follow it to its end")
    p.add_argument("x", type=finite_number("x"), help="goal x [m]")
    p.add_argument("y", type=finite_number("y"), help="goal y [m]")
    p.add_argument("--frame", default="odom", help="frame of the goal (default odom)")
    sub.add_parser("cancel", help="cancel the navigator's goal (the robot stands)")
    p = sub.add_parser("mission", help="run a mission file (crawler-motion mission), or "
                       "'mission cancel'")
    p.add_argument("file", help="the mission YAML, or cancel")
    p = sub.add_parser("send", help="send one raw JSON gait command")
    p.add_argument("json", help="the JSON object, e.g. '{\"command\": \"stand\"}'")
    return parser


def command_from_args(args: argparse.Namespace) -> dict[str, Any] | None:
    """The gait command object an action sends (None for twist/status)."""
    if args.action not in COMMAND_KEYS:
        return None
    cmd: dict[str, Any] = {"command": args.action}
    for name in COMMAND_KEYS[args.action]:
        value = getattr(args, name)
        if value is not None:
            cmd[name] = value
    return cmd


def describe(status: dict[str, Any]) -> str:
    """One line for a status: state, step k of N, phase, body pose, pause."""
    text = str(status.get("state"))
    if status.get("state") in ("WALKING", "STOPPING"):
        steps = status.get("steps")
        text += f" step {status.get('step')} of {steps if steps is not None else '∞'}"
        if status.get("phase"):
            text += f" ({status['phase']})"
    pose = status.get("body_pose")
    if isinstance(pose, dict) and status.get("state") in ("STANDING", "MOVING"):
        shown = [f"{k} {v:g} {OPTIONS[k].unit}" for k, v in pose.items()
                 if k in OPTIONS and isinstance(v, (int, float)) and v]
        if shown:
            text += f" (pose {', '.join(shown)})"
    if status.get("paused"):
        text += f" PAUSED: {status.get('pause_reason')}"
    return text


def json_object(text: str) -> dict[str, Any] | None:
    """The JSON object of a status message's text; None when it is not one."""
    try:
        value = json.loads(text)
    except ValueError:
        return None
    return value if isinstance(value, dict) else None


#: How long `Console.connect` waits for every subscriber of gait_command to match [s].
MATCH_WAIT = 3.0


class Console:
    """A small rclpy node that talks to the planner (`main` makes one per run; tests too).

    Call ``rclpy.init`` first; `close` destroys the node.
    """

    def __init__(self, node_name: str = "crawler_console", namespace: str | None = None) -> None:
        import rclpy
        from geometry_msgs.msg import Twist
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String

        self._rclpy = rclpy
        self._string, self._twist = String, Twist
        self.node = rclpy.create_node(node_name, namespace=namespace)  # None: the ROS args'
        self.pub_cmd = self.node.create_publisher(String, "gait_command", 10)
        self.pub_twist = self.node.create_publisher(Twist, "cmd_vel", 10)
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.status: dict[str, Any] | None = None
        sub = self.node.create_subscription(String, "planner_status", self._on_status, qos)
        self._status_topic = sub.topic_name
        self.printer: Callable[[str], None] = print
        self._t0 = time.monotonic()
        self._last_line = ""

    def _on_status(self, msg: Any) -> None:
        status = json_object(msg.data)
        if status is not None:
            self.status = status
            line = describe(status)
            if line != self._last_line:
                self._last_line = line
                self.printer(f"[{time.monotonic() - self._t0:6.2f} s] {line}")

    def spin_for(self, seconds: float) -> None:
        """Process callbacks for ``seconds``."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            left = max(0.0, end - time.monotonic())
            self._rclpy.spin_once(self.node, timeout_sec=min(0.05, left))

    def wait_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Spin until ``predicate()`` is true or ``timeout`` [s] passes."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            self._rclpy.spin_once(self.node, timeout_sec=0.05)
        return predicate()

    def connect(self, timeout: float) -> bool:
        """Wait for the planner: a status received, the planner's own subscription of
        gait_command on the graph (`planner_listens`) and our command publisher matched by every
        subscriber the graph knows (the recorder and the driver subscribe too: one match is not
        the planner's, and a command sent before the planner matched is lost). A process
        killed a moment ago stays on the graph until its lease ends: after `MATCH_WAIT` [s] one
        match is enough."""
        topic = self.pub_cmd.topic_name

        def matched() -> bool:
            # the planner (the node publishing planner_status) must be on the graph as a
            # subscriber of gait_command: a new console may know only the recorder's and the
            # driver's subscriptions yet, and a command sent then never reaches the planner
            known = self.node.count_subscribers(topic)
            return known > 0 and self.pub_cmd.get_subscription_count() >= known and \
                planner_listens(self.node.get_publishers_info_by_topic(self._status_topic),
                                self.node.get_subscriptions_info_by_topic(topic))

        began = time.monotonic()
        if self.wait_until(lambda: self.status is not None and matched(),
                           min(timeout, MATCH_WAIT)):
            return True
        return self.wait_until(lambda: self.status is not None
                               and self.pub_cmd.get_subscription_count() > 0,
                               max(0.0, timeout - (time.monotonic() - began)))

    def send(self, command: dict[str, Any]) -> None:
        """Publish one gait command."""
        self.pub_cmd.publish(self._string(data=json.dumps(command)))

    def twist(self, vx: float, vy: float, wz: float) -> None:
        """Publish one twist."""
        msg = self._twist()
        msg.linear.x, msg.linear.y, msg.angular.z = float(vx), float(vy), float(wz)
        self.pub_twist.publish(msg)

    def run(self, command: dict[str, Any], timeout: float) -> tuple[bool, str]:
        """Send ``command`` and follow the status until done; returns (ok, message)."""
        assert self.status is not None
        refusals = _command_refusals(self.status)
        revision = self.status.get("revision", -1)
        name = command.get("command")
        self.send(command)
        seen: list[str] = []
        interruptions = self.status.get("interruptions", 0)

        def refused() -> bool:
            # a refused cmd_vel twist (another node's: a navigator) is not this command's
            return self.status is not None and _command_refusals(self.status) > refusals

        def progressed() -> bool:
            st = self.status or {}
            if st.get("revision", -1) != revision:
                seen.append(str(st.get("state")))
            if refused():
                return True
            if name == "pose":  # from STANDING through MOVING back to STANDING
                return "MOVING" in seen and st.get("state") == "STANDING"
            if name == "walk":
                if command.get("steps") is None:
                    return "WALKING" in seen
                return "WALKING" in seen and st.get("state") == "STANDING"
            return st.get("state") in DONE_STATES.get(str(name), ()) and (
                st.get("revision", -1) != revision or name in ("estop",))

        done = self.wait_until(progressed, timeout)
        if refused():
            return False, f"refused: {self.status.get('last_refusal')}"  # type: ignore[union-attr]
        if not done:
            return False, f"timed out after {timeout:g} s in {describe(self.status or {})}"
        status = self.status or {}
        if name == "pose" and status.get("interruptions", 0) != interruptions:
            # a pose move ends where it was interrupted (a status in between may be missed)
            return False, (f"interrupted ({status.get('last_event')}); the pose move stopped "
                           f"at {describe(status)}: send the pose again")
        return True, describe(self.status or {})

    def run_when_ready(self, command: dict[str, Any], timeout: float,
                       retry_for: float | None = None) -> tuple[bool, str]:
        """`run`, retried every 0.5 s for up to ``retry_for`` [s] (default ``timeout``) while
        the planner refuses it only for a transient reason: paused by a motor-manager fault
        such as a late heartbeat (waits for the pause to clear), a resume from the measured
        pose in progress after one (waits for it to end), or no measured joint_states yet (the
        driver's feedback still being discovered). For scripted sequences (the demo, tests);
        an operator's one command is `run` once."""
        end = time.monotonic() + (timeout if retry_for is None else retry_for)
        ok, message = self.run(command, timeout)
        while not ok and any(word in message for word in TRANSIENT_REFUSALS):
            if time.monotonic() >= end:
                break
            self.spin_for(0.5)
            self.wait_until(lambda: not ((self.status or {}).get("paused")
                                         or (self.status or {}).get("resuming")),
                            max(0.0, end - time.monotonic()))
            ok, message = self.run(command, timeout)
        return ok, message

    def close(self) -> None:
        """Destroy the node."""
        self.node.destroy_node()


def planner_listens(status_publishers: Iterable[Any], command_subscribers: Iterable[Any]
                    ) -> bool:
    """Whether a node publishing ``planner_status`` also subscribes ``gait_command`` (graph
    endpoint infos with ``node_name`` and ``node_namespace``)."""
    def names(infos: Iterable[Any]) -> set[tuple[str, str]]:
        return {(i.node_name, i.node_namespace) for i in infos}

    return bool(names(status_publishers) & names(command_subscribers))


def _command_refusals(status: dict[str, Any]) -> int:
    """Refusals of gait commands in a ``planner_status`` (those of cmd_vel twists left out)."""
    return int(status.get("refusals", 0)) - int(status.get("twist_refusals", 0))


def outcome(ok: bool, message: str, prog: str = PROG) -> int:
    """Print ``<prog>: done|error: <message>`` (stdout or stderr) and return the exit status."""
    print(f"{prog}: {'done' if ok else 'error'}: {message}",
          file=sys.stdout if ok else sys.stderr)
    return 0 if ok else 1


def run_session(make: Callable[[], Any], body: Callable[[Any], int], quiet: bool,
                ros_args: Sequence[str] = ()) -> int:
    """``rclpy`` up (with ``ros_args``: ``--ros-args ...``, e.g. a namespace remap), ``make()``
    a console object (with ``printer`` and ``close``), run ``body(console)`` and return its
    exit status; 130 on Ctrl-C; everything shut down after."""
    import rclpy

    rclpy.init(args=[PROG, *ros_args])
    console = None
    try:
        console = make()
        if quiet:
            console.printer = lambda _line: None
        return body(console)
    except KeyboardInterrupt:
        return 130
    finally:
        if console is not None:
            console.close()
        rclpy.try_shutdown()


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``crawler-motion console``; returns the exit status. ROS arguments after
    ``--ros-args`` go to rclpy (``--ros-args -r __ns:=/crawler1``: the robot in that
    namespace)."""
    own, ros = split_ros_args(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(own)
    command: dict[str, Any] | None
    if args.action == "send":
        try:
            command = json.loads(args.json)
        except ValueError as exc:
            print(f"{PROG}: error: not valid JSON: {exc}", file=sys.stderr)
            return 2
        if not isinstance(command, dict):
            print(f"{PROG}: error: the command must be a JSON object", file=sys.stderr)
            return 2
    else:
        command = command_from_args(args)
    if args.action == "mission":
        from crawler_motion.tools.mission import main as mission_main

        return mission_main([args.file, *ros])  # a mission's own time limit, not --timeout
    if args.action in ("goto", "cancel"):
        from crawler_motion.tools.goto import run

        return run(args.action, getattr(args, "x", 0.0), getattr(args, "y", 0.0),
                   getattr(args, "frame", "odom"), args.timeout, args.quiet, ros)
    return run_session(Console, lambda console: _act(console, args, command), args.quiet, ros)


def _act(console: Console, args: argparse.Namespace, command: dict[str, Any] | None) -> int:
    """One console action on a connected planner; the exit status."""
    if not console.connect(min(args.timeout, 10.0)):
        print(f"{PROG}: error: no planner answering on planner_status/gait_command",
              file=sys.stderr)
        return 1
    if args.action in ("status", "recover"):
        from crawler_motion.tools.recover import run_driver_action

        return run_driver_action(console, args.action, args, PROG)
    if args.action == "twist":
        period = 1.0 / args.rate
        end = time.monotonic() + args.duration
        while time.monotonic() < end:
            console.twist(args.vx, args.vy, args.wz)
            console.spin_for(period)
        console.twist(0.0, 0.0, 0.0)
        ok = console.wait_until(lambda: (console.status or {}).get("state") in (
            "STANDING", "IDLE", "ESTOP"), args.timeout)
        print(f"{PROG}: {'done' if ok else 'timed out'}: {describe(console.status or {})}")
        return 0 if ok else 1
    assert command is not None
    return outcome(*console.run(command, args.timeout))
