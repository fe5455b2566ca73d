"""crawler_motion.mapping.clouds: a cloud whose layout does not fit is refused, never read
past its data (a field offset beyond the point step used to kill terrain_mapper)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from crawler_motion.mapping.clouds import FLOAT32, MAX_POINTS, read_float32

XYZ = ("x", "y", "z")


def cloud(points: np.ndarray, step: int = 12, offsets=(0, 4, 8), datatype: int = FLOAT32,
          count: int = 1, width: int | None = None, data: bytes | None = None):
    fields = [SimpleNamespace(name=n, offset=o, datatype=datatype, count=count)
              for n, o in zip(XYZ, offsets, strict=True)]
    raw = np.zeros((len(points), max(step, 12)), dtype=np.uint8)
    for k, o in enumerate(offsets):
        if 0 <= o and o + 4 <= step:
            raw[:, o:o + 4] = points[:, k].astype("<f4").view(np.uint8).reshape(-1, 4)
    return SimpleNamespace(fields=fields, point_step=step, width=len(points) if width is None
                           else width, height=1, is_bigendian=False,
                           data=raw.tobytes() if data is None else data)


POINTS = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])


def test_a_good_cloud_reads_back():
    np.testing.assert_array_equal(read_float32(cloud(POINTS), XYZ), POINTS)
    padded = cloud(POINTS, step=16, offsets=(0, 4, 12))  # a field ending at the step: fine
    np.testing.assert_array_equal(read_float32(padded, XYZ), POINTS)
    assert read_float32(cloud(POINTS[:0]), XYZ).shape == (0, 3)


@pytest.mark.parametrize("bad", [
    {"offsets": (0, 4, 12)},  # z's 4 bytes beyond the 12-byte step
    {"offsets": (0, 4, 1_000_000)},
    {"offsets": (0, -4, 8)},
    {"step": 0},
    {"step": -12},
    {"datatype": 8},  # float64
    {"count": 3},
    {"width": 3},  # more points than data
    {"width": MAX_POINTS + 1},
    {"data": b"\x00" * 5},
])
def test_a_cloud_that_does_not_fit_is_refused(bad):
    assert read_float32(cloud(POINTS, **bad), XYZ) is None


def test_a_missing_field_is_refused():
    assert read_float32(cloud(POINTS), ("x", "y", "z", "variance")) is None
