"""The mission part of the run report, from a synthetic recording: a row per task with time,
distance, covered share, clearance, contacts, faults and outcome; the picture; none without a
mission."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace as Ns

import numpy as np

from crawler_motion.recording import series
from crawler_motion.recording.reader import Recording
from crawler_motion.recording.report import write_report
from crawler_motion.recording.report_mission import HEADER, draw_mission, task_rows
from crawler_motion.runtime.diagnostic_names import BODY_CONTACTS_KEY

SEC = 1_000_000_000


def odom(x: float, y: float) -> Ns:
    return Ns(pose=Ns(pose=Ns(position=Ns(x=x, y=y, z=0.07))))


def status(index: int, kind: str, state: str, distance: float, covered=None, reason=""):
    return Ns(data=json.dumps({"mission": "m", "task_index": index, "tasks": 2,
                               "task_kind": kind, "state": state, "distance": distance,
                               "covered": covered, "reason": reason}))


def diag(contacts: int, level: int = 0) -> Ns:
    kv = Ns(key=BODY_CONTACTS_KEY, value=str(contacts))
    return Ns(status=[Ns(name="seabed_sim: physics", level=level, message="x", values=[kv])])


def recording(final: str = "DONE") -> Recording:
    rec = Recording(Path("synthetic.mcap"))
    rec.messages["odom"] = [(k * SEC // 10, odom(0.01 * k, 0.0)) for k in range(200)]
    grid = np.zeros((40, 40), dtype=np.int8)
    grid[20, 30] = 100  # an obstacle cell at (1.025, 0.025)
    rec.messages["terrain_map"] = [(19 * SEC, Ns(data=grid.ravel().tolist(), info=Ns(
        width=40, height=40, resolution=0.05, origin=Ns(position=Ns(x=-0.5, y=-1.0)))))]
    rec.messages["mission_status"] = [
        (0, status(1, "goto", "RUNNING", 0.0)), (5 * SEC, status(1, "goto", "RUNNING", 0.5)),
        (10 * SEC, status(2, "cover", "RUNNING", 1.0, 0.2)),
        (19 * SEC, status(2, "cover", final, 1.9, 0.93, "" if final == "DONE" else "why"))]
    rec.messages["/diagnostics"] = [(0, diag(0)), (12 * SEC, diag(0, level=2)),
                                    (18 * SEC, diag(3))]
    return rec


def test_a_row_per_task() -> None:
    rows = task_rows(recording())
    assert len(rows) == 2 and len(rows[0]) == len(HEADER)
    goto, cover = rows
    assert goto[:4] == ("1", "goto", "5.0", "0.50") and goto[-1] == "done"
    assert cover[1] == "cover" and cover[3] == "1.40" and cover[4] == "93.0 %"
    assert cover[6] == "3" and cover[7] == "1" and cover[-1] == "done"
    assert float(cover[5]) < float(goto[5])  # the path nears the obstacle in the cover task


def test_a_failed_task_shows_its_reason() -> None:
    assert task_rows(recording("FAILED"))[-1][-1] == "failed: why"


def test_no_mission_no_rows(tmp_path: Path) -> None:
    rec = recording()
    del rec.messages["mission_status"]
    assert task_rows(rec) == [] and draw_mission(rec, tmp_path / "m.png", 0.16) is None


def test_the_report_shows_the_mission(tmp_path: Path) -> None:
    index = write_report(recording(), tmp_path)
    text = index.read_text()
    assert "Mission tasks" in text and "93.0 %" in text
    assert (tmp_path / "mission.png").stat().st_size > 1000


def window(t: float, x0: float, cells: dict[tuple[int, int], int]) -> tuple[int, Ns]:
    """A 4 x 2 map of 0.5 m cells at origin (x0, 0), unknown but for ``cells`` (col, row)."""
    data = np.full((2, 4), -1, dtype=np.int8)
    for (col, row), value in cells.items():
        data[row, col] = value
    return int(t * SEC), Ns(data=data.ravel().tolist(), info=Ns(
        width=4, height=2, resolution=0.5, origin=Ns(position=Ns(x=x0, y=0.0))))


def test_the_map_is_the_runs_mosaic_of_the_moving_window() -> None:
    rec = Recording(Path("synthetic.mcap"))
    rec.messages["terrain_map"] = [
        window(0.0, 0.0, {(0, 0): 100, (1, 0): 0}),  # an obstacle at x 0-0.5 m
        window(0.5, 0.5, {(0, 1): 100}),  # within the merge period: left out
        window(1.0, 1.0, {(0, 0): 0, (3, 1): 100}),  # moved on: the obstacle left behind
        window(1.5, 1.5, {(0, 0): 100})]  # the last map: always merged
    cells, extent = series.terrain(rec)
    assert extent == (0.0, 3.5, 0.0, 1.0)
    assert cells.tolist() == [[100, 0, 0, 100, -1, -1, -1], [-1, -1, -1, -1, -1, 100, -1]]
