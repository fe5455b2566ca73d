"""The mission part of a run report: a table per task and the map with the walked path, the
covered cells and the obstacles, from ``mission_status``, ``odom``, ``terrain_map`` and
``/diagnostics`` of a recording (empty when it holds no mission).

Per task: its kind, time [s] and distance walked [m] (from the mission's own ``distance``),
the covered share (cover tasks: the navigator's measured share), the least distance of the
body centre while it ran to the obstacle cells of the run's map [m] (`series.terrain`: every
cell's latest known value; the live map is a window that forgets what the robot leaves),
the hull-or-leg contact ticks the simulator counted meanwhile (``/diagnostics``; "-" on the
real robot), the diagnostics entries not OK meanwhile, and the outcome (done, or the
failure's reason).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from crawler_motion.recording import series
from crawler_motion.recording.reader import Recording
from crawler_motion.runtime.diagnostic_names import BODY_CONTACTS_KEY

#: The picture shows the walked path and this much around it [m].
VIEW_PAD = 0.8

HEADER = ("task", "kind", "time [s]", "distance [m]", "covered", "min clearance [m]",
          "contacts", "faults", "outcome")


def statuses(rec: Recording) -> list[tuple[float, dict[str, Any]]]:
    """The ``mission_status`` messages as (time [s], fields)."""
    out = []
    for log_time, msg in rec.topic("mission_status"):
        try:
            data = json.loads(msg.data)
        except ValueError:
            continue
        if data.get("mission") is not None:
            out.append(((log_time - rec.start()) * 1e-9, data))
    return out


def _contacts(rec: Recording) -> list[tuple[float, int]]:
    out = []
    for log_time, msg in rec.topic("/diagnostics"):
        for status in msg.status:
            for kv in status.values:
                if kv.key == BODY_CONTACTS_KEY:
                    out.append(((log_time - rec.start()) * 1e-9, int(kv.value)))
    return out


def _obstacles(rec: Recording) -> np.ndarray:
    """Centres ``(k, 2)`` of the last map's obstacle cells."""
    grid = series.terrain(rec)
    if grid is None:
        return np.zeros((0, 2))
    cells, (x0, x1, y0, _y1) = grid
    rows, cols = np.nonzero(cells >= 100)
    res = (x1 - x0) / cells.shape[1]
    return np.column_stack([x0 + (cols + 0.5) * res, y0 + (rows + 0.5) * res])


def task_rows(rec: Recording) -> list[tuple[str, ...]]:
    """One row per task that ran (`HEADER`)."""
    seen = statuses(rec)
    if not seen:
        return []
    t_path, xyz = series.body_path(rec)
    obst = _obstacles(rec)
    contacts = _contacts(rec)
    faults = series.faults(rec)
    rows = []
    indices = sorted({s["task_index"] for _, s in seen})
    for index in indices:
        mine = [(t, s) for t, s in seen if s["task_index"] == index]
        t0, t1 = mine[0][0], mine[-1][0]
        last = mine[-1][1]
        before = [s for _, s in seen if s["task_index"] < index]
        d0 = before[-1]["distance"] if before else 0.0
        during = (t_path >= t0) & (t_path <= t1)
        clear = "-"
        if during.any() and len(obst):
            pts = xyz[during, :2]
            gap = np.hypot(*(pts[:, None, :] - obst[None, :, :]).transpose(2, 0, 1)).min()
            clear = f"{gap:.3f}"
        hits = [c for t, c in contacts if t0 <= t <= t1]
        outcome = "done" if index < indices[-1] or last["state"] == "DONE" else (
            f"{last['state'].lower()}: {last.get('reason', '')}")
        covered = last.get("covered") if last.get("task_kind") == "cover" else None
        rows.append((str(index), str(last.get("task_kind")), f"{t1 - t0:.1f}",
                     f"{last['distance'] - d0:.2f}",
                     "-" if covered is None else f"{100 * covered:.1f} %", clear,
                     str(hits[-1] - hits[0]) if hits else "-",
                     str(sum(1 for t, *_ in faults if t0 <= t <= t1)), outcome))
    return rows


def draw_mission(rec: Recording, path: Path, tool_width: float) -> Path | None:
    """The run's map (`series.terrain`: obstacles dark, free white, unknown grey), the cells
    within half the tool width of the walked path (covered, green) and the path."""
    from crawler_motion.recording import report_plots

    _, xyz = series.body_path(rec)
    grid = series.terrain(rec)
    if not statuses(rec) or not len(xyz) or grid is None:
        return None
    cells, extent = grid
    res = (extent[1] - extent[0]) / cells.shape[1]
    ys, xs = np.mgrid[0:cells.shape[0], 0:cells.shape[1]]
    centres = np.column_stack([(extent[0] + (xs.ravel() + 0.5) * res),
                               (extent[2] + (ys.ravel() + 0.5) * res)])
    covered = np.zeros(len(centres), dtype=bool)
    for k in range(0, len(xyz), 256):
        d = centres[:, None, :] - xyz[None, k:k + 256, :2]
        covered |= (np.hypot(d[..., 0], d[..., 1]) <= tool_width / 2).any(axis=1)
    fig, axes = report_plots.figure(size=(5.5, 5.0))
    ax = axes[0][0]
    ax.imshow(np.ma.masked_less(cells, 0), origin="lower", extent=extent, cmap="Greys",
              vmin=0, vmax=100)
    ax.imshow(np.ma.masked_equal(covered.reshape(cells.shape).astype(float), 0),
              origin="lower", extent=extent, cmap="Greens", vmin=0, vmax=1.5, alpha=0.6)
    ax.plot(xyz[:, 0], xyz[:, 1], "C0", lw=1.0, label="walked path (odom)")
    ax.plot(*xyz[0, :2], "go", label="start")
    ax.set_facecolor("#d9d9d9")  # never known
    lo, hi = xyz[:, :2].min(axis=0) - VIEW_PAD, xyz[:, :2].max(axis=0) + VIEW_PAD
    ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), xlabel="x [m] (odom)", ylabel="y [m]",
           title="mission: map of the run (obstacles dark, free white, unknown grey),\n"
           "covered cells (green), walked path")
    ax.title.set_fontsize(9)
    ax.set_aspect("equal", adjustable="box")
    ax.legend(loc="lower left", fontsize=8)
    return report_plots.save(fig, path)
