"""``crawler-motion mission MISSION.yaml``: send a mission to the navigator and follow it.

Checks the file first (one line and exit 1 for a bad one: nothing is sent), sends it on
``mission``, prints a progress line on every change of task or state and every few seconds
(task i of n, its kind, the state, progress %, covered %, distance walked), and exits 0 when
every task is done, 2 when a task failed or the mission was cancelled (with the reason), 1
when the navigator refused it or did not answer. Ctrl-C cancels the mission (the navigator's
``~/cancel``): the robot stands. ``crawler-motion mission cancel`` cancels a running one.
ROS arguments after ``--ros-args`` go to rclpy (a namespace: ``-r __ns:=/crawler1``).
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from crawler_motion.errors import CommandError, CrawlerMotionError
from crawler_motion.navigation.mission import parse_mission
from crawler_motion.runtime.cli_args import OneLineParser, finite_number, split_ros_args

PROG = "crawler-motion mission"
#: Seconds between repeated progress lines.
PROGRESS_PERIOD = 5.0
#: The navigator must answer a mission within this time [s], sent this many times in it.
ANSWER_TIMEOUT = 10.0
ANSWER_TRIES = 5
#: Exit status per final mission state.
EXIT = {"DONE": 0, "FAILED": 2, "CANCELLED": 2, "REFUSED": 1}


def progress_line(status: dict[str, Any]) -> str:
    """One line of a ``mission_status``."""
    if status.get("mission") is None:
        return f"{status.get('state')}: {status.get('reason')}"
    covered = status.get("covered")
    line = (f"task {status.get('task_index')} of {status.get('tasks')} "
            f"({status.get('task_kind')}): {status.get('state')}, "
            f"{100 * float(status.get('progress') or 0):.0f} %")
    if covered is not None:
        line += f", covered {100 * covered:.1f} %"
    line += f", walked {status.get('distance', 0):.2f} m, {status.get('elapsed', 0):.0f} s"
    return line + (f" ({status['reason']})" if status.get("reason") else "")


class ProgressPrinter:
    """Prints a ``mission_status``'s progress line on every change of task, state or reason
    and every `PROGRESS_PERIOD` seconds."""

    def __init__(self) -> None:
        self.last = ""
        self.printed = 0.0

    def __call__(self, status: dict[str, Any]) -> None:
        key = json.dumps([status.get(k) for k in ("task_index", "state", "reason")])
        if key != self.last or time.monotonic() - self.printed >= PROGRESS_PERIOD:
            print(f"{PROG}: {progress_line(status)}", flush=True)
            self.last, self.printed = key, time.monotonic()


def mission_text(path: Path) -> tuple[str, str]:
    """The checked text to send and its id (a unique one added when the file has none);
    `CommandError` naming the file and the problem."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CommandError(f"{path}: cannot read it ({exc})") from None
    mission = parse_mission(text)
    if mission.id:
        return text, mission.id
    data = yaml.safe_load(text)
    mid = f"{path.stem}-{int(time.time())}"
    return yaml.safe_dump({"id": mid, "tasks": data["tasks"]}, sort_keys=False), mid


class MissionClient:
    """A node that sends a mission and follows ``mission_status``."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from std_msgs.msg import String
        from std_srvs.srv import Trigger

        self._rclpy, self._string, self._trigger = rclpy, String, Trigger
        self.node = rclpy.create_node("crawler_mission_console")
        self.status: dict[str, Any] | None = None
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub = self.node.create_publisher(String, "mission", 10)
        self.node.create_subscription(String, "mission_status", self._on_status, latched)
        self.cancel_client = self.node.create_client(Trigger, "navigator/cancel")

    def _on_status(self, msg: Any) -> None:
        try:
            self.status = json.loads(msg.data)
        except ValueError:
            pass

    def spin_until(self, predicate: Any, timeout: float) -> bool:
        """Spin until ``predicate()`` or ``timeout`` [s]."""
        end = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() >= end:
                return False
            self._rclpy.spin_once(self.node, timeout_sec=0.05)
        return True

    def cancel(self, timeout: float = 5.0) -> bool:
        """Call ``navigator/cancel``."""
        if not self.cancel_client.wait_for_service(timeout_sec=timeout):
            return False
        future = self.cancel_client.call_async(self._trigger.Request())
        return self.spin_until(future.done, timeout)

    def run(self, text: str, mid: str, timeout: float) -> int:
        """Send and follow; the exit status."""
        if not self.spin_until(lambda: self.pub.get_subscription_count() > 0, 10.0):
            print(f"{PROG}: error: no navigator listening on mission", file=sys.stderr)
            return 1
        before = json.dumps(self.status)

        def answered() -> bool:
            status = self.status or {}
            return json.dumps(self.status) != before and (
                status.get("mission") == mid or status.get("state") == "REFUSED")

        # sent again until answered: a subscriber just discovered may not hear the first one
        # (the navigator ignores a repeat of the mission it runs)
        for _ in range(ANSWER_TRIES):
            self.pub.publish(self._string(data=text))
            if self.spin_until(answered, ANSWER_TIMEOUT / ANSWER_TRIES):
                break
        else:
            print(f"{PROG}: error: the navigator did not take the mission", file=sys.stderr)
            return 1
        show = ProgressPrinter()
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            status = self.status or {}
            show(status)
            if status.get("state") in EXIT and (status.get("mission") in (mid, None)):
                code = EXIT[status["state"]]
                print(f"{PROG}: {'done' if code == 0 else 'error'}: {progress_line(status)}",
                      file=sys.stdout if code == 0 else sys.stderr)
                return code
            self.spin_until(lambda: False, 0.2)
        self.cancel()
        print(f"{PROG}: error: not done within {timeout:g} s; mission cancelled", file=sys.stderr)
        return 2


def run_simulated(world: str, text: str, timeout: float, record: Path | None = None) -> int:
    """The mission on a simulated stack of its own (a fresh ROS domain); its figures."""
    import random
    import tempfile

    import rclpy

    from crawler_motion.bringup.checks import check_output, check_world
    from crawler_motion.tools.live_cases import run_mission

    try:
        check_world(world)
        if record is not None:
            check_output(record, "recording")
    except CrawlerMotionError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    domain = random.randint(102, 200)
    rclpy.init(domain_id=domain)
    try:
        with tempfile.TemporaryDirectory(prefix="mission-") as logs:
            res, fig = run_mission(world, text, Path(logs), domain, timeout, record,
                                   progress=ProgressPrinter())
    except KeyboardInterrupt:
        print(f"{PROG}: cancelled: the simulated stack is stopped"
              f"{'' if record is None else f' ({record} is complete)'}", file=sys.stderr)
        return 130
    finally:
        rclpy.try_shutdown()
    for key, value in fig.items():
        print(f"{key}: {value:.4g}" if isinstance(value, float) else f"{key}: {value}")
    return EXIT.get(res.state, 2)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; the exit status."""
    own, ros = split_ros_args(sys.argv[1:] if argv is None else argv)
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("mission", help="the mission file (YAML), or 'cancel'")
    parser.add_argument("--timeout", type=finite_number("timeout", positive=True),
                        default=7200.0, help="give up (and cancel) after [s] (default 7200)")
    parser.add_argument("--sim", metavar="WORLD", default=None, help="bring the simulated "
                        "stack up in WORLD first (as crawler-motion sim), run the mission, print "
                        "its figures and stop everything")
    parser.add_argument("--record", metavar="RUN.mcap", type=Path, default=None,
                        help="with --sim: record every topic to this MCAP file (then "
                        "crawler-motion report RUN.mcap draws the mission)")
    args = parser.parse_args(own)
    text = mid = ""
    if args.mission != "cancel":
        try:
            text, mid = mission_text(Path(args.mission))
        except CommandError as exc:
            print(f"{PROG}: error: {exc}", file=sys.stderr)
            return 1
    if args.record is not None and args.sim is None:
        parser.error("--record needs --sim (with a running stack: crawler-motion sim --record)")
    if args.sim is not None:
        return run_simulated(args.sim, text, args.timeout, args.record)
    import rclpy

    rclpy.init(args=[PROG, *ros])
    client = None
    try:
        client = MissionClient()
        if args.mission == "cancel":
            ok = client.cancel(min(args.timeout, 10.0))
            print(f"{PROG}: {'done: cancelled' if ok else 'error: no navigator/cancel'}")
            return 0 if ok else 1
        return client.run(text, mid, args.timeout)
    except KeyboardInterrupt:
        if client is not None:
            client.cancel()
        print(f"{PROG}: cancelled: the robot stands", file=sys.stderr)
        return 130
    finally:
        if client is not None:
            client.node.destroy_node()
        rclpy.try_shutdown()
