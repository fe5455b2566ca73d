"""The machine's floor of the end-to-end bench: a bare ticker in a child process."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.tools import bench_e2e, wake_floor
from crawler_motion.tools.e2e_analysis import period_stats
from crawler_motion.tools.wake_floor import Floor


def floor_of(stamps: list[float], skipped: int, rate: float = 500.0) -> Floor:
    return Floor(rate, period_stats(np.asarray(stamps), rate), skipped, 2.0)


def test_the_child_ticks_on_the_system_clock():
    floor = wake_floor.measure(200.0, 0.5)
    # 0.5 s at 200 Hz: at most ~100 deadlines, each ticked once or counted as skipped (how many
    # the machine makes is the benchmark's figure, not this test's)
    assert 2 <= floor.timing.n and floor.timing.n + floor.skipped <= 102
    assert floor.cpu >= 0.0


@pytest.mark.parametrize(("stdout", "fragment"), [
    ("", "printed no figures"),
    ('{"stamps": [1.0, 2.0]}', "printed no figures"),
    ('{"stamps": [1.0], "missed": 0, "cpu": 1.0}', "ticked 1 times"),
])
def test_a_child_without_figures_is_an_error(monkeypatch, stdout, fragment):
    import subprocess

    monkeypatch.setattr(subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(
        a, 0, stdout=stdout, stderr=""))
    with pytest.raises(RuntimeError, match=fragment):
        wake_floor.measure(100.0, 0.1)


@pytest.mark.parametrize("argv", [[], ["500"], ["x", "1"], ["500", "0"], ["0.5", "1"],
                                  ["500", "nan"], ["20000", "1"]])
def test_the_child_refuses_bad_arguments(argv, capsys):
    assert wake_floor.main(argv) == 2
    assert capsys.readouterr().err.strip()


def test_a_failing_child_is_an_error(monkeypatch):
    monkeypatch.setattr(wake_floor, "__name__", "crawler_motion.tools.no_such_module")
    with pytest.raises(RuntimeError, match="floor's process failed"):
        wake_floor.measure(100.0, 0.1)


def test_verdict_names_what_the_floor_misses():
    even = [k * 0.002 for k in range(500)]
    assert wake_floor.verdict(floor_of(even, 0), 0.5).endswith("within the machine's reach")
    late = even[:250] + [t + 0.0045 for t in even[250:]]  # one period 4.5 ms late
    text = wake_floor.verdict(floor_of(late, 2), 0.5)
    assert "out of this machine's reach" in text and "skipped 2 deadlines (1 gaps" in text
    jittery = [t + (0.0008 if k % 2 else 0.0) for k, t in enumerate(even)]
    text = wake_floor.verdict(floor_of(jittery, 0), 0.5)
    assert "its p99 period error is 0.800 ms" in text and "skipped" not in text.split(":")[-1]


def test_the_floor_row_has_the_columns_of_the_timing_table(capsys):
    floor = floor_of([k * 0.002 for k in range(100)], 0)
    bench_e2e.print_timing_table([bench_e2e.RateResult(500.0)], 10.0, {500.0: floor})
    lines = [x for x in capsys.readouterr().out.splitlines() if x.startswith("|")]
    header, floor_row, failed = lines[0], lines[2], lines[3]
    assert floor_row.startswith("| floor (bare ticker) | 500 | 500.0 |")
    assert floor_row.count("|") == header.count("|") == failed.count("|")
