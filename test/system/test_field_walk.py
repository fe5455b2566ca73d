"""The default walk (the ZMP diagonal) on the real-time stack: ``seabed_sim``, the driver and
the planner as processes on the cross-process bus, started by the demo as a user does. The
bounds are loose enough not to be flaky (runs vary by ±1-2° of pitch) and the roll bound is
tight enough that the old default fails it (its peak-to-peak roll on flat ground: 6.4°)."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

ADVANCE = re.compile(r"body advance +([-0-9.]+) mm of ([-0-9.]+) mm planned without slip "
                     r"\(([-0-9.]+)\), ([-+0-9.]+) mm left")
ATTITUDE = re.compile(r"body attitude +roll ([0-9.]+)°, pitch ([0-9.]+)° peak to peak")


def demo(tmp_path: Path, *args: str) -> str:
    pytest.importorskip("mujoco")
    proc = subprocess.run(
        [sys.executable, "-m", "crawler_motion.tools.cli", "demo", "--no-record",
         "--out", str(tmp_path), *args], capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "final state           STANDING" in proc.stdout, proc.stdout[-3000:]
    assert "HOLDING" not in proc.stdout and "hit an obstacle" not in proc.stderr
    return proc.stdout


@pytest.mark.slow
@pytest.mark.parametrize(("heading", "steps"), [(0.0, 5), (math.pi / 2, 4)],
                         ids=["forward", "sideways"])
def test_the_default_walk_on_the_real_time_stack(tmp_path: Path, heading: float,
                                                 steps: int) -> None:
    out = demo(tmp_path, "--steps", str(steps), "--heading", str(heading))
    advance = ADVANCE.search(out)
    attitude = ATTITUDE.search(out)
    assert advance and attitude, out[-2000:]
    ratio = float(advance.group(3))
    roll, pitch = float(attitude.group(1)), float(attitude.group(2))
    print(f"\nheading {heading:.2f}: advance {ratio:.2f}, roll {roll:.1f}°, pitch {pitch:.1f}° "
          f"peak to peak")
    assert 0.85 <= ratio <= 1.05
    assert roll <= 5.5 and pitch <= 8.0  # the old default: 6.4° and 7.5° (docs/seabed.md)
