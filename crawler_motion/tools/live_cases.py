"""The navigation cases walked on the real-time stack, and their figures (tests and docs).

Each case is a world, a start pose, navigator parameters and a task (a goal or a follow
command); `run_case` walks it with `live_nav.LiveNav` and `figures` measures what the targets
ask: the final distance to the goal, the body centre's least distance to the obstacles, the
wall cells of the final map (known, obstacle, free), obstacle cells more than one cell from a
real obstacle, contact ticks, and for a follow the mean clearance of the navigator's disc
from the mapped obstacle cells (what it controls) and from the real wall.
The obstacles are the world's boxes (axis-aligned, as the shipped worlds have them).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.bringup.supervisor import interrupts_held
from crawler_motion.navigation.mission import Task, parse_mission
from crawler_motion.tools.live_nav import LiveNav, LiveResult, MapSnapshot

#: Wall boxes of the shipped worlds: (x0, x1, y0, y1) [m].
BOXES: dict[str, tuple[tuple[float, float, float, float], ...]] = {
    "low_wall": ((0.80, 0.90, -0.30, 0.30),),
    "u_trap": ((0.50, 0.60, -0.35, 0.35), (-0.10, 0.50, 0.30, 0.40),
               (-0.10, 0.50, -0.40, -0.30)),
    "long_wall": ((-0.40, 2.60, 0.475, 0.575),),
    "harbour": ((-0.40, 3.00, 0.475, 0.675), (1.25, 1.55, -1.75, -1.45)),
}


@dataclass(frozen=True)
class Case:
    """A world, start pose (x, y [m], yaw [rad]), navigator parameters and a task: ``goal``
    (x, y) or ``follow`` (length [m], side)."""

    name: str
    world: str
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    navigator: dict[str, Any] = field(default_factory=dict)
    goal: tuple[float, float] | None = None
    follow: tuple[float, str] | None = None
    timeout: float = 150.0


CASES = {
    "wall_crab": Case("wall_crab", "low_wall", goal=(1.6, 0.0),
                      navigator={"steering": "crab"}),
    "wall_turn": Case("wall_turn", "low_wall", goal=(1.6, 0.0),
                      navigator={"steering": "turn"}),
    "u_trap_apf": Case("u_trap_apf", "u_trap", start=(-1.2, 0.0, 0.0), goal=(1.3, 0.0),
                       navigator={"method": "apf"}, timeout=300.0),
    **{f"follow_{int(s * 100)}": Case(f"follow_{int(s * 100)}", "long_wall",
                                      follow=(1.5, "left"),
                                      navigator={"method": "apf", "standoff": s})
       for s in (0.10, 0.15, 0.20)},
}


def box_distance(world: str, xy: np.ndarray) -> np.ndarray:
    """Least distance [m] from points ``(k, 2)`` to the world's boxes (0 inside one)."""
    best = np.full(len(xy), np.inf)
    for x0, x1, y0, y1 in BOXES[world]:
        dx = np.maximum(0.0, np.maximum(x0 - xy[:, 0], xy[:, 0] - x1))
        dy = np.maximum(0.0, np.maximum(y0 - xy[:, 1], xy[:, 1] - y1))
        best = np.minimum(best, np.hypot(dx, dy))
    return best


def map_distance(grid: MapSnapshot, xy: np.ndarray) -> np.ndarray:
    """Least distance [m] from points ``(k, 2)`` to the obstacle cells (squares) of a map (the
    final one: what the navigator keeps its disc's stand-off from)."""
    x, y = grid.cell_centres()
    obstacle = grid.data == 100
    cells = np.column_stack([x[obstacle], y[obstacle]])
    if len(cells) == 0:
        return np.full(len(xy), np.inf)
    half = grid.resolution / 2
    d = np.maximum(np.abs(xy[:, None, :] - cells[None, :, :]) - half, 0.0)
    return np.hypot(d[..., 0], d[..., 1]).min(axis=1)


def map_figures(world: str, grid: MapSnapshot,
                boxes: tuple[tuple[float, float, float, float], ...] | None = None,
                ) -> dict[str, Any]:
    """Cells of a map touching a box (``boxes``, default every box of the world) that the map
    knows, of them obstacles and free; obstacle cells whose square lies more than one cell
    from every box of the world."""
    x, y = grid.cell_centres()
    h = grid.resolution / 2
    data = grid.data
    touch = np.zeros(data.shape, dtype=bool)
    eps = 1e-6  # a cell that only shares an edge with the box does not touch it
    for x0, x1, y0, y1 in BOXES[world] if boxes is None else boxes:
        touch |= (x + h > x0 + eps) & (x - h < x1 - eps) & (y + h > y0 + eps) & (
            y - h < y1 - eps)
    known = touch & (data >= 0)
    centre_gap = box_distance(world, np.column_stack([x.ravel(), y.ravel()])).reshape(x.shape)
    stray = (data == 100) & (centre_gap - h * np.sqrt(2) > grid.resolution)
    return {"wall_cells_known": int(known.sum()),
            "wall_cells_obstacle": int((data[known] == 100).sum()),
            "wall_cells_free": int((data[known] == 0).sum()),
            "wall_cells_free_at": [(round(float(a), 3), round(float(b), 3)) for a, b in zip(
                x[known & (data == 0)], y[known & (data == 0)], strict=True)],
            "stray_obstacle_cells": int(stray.sum()),
            "stray_obstacle_cells_at": [(round(float(a), 3), round(float(b), 3)) for a, b in zip(
                x[stray], y[stray], strict=True)]}


def contact_figures(res: LiveResult) -> dict[str, Any]:
    """The simulator's hull or leg contact ticks of a run: in all (the seabed included), with
    an obstacle, and the first contact of each kind named."""
    return {"contact_ticks": res.contacts, "obstacle_contact_ticks": res.obstacle_contacts,
            "first_contacts": res.first_contacts}


def figures(case: Case, res: LiveResult, disc_radius: float) -> dict[str, float]:
    """The case's figures from a run (``disc_radius``: the navigator's disc [m] when its
    status does not say)."""
    xy = res.path[:, 1:3]
    if res.map is None:
        raise RuntimeError(f"{case.name}: no terrain_map received ({res.state}: {res.reason})")
    out: dict[str, float] = {"state": res.state, "reason": res.reason,  # type: ignore[dict-item]
                             "duration_s": res.duration, **contact_figures(res),
                             "min_centre_distance_m": float(box_distance(case.world,
                                                                         xy).min())}
    if case.goal is not None:
        out["final_error_m"] = float(np.hypot(*(xy[-1] - np.array(case.goal))))
    if case.follow is not None:
        disc_radius = res.disc_radius or disc_radius
        out["disc_radius_m"] = disc_radius
        walked = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
        steady = walked >= walked[-1] / 5  # after the first fifth, as the offline figure
        out["mean_clearance_m"] = float(map_distance(res.map, xy[steady]).mean() - disc_radius)
        out["mean_wall_clearance_m"] = float(
            box_distance(case.world, xy[steady]).mean() - disc_radius)
        out["walked_m"] = float(walked[-1])
    out.update(map_figures(case.world, res.map))
    out.update({f"cpu_{k}_pct": v for k, v in res.cpu.items()})
    return out


def run_case(case: Case, logs: Path, domain: int | None = None
             ) -> tuple[LiveResult, dict[str, float]]:
    """Walk ``case`` on the real-time stack (rclpy initialised by the caller in ROS domain
    ``domain``; None: the environment's)."""
    from crawler_motion.model.config import load_config
    from crawler_motion.navigation.parameters import NAVIGATOR_PARAMETERS

    spec = {p.name: p for p in NAVIGATOR_PARAMETERS}
    margin = case.navigator.get("margin", spec["margin"].default)
    feet = load_config().robot.standing_feet()
    radius = float(np.hypot(feet[:, 0], feet[:, 1]).max()) + float(margin)
    nav = LiveNav(logs, case.world, case.start, params={"navigator": case.navigator},
                  domain=domain)
    try:
        nav.start()
        if case.goal is not None:
            res = nav.goto(*case.goal, timeout=case.timeout)
        else:
            assert case.follow is not None
            res = nav.follow(*case.follow, timeout=case.timeout)
    finally:
        nav.close()
    return res, figures(case, res, radius)


def task_path(res: LiveResult, index: int) -> np.ndarray:
    """The path samples ``(k, 3)`` while task ``index`` (1-based) ran, from the times of the
    mission statuses."""
    times = [(m["received"], m.get("task_index")) for m in res.mission if "received" in m]
    start = min((t for t, i in times if i == index), default=None)
    end = min((t for t, i in times if i is not None and i > index), default=np.inf)
    if start is None:
        return np.zeros((0, 3))
    keep = (res.path[:, 0] >= start) & (res.path[:, 0] < end)
    return res.path[keep]


def boxes_in(world: str, polygon: list[tuple[float, float]],
             ) -> tuple[tuple[float, float, float, float], ...]:
    """The world's boxes that overlap a polygon's bounding box."""
    xs, ys = [p[0] for p in polygon], [p[1] for p in polygon]
    return tuple(b for b in BOXES[world]
                 if b[0] < max(xs) and b[1] > min(xs) and b[2] < max(ys) and b[3] > min(ys))


def end_map(res: LiveResult, index: int) -> MapSnapshot | None:
    """The map as task ``index`` (1-based) ended: the next task's first, else the final one
    (the live map is a window that moves with the robot and forgets what it leaves)."""
    return res.task_maps.get(index + 1, res.map)


def mission_figures(world: str, res: LiveResult, start: tuple[float, float],
                    tasks: list[Task]) -> dict[str, Any]:
    """A mission's figures: outcome, time, distance, covered share, home error, follow
    clearance (from the map, disc from the navigator), least body-centre distance to the
    obstacles, contact ticks, CPU per process; for a cover task over a box, the box's cells
    that the map held as obstacles as the task began and at the end (an obstacle found during
    the task: none, then some)."""
    kinds = [t.kind.value for t in tasks]
    xy = res.path[:, 1:3]
    last = res.mission[-1] if res.mission else {}
    covers = [m["covered"] for m in res.mission if m.get("task_kind") == "cover"
              and m.get("covered") is not None]
    out: dict[str, Any] = {"state": res.state, "reason": res.reason,
                           "duration_s": res.duration, "distance_m": last.get("distance"),
                           "covered": covers[-1] if covers else None,
                           "home_error_m": float(np.hypot(*(xy[-1] - np.array(start)))),
                           "min_centre_distance_m": float(box_distance(world, xy).min()),
                           **contact_figures(res)}
    if "follow" in kinds:
        index = kinds.index("follow") + 1
        seg = task_path(res, index)[:, 1:3]
        grid = end_map(res, index)
        if len(seg) > 5 and grid is not None:
            seg = seg[len(seg) // 5:]
            out["follow_clearance_m"] = float(map_distance(grid, seg).mean()
                                              - (res.disc_radius or 0.325))
    for index, task in enumerate(tasks, 1):
        inside = boxes_in(world, task.polygon) if task.kind.value == "cover" else ()
        grid = end_map(res, index)
        if inside and index in res.task_maps and grid is not None:
            out["cover_box_cells_at_start"] = map_figures(
                world, res.task_maps[index], inside)["wall_cells_obstacle"]
            out["cover_box_cells_at_end"] = map_figures(world, grid,
                                                        inside)["wall_cells_obstacle"]
    out.update({f"cpu_{k}_pct": v for k, v in res.cpu.items()})
    return out


def run_mission(world: str, text: str, logs: Path, domain: int | None = None,
                timeout: float = 1800.0, record: Path | None = None,
                progress: Callable[[dict[str, Any]], None] | None = None,
                ) -> tuple[LiveResult, dict[str, Any]]:
    """Walk a mission's text on the real-time stack with the navigator's defaults (rclpy
    initialised by the caller), recorded to ``record`` (MCAP) when given; ``progress`` is
    called with the latest ``mission_status`` while it runs."""
    tasks = list(parse_mission(text).tasks)
    nav = LiveNav(logs, world, domain=domain, record=record)
    try:
        nav.start()
        res = nav.mission(text, timeout, progress)
    finally:
        with interrupts_held():  # a second Ctrl-C must not leave processes behind
            nav.close()
    return res, mission_figures(world, res, (0.0, 0.0), tasks)
