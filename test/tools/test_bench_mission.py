"""The mission-overhead bench: its map holds the harbour's boxes, a short run prints every
row and the verdicts (figures, not timing asserts)."""

from __future__ import annotations

import pytest

from crawler_motion.tools import bench_mission, cli


def test_the_map_holds_the_quay_and_the_box() -> None:
    view = bench_mission.harbour_view()
    assert view.obstacle.shape == (80, 80)
    col = int((1.4 - bench_mission.ORIGIN[0]) / bench_mission.RES)  # x = 1.4 m
    rows = {int((y - bench_mission.ORIGIN[1]) / bench_mission.RES): y
            for y in (0.575, -1.6, -1.0)}
    flags = {y: bool(view.obstacle[r, col]) for r, y in rows.items()}
    assert flags == {0.575: True, -1.6: True, -1.0: False}


def test_a_short_run_prints_every_row_and_both_verdicts(capsys) -> None:
    assert bench_mission.main(["--cycles", "40"]) == 0
    out = capsys.readouterr().out
    for label in ("navigator cycle", "re-plan of a cover slice", "covered-share measure",
                  "clean-up choice", "target <= 2 ms", "target <= 200 ms",
                  "navigator cycle, far goals", "target <= the period 100 ms"):
        assert label in out, out


def test_it_is_a_subcommand(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        cli.main(["bench-mission", "--help"])
    assert exc.value.code == 0 and "crawler-motion bench-mission" in capsys.readouterr().out
