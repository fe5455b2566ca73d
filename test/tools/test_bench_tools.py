"""The benchmark and soak tools as subcommands, and their analysis (no processes started)."""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
import pytest

from crawler_motion.tools import cli, soak
from crawler_motion.tools.bench_e2e import (
    Pipeline,
    RateResult,
    parse_pipelines,
    parse_rates,
)
from crawler_motion.tools.e2e_analysis import (
    counters_text,
    fmt,
    match_groups,
    period_stats,
    planner_counters,
)
from crawler_motion.tools.e2e_records import GROUP_Q, GROUP_T, REC_Q, REC_STAMP, Rows
from crawler_motion.tools.e2e_stack import Snapshot, parse_sim_counters
from crawler_motion.tools.e2e_targets import TARGETS, print_against_floor, shortfalls
from crawler_motion.tools.procstat import cpu_percent
from crawler_motion.tools.wake_floor import Floor


@pytest.mark.parametrize("name", ["bench", "soak", "smoothness", "tune-smooth", "demo",
                                  "console"])
def test_tools_are_subcommands(name, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main([name, "--help"])
    assert exc.value.code == 0
    assert f"crawler-motion {name}" in capsys.readouterr().out.replace("\n", " ")


def test_bench_refuses_unknown_options_without_e2e(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["bench", "--rates", "100"])
    assert exc.value.code == 2
    assert "unrecognized arguments: --rates 100" in capsys.readouterr().err


def test_bench_e2e_forwards_its_options(monkeypatch):
    from crawler_motion.tools import bench, bench_e2e

    seen = []
    monkeypatch.setattr(bench_e2e, "main", lambda argv: seen.append(argv) or 0)
    assert bench.main(["--e2e", "--quick", "--rates", "100"]) == 0
    assert bench.main(["--e2e", "--seconds", "2"]) == 0
    assert seen == [["--seconds", "5", "--rates", "100"], ["--seconds", "15", "--seconds", "2"]]


def test_tune_smooth_names_the_extra_when_scipy_is_missing(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "scipy.optimize", None)
    assert cli.main(["tune-smooth"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("crawler-motion tune-smooth: error:")
    assert "scipy" in err and "crawler_motion[tune]" in err


@pytest.mark.parametrize(("argv", "message"), [
    (["--rate", "0.5"], "--rate must be in [1, 1000] Hz"),
    (["--rate", "1001"], "--rate must be in [1, 1000] Hz"),
    (["--duration", "0"], "--duration must be > 0"),
    (["--max-lag", "nan"], "--max-lag must be > 0"),
    (["--duration", "10", "--warmup", "10"], "--warmup must be shorter than --duration"),
    (["--command-timeout", "0.01"], "--command-timeout must be in [0.02, 10] s"),
    (["--command-timeout", "10.5"], "--command-timeout must be in [0.02, 10] s"),
])
def test_soak_refuses_bad_options(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        soak.parse_args(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--rate", "1"], ["--rate", "1000"],
                                  ["--command-timeout", "0.02"], ["--command-timeout", "10"]])
def test_soak_accepts_the_bounds(argv):
    soak.parse_args(argv)


@pytest.mark.parametrize(("text", "rates"), [("100,200,500", (100.0, 200.0, 500.0)),
                                              ("1", (1.0,)), ("1000,", (1000.0,))])
def test_parse_rates(text, rates):
    assert parse_rates(text) == rates


@pytest.mark.parametrize("text", ["", "0.5", "1001", "a,b"])
def test_parse_rates_refuses(text):
    import argparse

    with pytest.raises(argparse.ArgumentTypeError):
        parse_rates(text)


def test_rows_grow_in_chunks():
    rows = Rows(3, chunk=2)
    assert rows.array().shape == (0, 3)
    for i in range(5):
        row = rows.append()
        assert np.isnan(row).all()
        row[0] = i
    assert len(rows) == 5
    np.testing.assert_array_equal(rows.array()[:, 0], np.arange(5))


def test_period_stats():
    stamps = np.array([0.0, 0.01, 0.02, 0.035, 0.045])
    stats = period_stats(stamps, 100.0)
    assert stats.n == 5 and stats.missed == 1  # the 15 ms gap is > 1.5 periods
    assert stats.rate == pytest.approx(4 / 0.045)
    assert stats.longest_gap_ms == pytest.approx(15.0)
    assert stats.err_max_ms == pytest.approx(5.0)
    assert period_stats(np.array([1.0]), 100.0).n == 1
    assert math.isnan(period_stats(np.array([]), 100.0).rate)


def test_match_groups_in_order_and_latency():
    commands = np.full((3, REC_Q + 2), np.nan)
    commands[:, REC_STAMP] = [1.0, 1.01, 1.02]
    commands[:, REC_Q:] = [[0.1, 0.2], [0.1, 0.2], [0.3, 0.4]]
    groups = np.full((3, GROUP_Q + 2), np.nan)
    groups[:, GROUP_T] = [1.002, 1.013, 5.0]
    groups[:, GROUP_Q:] = [[0.1, 0.2], [0.1, np.nan], [0.3, 0.4]]  # the last one too late
    matching = match_groups(commands, groups, 1e-6)
    assert matching.command_group.tolist() == [0, 1, -1]
    assert matching.group_command.tolist() == [0, 1, -1]
    latency = matching.latency(commands, groups)
    np.testing.assert_allclose(latency[:2], [0.002, 0.003])
    assert math.isnan(latency[2])


def test_counters_and_formatting():
    assert planner_counters({"late_ticks": 3, "missed_ticks": "x", "state": "W"}) == {
        "late_ticks": 3}
    assert counters_text({"late_ticks": 1}, {"late_ticks": 4}) == "3 / -"
    assert (fmt(None), fmt(math.nan), fmt(1.234), fmt(2.0, 0)) == ("-", "-", "1.23", "2")
    assert cpu_percent({"wall": 0.0, "a": 1.0, "b": None}, {"wall": 2.0, "a": 2.0, "b": 1.0}
                       ) == {"a": 50.0}


def test_sim_counters_and_snapshot():
    assert parse_sim_counters("x SimCounters(targets=8, rejected=0) y") == {"targets": 8,
                                                                           "rejected": 0}
    assert parse_sim_counters("nothing") == {}
    snap = Snapshot(bus={"tx": "12", "bad": "x"})
    assert (snap.n("tx"), snap.n("bad"), snap.n("absent")) == (12, 0, 0)


@pytest.mark.parametrize(("text", "pipelines"), [
    ("two-node", (Pipeline.TWO_NODE,)),
    ("controller,two-node", (Pipeline.CONTROLLER, Pipeline.TWO_NODE)),
    ("controller, controller", (Pipeline.CONTROLLER,)),
])
def test_parse_pipelines(text, pipelines):
    assert parse_pipelines(text) == pipelines


@pytest.mark.parametrize("text", ["", "three-node", "controller,x"])
def test_parse_pipelines_refuses(text):
    with pytest.raises(argparse.ArgumentTypeError, match="pipelines must be among"):
        parse_pipelines(text)


def test_shortfalls_name_each_missed_bound_of_the_controller_target():
    stamps = np.arange(0.0, 2.0, 0.002)  # 500 Hz, exact
    floor = Floor(500.0, period_stats(stamps, 500.0), 3, 1.0)
    result = RateResult(500.0, Pipeline.CONTROLLER, timing=period_stats(stamps, 500.0),
                        lat_p99_ms=0.3, cpu={"controller": 15.0}, skipped=5)
    target = TARGETS[(Pipeline.CONTROLLER, 500.0)]
    assert shortfalls(result, target, floor, 10.0) == []  # 5 skipped: floor 3 + 2 allowed
    result.lat_p99_ms, result.cpu, result.skipped = 0.6, {"controller": 55.0}, 6
    assert shortfalls(result, target, floor, 10.0) == [
        "6 deadlines skipped (floor 3, allowed 5)", "p99 latency 0.60 ms",
        "CPU 1.10 ms per command"]
    jittery = np.sort(stamps + np.random.default_rng(1).uniform(0, 0.0015, stamps.size))
    result = RateResult(500.0, Pipeline.TWO_NODE, timing=period_stats(jittery, 500.0),
                        lat_p99_ms=1.0, cpu={"planner": 10.0, "driver": 10.0})
    two = TARGETS[(Pipeline.TWO_NODE, 500.0)]
    assert [s.split(" (")[0] for s in shortfalls(result, two, floor, 10.0)] == [
        f"p99 period error {result.timing.err_p99_ms:.3f} ms"]
    assert shortfalls(result, two, None, 10.0) == []  # no floor: its bounds not judged
    assert shortfalls(RateResult(500.0, error="boom"), target, floor, 10.0) == ["failed: boom"]


def test_the_against_floor_table_gives_ratios_and_verdicts(capsys):
    stamps = np.arange(0.0, 2.0, 0.002)
    floor = Floor(500.0, period_stats(stamps + np.tile([0.0, 1e-4], 500), 500.0), 1, 1.0)
    good = RateResult(500.0, Pipeline.CONTROLLER, timing=period_stats(stamps, 500.0),
                      lat_p99_ms=0.2, cpu={"controller": 10.0})
    slow = RateResult(1000.0, Pipeline.CONTROLLER, timing=period_stats(stamps, 500.0),
                      cpu={"controller": 60.0})
    assert not print_against_floor([good, slow], {500.0: floor}, 10.0)
    rows = [x for x in capsys.readouterr().out.splitlines() if x.startswith("| controller")]
    assert "| 0 / 1 / -1 |" in rows[0] and "0.0x" in rows[0] and rows[0].endswith("**met** |")
    assert "**NOT met**: achieved 500.0 Hz; CPU 60 %" in rows[1]
