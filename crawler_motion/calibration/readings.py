"""A calibration session's measurement file: one tracker reading a row, strictly checked.

CSV with a header naming the columns `COLUMNS` (any order, extra columns refused)::

    leg,q_root,q_shoulder,q_knee,x,y,z
    lf,0.1,0.3,1.2,0.1364,0.1621,-0.0410

``leg`` is a leg name of robot.yaml, ``q_*`` the commanded joint angles [rad], ``x y z`` the
target's position [m] in the measuring frame (base_link or the tracker's). Rows are numbered
as lines of the file (the header is line 1). Refused, naming the line: a missing or unknown
column, a wrong cell count, a non-number, NaN or infinity, an unknown leg, a pose outside the
joint limits, a leg's pose that repeats an earlier row's (a pose is read once; average
repeated readings first), and a leg with fewer poses than its identifiable parameters need.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from crawler_motion.errors import CalibrationError
from crawler_motion.model.config import RobotConfig

COLUMNS = ("leg", "q_root", "q_shoulder", "q_knee", "x", "y", "z")


@dataclass(frozen=True)
class Readings:
    """Rows of a session: leg indices ``(M,)``, poses ``(M, 3)`` [rad], measured points
    ``(M, 3)`` [m] and their line numbers ``(M,)`` in the file."""

    legs: np.ndarray
    q: np.ndarray
    points: np.ndarray
    lines: np.ndarray

    def subset(self, keep: np.ndarray) -> Readings:
        """The rows where the boolean mask ``keep`` ``(M,)`` is true."""
        return Readings(self.legs[keep], self.q[keep], self.points[keep], self.lines[keep])

    def measured_legs(self) -> tuple[int, ...]:
        """The measured legs' indices, ascending (robot.yaml's order)."""
        return tuple(int(i) for i in np.unique(self.legs))


def _header(cells: list[str], where: str) -> list[int]:
    missing = [c for c in COLUMNS if c not in cells]
    unknown = [c for c in cells if c not in COLUMNS]
    if missing or unknown or len(set(cells)) != len(cells):
        raise CalibrationError(f"{where} line 1: the header must name the columns "
                               f"{','.join(COLUMNS)} once each; missing: "
                               f"{','.join(missing) or 'none'}; unknown: "
                               f"{','.join(unknown) or 'none'}", key=where)
    return [cells.index(c) for c in COLUMNS]


def _row(cells: list[str], order: list[int], robot: RobotConfig, where: str
         ) -> tuple[int, list[float]]:
    if len(cells) != len(COLUMNS):
        raise CalibrationError(f"{where}: expected {len(COLUMNS)} values, got {len(cells)}")
    leg = cells[order[0]]
    if leg not in robot.legs:
        raise CalibrationError(f"{where}: leg '{leg}' does not exist; the legs are "
                               f"{list(robot.legs)}")
    try:
        values = [float(cells[i]) for i in order[1:]]
    except ValueError:
        raise CalibrationError(f"{where}: not a number in {','.join(cells)!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise CalibrationError(f"{where}: NaN or infinite value in {','.join(cells)!r}")
    q = np.array(values[:3])
    bad = np.flatnonzero((q < robot.lower) | (q > robot.upper))
    if bad.size:
        j = int(bad[0])
        raise CalibrationError(f"{where}: pose outside the joint limits: {COLUMNS[1 + j]} = "
                               f"{q[j]:.6g} rad not in [{robot.lower[j]:.6g}, "
                               f"{robot.upper[j]:.6g}]")
    return robot.legs.index(leg), values


def parse_readings(text: str, robot: RobotConfig, where: str) -> Readings:
    """`Readings` of the CSV ``text`` (see the module docstring); `CalibrationError` naming the
    line and the reason otherwise."""
    lines = text.splitlines()
    if not lines:
        raise CalibrationError(f"{where}: empty; needs the header {','.join(COLUMNS)}")
    order = _header([c.strip() for c in lines[0].split(",")], where)
    legs, values, numbers = [], [], []
    seen: dict[tuple[int, tuple[float, ...]], int] = {}
    for number, line in enumerate(lines[1:], start=2):
        cells = [c.strip() for c in line.split(",")]
        if cells == [""]:
            continue
        leg, row = _row(cells, order, robot, f"{where} line {number}")
        key = (leg, tuple(row[:3]))
        if key in seen:
            raise CalibrationError(f"{where} line {number}: duplicate row: leg "
                                   f"{robot.legs[leg]} at the pose of line {seen[key]} (a "
                                   f"pose is read once; average repeated readings first)")
        seen[key] = number
        legs.append(leg)
        values.append(row)
        numbers.append(number)
    if not values:
        raise CalibrationError(f"{where}: no readings")
    table = np.array(values)
    return Readings(np.array(legs), table[:, :3], table[:, 3:], np.array(numbers))


def read_readings(path: str | Path, robot: RobotConfig) -> Readings:
    """`parse_readings` of the file ``path``."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"cannot read {path}: {exc}", path=path) from exc
    return parse_readings(text, robot, str(path))


def format_readings(robot: RobotConfig, readings: Readings) -> str:
    """CSV text of ``readings`` (header `COLUMNS`, full precision)."""
    body = "".join(
        f"{robot.legs[int(leg)]}," + ",".join(f"{v:.12g}" for v in (*q, *p)) + "\n"
        for leg, q, p in zip(readings.legs, readings.q, readings.points, strict=True))
    return ",".join(COLUMNS) + "\n" + body
