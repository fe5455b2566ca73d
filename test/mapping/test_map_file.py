"""map_server maps (YAML + PGM): round trip, thresholds, and one-line errors for bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crawler_motion.errors import MapFileError
from crawler_motion.mapping.map_file import MapData, read_map, write_map

YAML = ("image: m.pgm\nresolution: 0.05\norigin: [-1.0, -0.5, 0.0]\nnegate: {negate}\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")


def test_round_trip_keeps_cells_origin_and_rows(tmp_path: Path) -> None:
    cells = np.zeros((4, 6), dtype=np.int8)
    cells[0, 1], cells[3, 5], cells[2, 2] = 100, 100, -1  # row 0 = bottom
    write_map(tmp_path / "a.yaml", MapData(cells, (-1.0, 2.0), 0.1))
    back = read_map(tmp_path / "a.yaml")
    assert np.array_equal(back.cells, cells)
    assert back.origin == (-1.0, 2.0) and back.resolution == 0.1
    pixels = (tmp_path / "a.pgm").read_bytes()[-24:]
    assert pixels[5] == 0  # the image's first row is the top of the map: cells[3, 5]


@pytest.mark.parametrize(("pixel", "negate", "value"), [
    (0, 0, 100), (254, 0, 0), (205, 0, -1), (89, 0, 100), (90, 0, -1),  # p = 0.651 / 0.647
    (205, 1, 100), (0, 1, 0), (49, 1, 0), (50, 1, -1)])  # negated: p = v/255 (50/255 > .196)
def test_thresholds_table(tmp_path: Path, pixel: int, negate: int, value: int) -> None:
    (tmp_path / "m.yaml").write_text(YAML.format(negate=negate))
    (tmp_path / "m.pgm").write_bytes(b"P5\n1 1\n255\n" + bytes([pixel]))
    assert int(read_map(tmp_path / "m.yaml").cells[0, 0]) == value


def test_plain_pgm_with_comments(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text(YAML.format(negate=0))
    (tmp_path / "m.pgm").write_bytes(b"P2\n# made by hand\n2 1\n255\n0 254\n")
    assert read_map(tmp_path / "m.yaml").cells.tolist() == [[100, 0]]


@pytest.mark.parametrize(("yaml_text", "pgm", "words"), [
    (None, b"P5\n1 1\n255\n\x00", "cannot read the map"),
    ("image: [\n", b"P5\n1 1\n255\n\x00", "not valid YAML"),
    ("resolution: 0.05\n", b"P5\n1 1\n255\n\x00", "'image'"),
    (YAML.format(negate=0).replace("0.05", "-1"), b"P5\n1 1\n255\n\x00", "resolution > 0"),
    (YAML.format(negate=0).replace("0.05", ".nan"), b"P5\n1 1\n255\n\x00", "finite"),
    (YAML.format(negate=0).replace("0.0]", "0.5]"), b"P5\n1 1\n255\n\x00", "yaw 0"),
    (YAML.format(negate=0).replace("[-1.0, -0.5, 0.0]", "[1, 2]"), b"P5\n1 1\n255\n\x00",
     "origin"),
    (YAML.format(negate=2), b"P5\n1 1\n255\n\x00", "negate"),
    (YAML.format(negate=0), None, "cannot read the map image"),
    (YAML.format(negate=0), b"GIF89a", "not a PGM"),
    (YAML.format(negate=0), b"P5\n2 2\n255\n\x00\x00\x00", "header says 2 x 2"),
    (YAML.format(negate=0), b"P5\n1 1\n65535\n\x00\x00", "8 bit"),
    (YAML.format(negate=0), b"P2\n2 1\n255\n0 x\n", "integers"),
])
def test_bad_map_files_are_one_line_errors(tmp_path: Path, yaml_text: str | None,
                                           pgm: bytes | None, words: str) -> None:
    if yaml_text is not None:
        (tmp_path / "m.yaml").write_text(yaml_text)
    if pgm is not None:
        (tmp_path / "m.pgm").write_bytes(pgm)
    with pytest.raises(MapFileError, match=words) as info:
        read_map(tmp_path / "m.yaml")
    assert "\n" not in str(info.value) and info.value.path.name in ("m.yaml", "m.pgm")
