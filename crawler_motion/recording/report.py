"""``crawler-motion report RUN.mcap -o REPORT/``: a recording as PNG plots and an index.html.

With a mission recorded (``mission_status``): a table per task and the map with the walked
path and the covered cells first (`report_mission`).
The plots: commanded against measured joints, the tracking error, the foot paths in
``base_link`` (forward kinematics of the measured joints), the body's path from
``odom`` over the terrain map with the goals, planner and driver states over time, and the
faults ``/diagnostics`` reported. ``index.html`` shows them under the run's summary figures.
A damaged recording: one line naming the file on stderr, a report of its readable part when
there is one, exit status 1.
"""

from __future__ import annotations

import argparse
import html
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from crawler_motion.errors import CrawlerMotionError
from crawler_motion.model.config import RobotConfig, load_config
from crawler_motion.recording import report_mission, report_plots, series
from crawler_motion.recording.reader import Recording, read_recording
from crawler_motion.runtime.cli_args import OneLineParser

PROG = "crawler-motion report"
INDEX = "index.html"


def summary(rec: Recording, err: series.Joints) -> list[tuple[str, str]]:
    """The run's summary figures as (name, value) rows."""
    _, xyz = series.body_path(rec)
    _, states = series.status_states(rec)
    rows = [("recording", str(rec.path)), ("duration", f"{rec.duration():.1f} s"),
            ("messages", f"{rec.count} on {len(rec.messages)} topics"),
            ("final planner state", states[-1] if states else "not recorded")]
    if len(err.t):
        rows.append(("largest tracking error", f"{np.nanmax(np.abs(err.q)):.4f} rad"))
        rows.append(("RMS tracking error", f"{np.sqrt(np.nanmean(err.q ** 2)):.4f} rad"))
    if len(xyz) > 1:
        rows.append(("body path length (odom)",
                     f"{np.linalg.norm(np.diff(xyz[:, :2], axis=0), axis=1).sum():.3f} m"))
        dx, dy = xyz[-1, :2] - xyz[0, :2]
        rows.append(("body displacement (odom)", f"{dx:+.3f} m forward x, {dy:+.3f} m y"))
    rows.append(("faults (/diagnostics not OK)", str(len(series.faults(rec)))))
    if rec.damage:
        rows.append(("damage", rec.damage))
    return rows


def write_report(rec: Recording, out: Path, robot: RobotConfig | None = None,
                 tool_width: float | None = None) -> Path:
    """Every picture and ``index.html`` into ``out`` for ``robot`` and the mission tool's
    ``tool_width`` [m] (the shipped configuration's when None); returns the index."""
    cfg = load_config() if robot is None or tool_width is None else None
    robot = robot if robot is not None else cfg.robot  # type: ignore[union-attr]
    width = tool_width if tool_width is not None else cfg.tool_width  # type: ignore[union-attr]
    names = list(robot.joint_names)
    cmd = series.joints(rec, "joint_commands", names)
    meas = series.joints(rec, "joint_states", names)
    err = series.tracking_error(cmd, meas)
    t_feet, feet = series.feet(meas, robot)
    pictures = [
        ("Commanded (dashed) and measured joints",
         report_plots.draw_joints(cmd, meas, list(robot.legs), out / "joints.png")),
        ("Tracking error", report_plots.draw_tracking(err, out / "tracking_error.png")),
        ("Foot paths in base_link (measured joints, forward kinematics)",
         report_plots.draw_feet(t_feet, feet, list(robot.legs), out / "feet.png")),
        ("Body path over the terrain map", report_plots.draw_path(rec, out / "path.png")),
        ("Planner and driver states", report_plots.draw_states(rec, out / "states.png")),
        ("Faults from /diagnostics",
         report_plots.draw_faults(series.faults(rec), out / "faults.png")),
    ]
    tasks = report_mission.task_rows(rec)
    if tasks:
        pictures.insert(0, ("Mission: map, covered cells, walked path",
                            report_mission.draw_mission(rec, out / "mission.png", width)))
    index = out / INDEX
    index.write_text(render_html(rec, summary(rec, err), pictures, tasks), encoding="utf-8")
    return index


def render_html(rec: Recording, rows: list[tuple[str, str]],
                pictures: list[tuple[str, Path | None]],
                tasks: Sequence[tuple[str, ...]] = ()) -> str:
    """The self-contained index page (pictures by relative file name; the mission's task
    table when ``tasks``)."""
    esc = html.escape
    mission = "" if not tasks else (
        "<h2>Mission tasks</h2><table><tr>"
        + "".join(f"<th>{esc(h)}</th>" for h in report_mission.HEADER) + "</tr>"
        + "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in row) + "</tr>"
                  for row in tasks) + "</table>")
    table = "\n".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in rows)
    topics = "\n".join(f"<tr><td>{esc(t)}</td><td>{esc(rec.types.get(t, ''))}</td>"
                       f"<td>{len(m)}</td></tr>" for t, m in sorted(rec.messages.items()))
    figures = "\n".join(
        f"<h2>{esc(title)}</h2>\n<img src=\"{esc(p.name)}\" alt=\"{esc(title)}\">"
        if p is not None else f"<h2>{esc(title)}</h2>\n<p>not recorded</p>"
        for title, p in pictures)
    faults = "\n".join(f"<tr><td>{t:.2f}</td><td>{esc(n)}</td><td>{esc(lv)}</td>"
                       f"<td>{esc(msg)}</td></tr>" for t, n, lv, msg in series.faults(rec)[:200])
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>Run report: {esc(rec.path.name)}</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:auto}}th{{text-align:left}}
img{{max-width:100%}}td,th{{padding:0 .6em}}</style></head><body>
<h1>Run report: {esc(rec.path.name)}</h1>
<table>{table}</table>
{mission}
{figures}
<h2>Topics</h2><table><tr><th>topic</th><th>type</th><th>messages</th></tr>{topics}</table>
<h2>Fault log (first 200)</h2>
<table><tr><th>t [s]</th><th>status</th><th>level</th><th>message</th></tr>{faults}</table>
</body></html>
"""


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """The report's options."""
    parser = OneLineParser(prog=PROG, description=__doc__.splitlines()[0])
    parser.add_argument("recording", type=Path, help="MCAP file of a run")
    parser.add_argument("-o", "--output", type=Path, default=Path("report"),
                        help="directory to write (default ./report)")
    parser.add_argument("--config", type=Path, default=None,
                        help="robot.yaml of the recorded robot, for the foot paths' kinematics "
                        "and calibration (default: the shipped one)")
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    """Write the report; returns the exit status (1 for a damaged or unreadable input)."""
    args = parse_args(argv)
    try:
        robot = load_config(args.config).robot
        rec = read_recording(args.recording)
        args.output.mkdir(parents=True, exist_ok=True)
        index = write_report(rec, args.output, robot)
    except (CrawlerMotionError, OSError) as exc:
        reason = exc if isinstance(exc, CrawlerMotionError) else f"{args.output}: {exc}"
        print(f"{PROG}: error: {reason}", file=sys.stderr)
        return 1
    print(f"report of {rec.count} messages ({rec.duration():.1f} s): {index}")
    if rec.damage:
        print(f"{PROG}: error: {rec.damage}; the report covers the readable part only",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
