"""The mission soak with faults, 3 minutes (``make soak-mission`` runs 30): every process of
``crawler-motion sim --split`` in real time, faults from a seeded plan (a kill of the navigator
and of the mapper, stops of the driver and of the planner, a future-stamped odometry message),
each checked: the robot holds in time, nothing moves while the fault lasts, the documented
recovery works; no collision; the recording opens in mcap's reader and in rosbags."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("mujoco")

ROOT = Path(__file__).resolve().parents[2]


def test_a_three_minute_mission_soak_with_faults_passes(tmp_path: Path) -> None:
    cli = [str(Path(sys.executable).parent / "crawler-motion"), "soak", "--mission",
           str(ROOT / "config" / "missions" / "soak.yaml"), "--duration", "180", "--quiet",
           "8", "12", "--seed", "3", "--logs", str(tmp_path)]
    done = subprocess.run(cli, capture_output=True, text=True, timeout=600)
    text = done.stdout + done.stderr
    assert done.returncode == 0, text
    rows = [line for line in text.splitlines() if line.startswith("| ") and " ok" in line]
    assert len(rows) >= 4, text
    assert "rosbags" in text and "mcap" in text, text
