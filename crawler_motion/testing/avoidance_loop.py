"""Lock-step closed loop of terrain avoidance: seabed physics, scanner, terrain mapper, navigator
and planner core in one process, on simulated time (deterministic, faster than real time).

The same cores as the ``seabed_sim``, ``terrain_mapper``, ``navigator`` and ``planner_node``
processes: physics stepped per 10 ms control tick, the planner core ticked at 100 Hz with the
measured joints, a scan every 0.1 s fused into the map, the navigator run on each fused scan
and its twist given to the planner as ``cmd_vel``. It records what the avoidance targets are
judged by: the path, headings, the virtual circle's clearance to the obstacle cells, hull and
leg contact, and the compute time of the map update and the navigator cycle.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from crawler_motion.errors import CommandError
from crawler_motion.mapping.mapper import MapperSettings, Pose, TerrainMapper
from crawler_motion.mapping.points import Mount
from crawler_motion.model.config import Config, load_scanner
from crawler_motion.model.rotations import quaternion_matrix, yaw_of
from crawler_motion.navigation.body import virtual_radius
from crawler_motion.navigation.methods import make_navigator
from crawler_motion.navigation.navigator import Method, NavigatorSettings, NavState, TerrainView
from crawler_motion.planner.core import PlannerCore
from crawler_motion.sim.seabed.contacts import body_contact
from crawler_motion.sim.seabed.model import SeabedModel, SimSettings
from crawler_motion.sim.seabed.scanner import RangeScanner, ScannerSettings
from crawler_motion.testing.lockstep import LockStep

CONTROL_PERIOD = 0.01  # [s]
SCAN_EVERY = 10  # control ticks (10 Hz)
ODOM_EVERY = 2  # control ticks (50 Hz)


@dataclass
class LoopResult:
    """What a closed-loop run did; times [s], lengths [m], angles [rad]."""

    state: str
    reason: str
    goal: tuple[float, float]
    walk_time: float = 0.0  # simulated time from the goal to the end of the walk
    time: list[float] = field(default_factory=list)
    path: list[tuple[float, float, float]] = field(default_factory=list)  # x, y, yaw per scan
    heading: list[float] = field(default_factory=list)  # world heading per scan (NaN: none)
    rule: list[str] = field(default_factory=list)
    clearance: list[float] = field(default_factory=list)  # circle to nearest obstacle cell
    radius: list[float] = field(default_factory=list)
    contact_samples: int = 0  # control ticks with hull or link contact
    map_ms: list[float] = field(default_factory=list)
    nav_ms: list[float] = field(default_factory=list)
    refusals: list[str] = field(default_factory=list)
    virtual_goals: int = 0  # distinct virtual goals the method used (apf)
    mapper: TerrainMapper | None = None

    @property
    def final_error(self) -> float:
        """Distance of the final body position from the goal [m]."""
        x, y, _ = self.path[-1]
        return math.hypot(x - self.goal[0], y - self.goal[1])


def terrain_view(mapper: TerrainMapper) -> TerrainView:
    """The navigator's view of the mapper's grid, as the published terrain_map shows it."""
    g, data = mapper.grid, mapper.occupancy()
    return TerrainView(g.origin.copy(), g.resolution, data >= 0, data >= 100, g.height.copy())


def circle_clearance(view: TerrainView, x: float, y: float, radius: float) -> float:
    """Distance [m] from a circle (centre x, y, ``radius``) to the nearest obstacle cell
    square (negative: they overlap); +inf without obstacle cells."""
    centres = view.centres(view.obstacle)
    if not len(centres):
        return math.inf
    half = view.resolution / 2
    dx = np.maximum(np.abs(centres[:, 0] - x) - half, 0.0)
    dy = np.maximum(np.abs(centres[:, 1] - y) - half, 0.0)
    return float(np.hypot(dx, dy).min() - radius)


class AvoidanceLoop(LockStep):
    """One robot in one world, walking to one goal."""

    def __init__(self, cfg: Config, world: str, nav: NavigatorSettings | None = None,
                 mapper: MapperSettings | None = None, seed: int = 0,
                 method: Method = Method.VIRTUAL_BODY,
                 start: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        """``start``: x, y [m], yaw [rad] of the body in the world."""
        self.cfg = cfg
        self.sm = SeabedModel(cfg.robot, SimSettings(start_pose=start), world)
        self.data = self.sm.make_data()
        self.sm.settle(self.data, 0.3)
        mount = load_scanner()
        self.scanner = RangeScanner(self.sm, mount, ScannerSettings(seed=seed))
        self.mapper = TerrainMapper(mapper or MapperSettings(),
                                    Mount.from_config(mount))
        self.nav = make_navigator(method, nav or NavigatorSettings())
        self.core = PlannerCore(cfg, 1.0 / CONTROL_PERIOD)
        self.t = 0.0
        self.ticks = 0

    def body(self) -> tuple[np.ndarray, np.ndarray]:
        """Rotation base_link -> world and position [m] of the body now."""
        return quaternion_matrix(self.data.qpos[3:7]), self.data.qpos[:3].copy()

    def tick(self) -> bool:
        """One control period: planner, physics; True when the hull or a link touches."""
        self.core.set_measured(self.joints(), self.t)
        target = self.core.tick(self.t)
        if target is not None:
            self.data.ctrl[:] = target.positions
        self.sm.settle(self.data, CONTROL_PERIOD)
        self.t += CONTROL_PERIOD
        self.ticks += 1
        if self.ticks % ODOM_EVERY == 0:
            rot, pos = self.body()
            self.mapper.add_odometry(Pose(self.t, rot, pos))
        return body_contact(self.sm, self.data)

    def run(self, goal: tuple[float, float], limit: float = 120.0) -> LoopResult:
        """Walk to ``goal`` (world [m]) for at most ``limit`` s of simulated time."""
        self.stand()
        res = LoopResult(state="", reason="", goal=goal, mapper=self.mapper)
        t0 = self.t
        self.nav.set_goal(goal[0], goal[1], self.t)
        while self.t - t0 < limit:
            res.contact_samples += self.tick()
            if self.ticks % SCAN_EVERY:
                continue
            self._cycle(res)
            if self.nav.state is not NavState.ACTIVE and self.core.state == "STANDING":
                break
        res.walk_time = self.t - t0
        if self.nav.state is NavState.ACTIVE:
            self.nav.cancel(f"not arrived within {limit:g} s of simulated time")
            self.nav.state = NavState.FAILED
        res.state, res.reason = self.nav.state.value, self.nav.reason
        return res

    def _cycle(self, res: LoopResult) -> None:
        rot, pos = self.body()
        start = time.perf_counter()
        self.mapper.add_scan(self.scanner.points(self.data), self.t)
        view = terrain_view(self.mapper)
        res.map_ms.append((time.perf_counter() - start) * 1e3)
        radius = virtual_radius(self.cfg.robot, self.joints())
        pose = (float(pos[0]), float(pos[1]), yaw_of(rot))
        start = time.perf_counter()
        out = self.nav.step(pose, radius, view, self.t)
        res.nav_ms.append((time.perf_counter() - start) * 1e3)
        if out.twist is not None:
            try:
                self.core.on_twist(*out.twist, self.t)
            except CommandError as exc:
                res.refusals.append(f"{self.t:.2f} s: {exc}")
        res.time.append(self.t)
        res.path.append(pose)
        res.heading.append(math.nan if out.heading is None else out.heading)
        res.rule.append("" if self.nav.rule is None else self.nav.rule.value)
        res.radius.append(radius)
        res.clearance.append(circle_clearance(view, pose[0], pose[1], radius))
        res.virtual_goals = self.nav.status().get("virtual_goals_used", 0)
