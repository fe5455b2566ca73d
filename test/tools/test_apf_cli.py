"""``crawler-motion path`` and ``coverage``: CSV out, the summary line, exit 0 / 2 / 1."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crawler_motion.mapping.map_file import MapData, write_map
from crawler_motion.navigation.apf.maps import TWO_OBSTACLES, U_TRAP, box_grid
from crawler_motion.tools.cli import main


def _write(path: Path, boxes: tuple, origin: tuple, size: tuple) -> Path:
    grid = box_grid(boxes, origin, size, 0.05)
    write_map(path, MapData(np.where(grid.obstacle, 100, 0).astype(np.int8), origin, 0.05))
    return path


@pytest.fixture
def u_map(tmp_path: Path) -> str:
    return str(_write(tmp_path / "u.yaml", U_TRAP, (-2.0, -2.0), (4.0, 4.0)))


def _rows(text: str) -> np.ndarray:
    lines = text.strip().splitlines()
    assert lines[0] == "x,y"
    return np.array([[float(v) for v in line.split(",")] for line in lines[1:]])


def test_path_virtual_reaches_exit_0(u_map: str, capsys: pytest.CaptureFixture) -> None:
    code = main(["path", "--map", u_map, "--start", "-1.2", "0", "--goal", "1.3", "0"])
    out, err = capsys.readouterr()
    assert code == 0
    pts = _rows(out)
    assert np.allclose(pts[0], [-1.2, 0]) and np.allclose(pts[-1], [1.3, 0])
    assert err.startswith("reached; length ") and "virtual goals " in err
    assert len(err.strip().splitlines()) == 1
    assert float(err.split("min clearance ")[1].split(" m")[0]) > 0


def test_path_plain_is_trapped_exit_2(u_map: str, capsys: pytest.CaptureFixture) -> None:
    code = main(["path", "--map", u_map, "--start", "-1.2", "0", "--goal", "1.3", "0",
                 "--method", "apf"])
    out, err = capsys.readouterr()
    assert code == 2 and err.startswith("trapped (local minimum") and len(_rows(out)) > 1


@pytest.mark.parametrize("args", [
    ["--start", "nan", "0", "--goal", "1.3", "0"],
    ["--start", "-1.2", "0", "--goal", "0.55", "0"],
    ["--start", "-9", "0", "--goal", "1.3", "0"],
    ["--start", "-1.2", "0", "--goal", "1.3", "0", "--step", "0"],
    ["--start", "-1.2", "0", "--goal", "1.3", "0", "--standoff", "-1"],
    ["--start", "-1.2", "0", "--goal", "1.3", "0", "--method", "astar"],
    ["--start", "-1.2", "--goal", "1.3", "0"],
])
def test_path_bad_input_exit_1_no_path(u_map: str, args: list[str],
                                       capsys: pytest.CaptureFixture) -> None:
    try:
        code = main(["path", "--map", u_map, *args])
    except SystemExit as exc:  # argparse: usage errors exit 1 too (2 means trapped)
        code = exc.code
    assert code == 1
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "error" in err


def test_path_missing_map_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    code = main(["path", "--map", str(tmp_path / "none.yaml"), "--start", "0", "0",
                 "--goal", "1", "0"])
    out, err = capsys.readouterr()
    assert code == 1 and out == "" and "cannot read the map" in err


def test_coverage_prints_route_and_share(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = _write(tmp_path / "c.yaml", TWO_OBSTACLES, (-0.5, -0.5), (3.0, 3.0))
    code = main(["coverage", "--map", str(path), "--area", "0", "0", "2", "2", "--spacing",
                 "0.3", "--standoff", "0.03"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert len(_rows(out)) > 100
    share = float(err.split("covered ")[1].split(" %")[0])
    assert share >= 95.0 and "every slice done" in err

