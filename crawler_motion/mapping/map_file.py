"""Maps in the ROS map_server format: a YAML file and a PGM image (reader and writer, pure).

The YAML keys are those of map_server / nav2: ``image`` (relative to the YAML file),
``resolution`` [m], ``origin`` [x, y, yaw] (the lower-left pixel's corner; yaw must be 0),
``negate``, ``occupied_thresh``, ``free_thresh`` and ``mode`` (``trinary``, the default; the
others are read as trinary too). A pixel's occupancy is ``p = (255 − v)/255`` (``v/255`` when
negated): obstacle when ``p > occupied_thresh``, free when ``p < free_thresh``, unknown between.
The image is binary (P5) or plain (P2) PGM, 8 bit. Rows: the image's first row is the top of
the map (largest y); `MapData.cells` has row 0 at the bottom (smallest y), as OccupancyGrid.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from crawler_motion.errors import MapFileError

#: Cell values of `MapData.cells` (those of nav_msgs/OccupancyGrid).
OBSTACLE, FREE, UNKNOWN = 100, 0, -1
#: Pixel values the writer uses (map_saver's).
PIXEL = {OBSTACLE: 0, FREE: 254, UNKNOWN: 205}


@dataclass(frozen=True)
class MapData:
    """An occupancy map: ``cells[row, col]`` int8 (100, 0, −1), row 0 at the bottom, corner
    ``origin`` (x, y) [m], ``resolution`` [m]."""

    cells: np.ndarray
    origin: tuple[float, float]
    resolution: float

    @property
    def obstacle(self) -> np.ndarray:
        """Obstacle cells (unknown cells are not)."""
        return self.cells == OBSTACLE


def _number(meta: dict, key: str, path: Path, default: float | None = None) -> float:
    value = meta.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            value):
        raise MapFileError(f"{path}: '{key}' must be a finite number, got {value!r}", path=path)
    return float(value)


def _read_pgm(path: Path) -> np.ndarray:
    """An 8-bit PGM (P5 or P2) as ``(rows, cols)`` uint8, first row at the top."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise MapFileError(f"{path}: cannot read the map image ({exc.strerror})",
                           path=path) from None
    head = re.match(rb"(P[25])\s+((?:#[^\n]*\n\s*)*)(\d+)\s+(?:#[^\n]*\n\s*)*(\d+)\s+"
                    rb"(?:#[^\n]*\n\s*)*(\d+)\s", data)
    if head is None:
        raise MapFileError(f"{path}: not a PGM image (P5 or P2 header expected)", path=path)
    kind, cols, rows, maxval = head[1], int(head[3]), int(head[4]), int(head[5])
    if not 0 < maxval < 256 or cols == 0 or rows == 0:
        raise MapFileError(f"{path}: PGM must be 8 bit with a size > 0, got {cols} x {rows} "
                           f"max {maxval}", path=path)
    body = data[head.end():]
    if kind == b"P5":
        if len(body) != rows * cols:
            raise MapFileError(f"{path}: PGM holds {len(body)} bytes of pixels, its header "
                               f"says {cols} x {rows} = {rows * cols}", path=path)
        pixels = np.frombuffer(body, dtype=np.uint8)
    else:
        try:
            pixels = np.array(body.split(), dtype=np.int64)
        except ValueError:
            raise MapFileError(f"{path}: P2 pixels must be integers", path=path) from None
        if len(pixels) != rows * cols or pixels.min() < 0 or pixels.max() > maxval:
            raise MapFileError(f"{path}: P2 holds {len(pixels)} pixels in 0..{maxval}, "
                               f"expected {rows * cols}", path=path)
    return (pixels.astype(np.float64) * 255.0 / maxval).round().astype(np.uint8).reshape(
        rows, cols)


def read_map(yaml_path: str | Path) -> MapData:
    """Read a map_server map; `MapFileError` (one line) for anything wrong."""
    path = Path(yaml_path)
    try:
        meta = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise MapFileError(f"{path}: cannot read the map ({exc.strerror})", path=path) from None
    except yaml.YAMLError as exc:
        raise MapFileError(f"{path}: not valid YAML ({str(exc).splitlines()[0]})",
                           path=path) from None
    if not isinstance(meta, dict) or not isinstance(meta.get("image"), str):
        raise MapFileError(f"{path}: a map YAML needs an 'image' file name", path=path)
    resolution = _number(meta, "resolution", path)
    origin = meta.get("origin")
    if not (isinstance(origin, list) and len(origin) == 3):
        raise MapFileError(f"{path}: 'origin' must be [x, y, yaw], got {origin!r}", path=path)
    ox, oy, yaw = (_number({"origin": v}, "origin", path) for v in origin)
    occupied = _number(meta, "occupied_thresh", path, 0.65)
    free = _number(meta, "free_thresh", path, 0.196)
    if resolution <= 0 or yaw != 0.0 or not 0 <= free <= occupied <= 1:
        raise MapFileError(f"{path}: needs resolution > 0 (got {resolution}), origin yaw 0 "
                           f"(got {yaw}), 0 <= free_thresh <= occupied_thresh <= 1 (got "
                           f"{free}, {occupied})", path=path)
    negate = meta.get("negate", 0)
    if negate not in (0, 1, False, True):
        raise MapFileError(f"{path}: 'negate' must be 0 or 1, got {negate!r}", path=path)
    pixels = _read_pgm(path.parent / meta["image"])
    p = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
    cells = np.where(p > occupied, OBSTACLE, np.where(p < free, FREE, UNKNOWN)).astype(np.int8)
    return MapData(cells[::-1].copy(), (ox, oy), resolution)


def write_map(yaml_path: str | Path, data: MapData) -> None:
    """Write ``data`` as ``<name>.yaml`` + ``<name>.pgm`` (P5) next to it."""
    path = Path(yaml_path)
    image = path.with_suffix(".pgm")
    pixels = np.full(data.cells.shape, PIXEL[UNKNOWN], dtype=np.uint8)
    pixels[data.cells == OBSTACLE] = PIXEL[OBSTACLE]
    pixels[data.cells == FREE] = PIXEL[FREE]
    rows, cols = pixels.shape
    try:
        image.write_bytes(b"P5\n%d %d\n255\n" % (cols, rows) + pixels[::-1].tobytes())
        path.write_text(yaml.safe_dump({
            "image": image.name, "mode": "trinary", "resolution": float(data.resolution),
            "origin": [float(data.origin[0]), float(data.origin[1]), 0.0], "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196}, sort_keys=False), encoding="utf-8")
    except OSError as exc:
        raise MapFileError(f"{path}: cannot write the map ({exc.strerror})", path=path) from None
