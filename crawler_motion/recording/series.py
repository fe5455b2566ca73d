"""Time series of a recording for the report: joints, tracking error, body path, planner states,
faults, terrain map. Times are seconds since the recording's first message (log time)."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from crawler_motion.model.config import RobotConfig
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.recording.reader import Recording

#: ``diagnostic_msgs/DiagnosticStatus`` levels by value.
LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}


@dataclass
class Joints:
    """Joint positions over time: ``t`` (n,) [s], ``names`` (j,), ``q`` (n, j) [rad]."""

    t: np.ndarray
    names: list[str]
    q: np.ndarray


def _time(rec: Recording, log_time: int) -> float:
    return (log_time - rec.start()) * 1e-9


def joints(rec: Recording, topic: str, names: list[str]) -> Joints:
    """The positions of ``names`` on ``topic`` (NaN where a message lacks a joint)."""
    msgs = rec.topic(topic)
    q = np.full((len(msgs), len(names)), np.nan)
    for i, (_, msg) in enumerate(msgs):
        index = {name: k for k, name in enumerate(msg.name)}
        for j, name in enumerate(names):
            if name in index and index[name] < len(msg.position):
                q[i, j] = msg.position[index[name]]
    return Joints(np.array([_time(rec, t) for t, _ in msgs]), list(names), q)


def tracking_error(commanded: Joints, measured: Joints) -> Joints:
    """Measured minus the latest command at each measured sample after the first command
    [rad] (a zero-order hold: what the driver was tracking at that time)."""
    keep = measured.t >= (commanded.t[0] if len(commanded.t) else np.inf)
    t = measured.t[keep]
    index = np.searchsorted(commanded.t, t, side="right") - 1
    return Joints(t, measured.names, measured.q[keep] - commanded.q[index])


def feet(measured: Joints, robot: RobotConfig) -> tuple[np.ndarray, np.ndarray]:
    """Foot positions in ``base_link`` through the package's forward kinematics (with the
    configuration's calibration, if any) at every measured sample with all joints: times (n,)
    [s] and positions (n, legs, 3) [m]."""
    complete = ~np.isnan(measured.q).any(axis=1) if measured.q.size else np.zeros(0, bool)
    q = measured.q[complete].reshape(-1, robot.n_legs, 3)
    return measured.t[complete], forward_kinematics(robot, q)


def body_path(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """``odom`` positions: times (n,) [s] and x, y, z (n, 3) [m]."""
    msgs = rec.topic("odom")
    xyz = np.array([[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z]
                    for _, m in msgs]).reshape(-1, 3)
    return np.array([_time(rec, t) for t, _ in msgs]), xyz


def goals(rec: Recording) -> np.ndarray:
    """Goal positions x, y (n, 2) [m] from ``goal_pose``."""
    return np.array([[m.pose.position.x, m.pose.position.y]
                     for _, m in rec.topic("goal_pose")]).reshape(-1, 2)


def status_states(rec: Recording, topic: str = "planner_status") -> tuple[np.ndarray, list[str]]:
    """The ``state`` field of a JSON status topic over time (unparsable messages skipped)."""
    t, states = [], []
    for stamp, msg in rec.topic(topic):
        try:
            state = json.loads(msg.data).get("state")
        except (ValueError, AttributeError):
            continue
        if state is not None:
            t.append(_time(rec, stamp))
            states.append(str(state))
    return np.array(t), states


def faults(rec: Recording) -> list[tuple[float, str, str, str]]:
    """Every non-OK ``/diagnostics`` status: time [s], status name, level, message."""
    out = []
    for stamp, msg in rec.topic("/diagnostics"):
        for status in msg.status:
            level = int.from_bytes(status.level, "little") if isinstance(
                status.level, bytes) else int(status.level)
            if level:
                out.append((_time(rec, stamp), status.name, LEVELS.get(level, str(level)),
                            status.message))
    return out


#: The maps of a recording are merged one per this period [s] (and the last).
MOSAIC_PERIOD = 1.0


def terrain(rec: Recording) -> tuple[np.ndarray, tuple[float, float, float, float]] | None:
    """The run's ``terrain_map`` as one mosaic: every cell's latest known value over the
    maps (one per `MOSAIC_PERIOD` and the last; -1 where never known), since the live map is
    a window that moves with the robot and forgets what it leaves. Cells (rows = y) and the
    extent (x0, x1, y0, y1) [m]; None when not recorded. Maps of another resolution than the
    last are left out. Built once per recording (kept in ``rec.derived``)."""
    if "terrain" not in rec.derived:
        rec.derived["terrain"] = _mosaic(rec)
    return rec.derived["terrain"]


def _mosaic(rec: Recording) -> tuple[np.ndarray, tuple[float, float, float, float]] | None:
    msgs = rec.topic("terrain_map")
    if not msgs:
        return None
    picked, last = [], -np.inf
    for log_time, grid in msgs:
        t = _time(rec, log_time)
        if t - last >= MOSAIC_PERIOD:
            picked.append(grid)
            last = t
    if picked[-1] is not msgs[-1][1]:
        picked.append(msgs[-1][1])
    res = float(msgs[-1][1].info.resolution)
    picked = [g for g in picked if abs(g.info.resolution - res) <= 1e-9]
    # each map's place in cells of res (origins are whole cells of a rolling window)
    places = [(round(g.info.origin.position.x / res), round(g.info.origin.position.y / res),
               int(g.info.width), int(g.info.height)) for g in picked]
    ix0, iy0 = min(p[0] for p in places), min(p[1] for p in places)
    ix1, iy1 = max(p[0] + p[2] for p in places), max(p[1] + p[3] for p in places)
    cells = np.full((iy1 - iy0, ix1 - ix0), -1.0)
    for grid, (ix, iy, w, h) in zip(picked, places, strict=True):
        data = np.asarray(grid.data, dtype=float).reshape(h, w)
        window = cells[iy - iy0:iy - iy0 + h, ix - ix0:ix - ix0 + w]
        known = data >= 0
        window[known] = data[known]
    cells.setflags(write=False)  # shared by every figure of the report
    return cells, (ix0 * res, ix1 * res, iy0 * res, iy1 * res)
