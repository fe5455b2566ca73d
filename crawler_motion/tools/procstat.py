"""CPU time and resident memory of a process, from /proc."""

from __future__ import annotations

import os
from pathlib import Path

#: Clock ticks per second of the utime / stime fields of /proc/<pid>/stat [Hz].
CLK_TCK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float | None:
    """User + system CPU time of a process (all its threads) [s]; None if it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2:].split()  # fields[0] is field 3 (state)
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # fields 14 utime, 15 stime


def rss_mb(pid: int) -> float | None:
    """Resident set size (VmRSS) of a process [MiB]; None if it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        return None
    return None



def cpu_percent(before: dict[str, float | None], after: dict[str, float | None]
                ) -> dict[str, float]:
    """CPU % of one core per process between two samples of `cpu_seconds` by name, the time
    [s] under key ``"wall"``."""
    wall = float(after["wall"] or 0.0) - float(before["wall"] or 0.0)
    out = {}
    for name, value in after.items():
        start = before.get(name)
        if name == "wall" or value is None or start is None or wall <= 0:
            continue
        out[name] = 100.0 * (value - start) / wall
    return out
