"""Strict CSV of joint poses and foot positions: three finite numbers a row, optional header."""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from crawler_motion.errors import CalibrationError

POSE_HEADER = ("q_root", "q_shoulder", "q_knee")
FOOT_HEADER = ("x", "y", "z")


def parse_rows(lines: Iterable[str], header: tuple[str, ...], where: str) -> np.ndarray:
    """Rows ``(M, 3)`` of a CSV text; a first line equal to ``header`` is skipped; blank
    lines are ignored; a non-numeric, NaN or infinite cell or a wrong column count is refused
    with its line number."""
    rows = []
    for number, line in enumerate(lines, start=1):
        cells = [c.strip() for c in line.strip().split(",")]
        if cells == [""]:
            continue
        if number == 1 and tuple(cells) == header:
            continue
        if len(cells) != 3:
            raise CalibrationError(f"{where} line {number}: expected 3 values "
                                   f"({','.join(header)}), got {len(cells)}", key=where)
        try:
            values = [float(c) for c in cells]
        except ValueError:
            raise CalibrationError(f"{where} line {number}: not a number in {line.strip()!r}",
                                   key=where) from None
        if not all(math.isfinite(v) for v in values):
            raise CalibrationError(f"{where} line {number}: NaN or infinite value in "
                                   f"{line.strip()!r}", key=where)
        rows.append(values)
    if not rows:
        raise CalibrationError(f"{where}: no rows", key=where)
    return np.array(rows)


def read_rows(path: str | Path, header: tuple[str, ...]) -> np.ndarray:
    """`parse_rows` of the file ``path``."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CalibrationError(f"cannot read {path}: {exc}", path=path) from exc
    return parse_rows(text.splitlines(), header, str(path))


def format_rows(rows: np.ndarray, header: tuple[str, ...]) -> str:
    """CSV text with ``header`` and ``rows`` at full precision."""
    body = "".join(",".join(f"{v:.12g}" for v in row) + "\n" for row in rows)
    return ",".join(header) + "\n" + body
