"""Navigation on the real-time stack: ``crawler-motion sim``'s processes, a goal or a follow
command, and what a user would measure (the walked path from ``odom``, the final
``terrain_map``, the simulator's hull-or-leg contact count, CPU per process).

`LiveNav` needs ``rclpy.init`` first. It brings the stack up with the bring-up's lineup and
supervisor (every process in real time, CAN at the bus rate), stands the robot, and runs
`goto` or `follow` through the navigator's public topics, as the console does.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.bringup.lineup import BringUpOptions, lineup
from crawler_motion.bringup.supervisor import Supervisor
from crawler_motion.runtime.diagnostic_names import (
    BODY_CONTACTS_KEY,
    FIRST_CONTACTS_KEY,
    OBSTACLE_CONTACTS_KEY,
)
from crawler_motion.testing.bus import BusSpec
from crawler_motion.testing.stack import isolated_env
from crawler_motion.tools.procstat import cpu_seconds

#: Navigation states that end a goal or a follow, and mission states that end a mission.
FINAL = ("ARRIVED", "FAILED", "IDLE")
MISSION_FINAL = ("DONE", "FAILED", "CANCELLED", "REFUSED")
#: Longest wait for a goal's, follow's or mission's publisher to match its subscriber [s].
MATCH_TIMEOUT = 10.0


@dataclass
class MapSnapshot:
    """A ``terrain_map`` as arrays: ``data`` (rows y; -1 unknown, 0 free, 100 obstacle), the
    origin (x, y [m]) and the resolution [m]."""

    data: np.ndarray
    origin: tuple[float, float]
    resolution: float

    @classmethod
    def of(cls, grid: Any) -> MapSnapshot:
        """From a nav_msgs/OccupancyGrid."""
        info = grid.info
        return cls(np.asarray(grid.data, dtype=np.int16).reshape(info.height, info.width),
                   (info.origin.position.x, info.origin.position.y), float(info.resolution))

    def cell_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """x and y [m] of every map cell's centre."""
        rows, cols = self.data.shape
        x = self.origin[0] + (np.arange(cols) + 0.5) * self.resolution
        y = self.origin[1] + (np.arange(rows) + 0.5) * self.resolution
        return np.meshgrid(x, y)


@dataclass
class LiveResult:
    """One run: outcome and reason, the body path ``(k, 3)`` (t [s], x, y [m]), the final map,
    contact ticks and CPU % of one core by process over the run; for a mission every
    ``mission_status`` received and the map as each task began (by 1-based task index)."""

    state: str = ""
    reason: str = ""
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    map: MapSnapshot | None = None
    contacts: int = 0
    obstacle_contacts: int = 0  # of them, ticks touching anything but the seabed
    first_contacts: str = ""  # the simulator's first contact of each kind, named
    cpu: dict[str, float] = field(default_factory=dict)
    duration: float = 0.0
    disc_radius: float | None = None  # the navigator's mean disc radius (apf) [m]
    mission: list[dict[str, Any]] = field(default_factory=list)  # mission_status received
    task_maps: dict[int, MapSnapshot] = field(default_factory=dict)


class _Watch:
    """Subscriptions of the run: odom path, terrain_map, navigation_status, contacts."""

    def __init__(self, node: Any) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from nav_msgs.msg import OccupancyGrid, Odometry
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from std_msgs.msg import String

        self.lock = threading.Lock()
        self.path: list[tuple[float, float, float]] = []
        self.grid: Any = None
        self.status: dict[str, Any] = {}
        self.contacts = self.obstacle_contacts = 0
        self.first_contacts = ""
        self.discs: list[float] = []  # the navigator's disc radius while active [m]
        self.mission: dict[str, Any] = {}
        self.missions: list[dict[str, Any]] = []  # every mission_status received
        self.task_grids: dict[int, Any] = {}  # the map as each task began
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(Odometry, "odom", self._odom, 10)
        node.create_subscription(OccupancyGrid, "terrain_map", self._map, 2)
        node.create_subscription(String, "navigation_status", self._status, latched)
        node.create_subscription(DiagnosticArray, "/diagnostics", self._diag, 10)
        node.create_subscription(String, "mission_status", self._mission, latched)

    def _odom(self, msg: Any) -> None:
        p = msg.pose.pose.position
        with self.lock:
            self.path.append((time.monotonic(), p.x, p.y))

    def _map(self, msg: Any) -> None:
        self.grid = msg

    def _status(self, msg: Any) -> None:
        try:
            self.status = json.loads(msg.data)
        except ValueError:
            return
        if self.status.get("state") == "ACTIVE" and self.status.get("disc_radius"):
            self.discs.append(float(self.status["disc_radius"]))

    def _mission(self, msg: Any) -> None:
        try:
            self.mission = json.loads(msg.data)
        except ValueError:
            return
        self.missions.append({**self.mission, "received": time.monotonic()})
        index = self.mission.get("task_index")
        if isinstance(index, int) and index not in self.task_grids and self.grid is not None:
            self.task_grids[index] = self.grid

    def _diag(self, msg: Any) -> None:
        for status in msg.status:
            for kv in status.values:
                if kv.key == BODY_CONTACTS_KEY:
                    self.contacts = int(kv.value)
                elif kv.key == OBSTACLE_CONTACTS_KEY:
                    self.obstacle_contacts = int(kv.value)
                elif kv.key == FIRST_CONTACTS_KEY:
                    self.first_contacts = kv.value


class LiveNav:
    """The simulated robot's whole stack in real time, driven by goals and follow commands."""

    def __init__(self, logs: Path, world: str,
                 start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 params: Mapping[str, Mapping[str, Any]] | None = None,
                 domain: int | None = None, record: Path | None = None,
                 split: bool = False) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        extra = {k: dict(v) for k, v in (params or {}).items()}
        extra.setdefault("seabed_sim", {})["start_pose"] = [float(v) for v in start_pose]
        self.options = BringUpOptions(world=world, bus=BusSpec.fresh(), extra=extra,
                                      record=record, split=split)
        self.env = isolated_env(domain)  # rclpy's domain here (None: the environment's)
        self.node = rclpy.create_node("live_nav_watch")
        self.watch = _Watch(self.node)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self._spin = threading.Thread(target=self._spin_until_shutdown, daemon=True)
        self.sup = Supervisor(logs, self.env, self._ready)

    def _ready(self, nodes: Any) -> bool:
        seen = set(self.node.get_node_names_and_namespaces())
        return all((name, "/") in seen for name in nodes)

    def start(self, timeout: float = 60.0) -> None:
        """Bring the stack up and stand the robot (`RuntimeError` with the logs if not)."""
        self._spin.start()
        self.sup.start(lineup(self.options), timeout, lambda *_: None)
        from crawler_motion.tools.console import Console

        console = Console("live_nav_console")
        console.printer = lambda _line: None
        try:
            if not console.connect(30.0):
                raise RuntimeError(f"no planner\n{self.tails()}")
            ok, message = console.run_when_ready({"command": "stand"}, 30.0, retry_for=30.0)
            if not ok:
                raise RuntimeError(f"stand: {message}\n{self.tails()}")
        finally:
            console.close()

    def tails(self) -> str:
        """The last log lines of every process."""
        return "\n".join(f"--- {n} ---\n" + "\n".join(self.sup.tail(n, 15))
                         for n in self.sup.procs)

    def goto(self, x: float, y: float, timeout: float) -> LiveResult:
        """Send a goal in ``odom`` and wait for its end."""
        from geometry_msgs.msg import PoseStamped

        msg = PoseStamped()
        msg.header.frame_id = "odom"
        msg.pose.position.x, msg.pose.position.y = float(x), float(y)
        msg.pose.orientation.w = 1.0
        pub = self.node.create_publisher(PoseStamped, "goal_pose", 10)
        return self._run(pub, msg, timeout)

    def follow(self, length: float, side: str, timeout: float) -> LiveResult:
        """Send a follow command (navigator method ``apf``) and wait for its end."""
        from std_msgs.msg import String

        pub = self.node.create_publisher(String, "follow_command", 10)
        text = json.dumps({"length": float(length), "side": side})
        return self._run(pub, String(data=text), timeout)

    def mission(self, text: str, timeout: float,
                progress: Callable[[dict[str, Any]], None] | None = None) -> LiveResult:
        """Send a mission's text and wait for its end (`LiveResult.state`: the mission's);
        ``progress`` is called with the latest ``mission_status`` every 0.1 s meanwhile."""
        from std_msgs.msg import String

        pub = self.node.create_publisher(String, "mission", 10)
        return self._run(pub, String(data=text), timeout, mission=True,
                         progress=progress)

    def _run(self, pub: Any, msg: Any, timeout: float, mission: bool = False,
             progress: Callable[[dict[str, Any]], None] | None = None) -> LiveResult:
        """Publish ``msg`` once on ``pub`` after it matched its subscriber (a sample published
        before the match is lost), then watch the run for up to ``timeout`` [s]."""
        w = self.watch
        end = time.monotonic() + min(timeout, MATCH_TIMEOUT)
        while pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.05)
        if pub.get_subscription_count() == 0:
            raise TimeoutError(f"nothing subscribes to {pub.topic_name} after "
                               f"{min(timeout, MATCH_TIMEOUT):g} s: is the navigator running?")
        cpu0 = {n: cpu_seconds(p.pid) for n, p in self.sup.procs.items()}
        began = time.monotonic()
        with w.lock:
            w.path.clear()
        w.discs.clear()
        pub.publish(msg)
        end = began + timeout
        def state() -> Any:
            return w.mission.get("state") if mission else w.status.get("state")

        while time.monotonic() < end:
            if state() in ("ACTIVE", "RUNNING"):
                break
            time.sleep(0.05)
        while time.monotonic() < end and state() not in (*FINAL, *MISSION_FINAL):
            if self.sup.exited() is not None:
                break
            if progress is not None and w.mission.get("mission") is not None:
                progress(dict(w.mission))
            time.sleep(0.1)
        wall = time.monotonic() - began
        cpu = {n: 100.0 * ((cpu_seconds(p.pid) or 0.0) - (cpu0[n] or 0.0)) / wall
               for n, p in self.sup.procs.items()}
        time.sleep(1.5)  # the map after the stop
        res = self._result(wall, cpu)
        if mission:
            res.state, res.reason = str(w.mission.get("state")), str(w.mission.get("reason"))
            res.mission = list(w.missions)
            res.task_maps = {i: MapSnapshot.of(g) for i, g in w.task_grids.items()}
        return res

    def _result(self, wall: float, cpu: dict[str, float]) -> LiveResult:
        w = self.watch
        res = LiveResult(state=str(w.status.get("state")), reason=str(w.status.get("reason")),
                         contacts=w.contacts, obstacle_contacts=w.obstacle_contacts,
                         first_contacts=w.first_contacts, cpu=cpu, duration=wall,
                         disc_radius=float(np.mean(w.discs)) if w.discs else None)
        with w.lock:
            res.path = np.array(w.path) if w.path else np.zeros((0, 3))
        if w.grid is not None:
            res.map = MapSnapshot.of(w.grid)
        return res

    def _spin_until_shutdown(self) -> None:
        """The executor's spin; ends quietly when the context is shut down (rclpy's own
        SIGINT handler does that on Ctrl-C)."""
        from rclpy.executors import ExternalShutdownException

        try:
            self.executor.spin()
        except ExternalShutdownException:
            pass

    def close(self) -> None:
        """Stop every process and the watch node."""
        self.sup.stop()
        self.executor.shutdown()
        self._spin.join(5.0)
        self.node.destroy_node()
