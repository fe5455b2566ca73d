"""Reading float32 fields out of a sensor_msgs/PointCloud2 safely (pure: the message is only
read through its attributes; no rclpy).

One reader for every node that takes a cloud (``scan`` in the terrain mapper,
``terrain_heights`` in the navigator): a cloud whose fields, offsets, point step or data do
not fit together is refused (None), never read past its data or allowed to raise.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

#: sensor_msgs/PointField.FLOAT32.
FLOAT32 = 7
#: Largest number of points a cloud may declare (width x height).
MAX_POINTS = 10_000_000


def read_float32(msg: Any, names: Sequence[str]) -> np.ndarray | None:
    """``(k, len(names))`` float64 of the float32 fields ``names`` of the cloud ``msg``; None
    when a field is missing, not float32 or not one value, lies (with its 4 bytes) beyond
    ``point_step``, or the point count, the step or the data's length do not fit together."""
    fields = {f.name: f for f in msg.fields}
    if any(n not in fields or fields[n].datatype != FLOAT32 or fields[n].count not in (0, 1)
           for n in names):
        return None
    step, count = int(msg.point_step), int(msg.width) * int(msg.height)
    offsets = [int(fields[n].offset) for n in names]
    if (step <= 0 or count < 0 or count > MAX_POINTS or min(offsets) < 0
            or max(offsets) + 4 > step or len(msg.data) < count * step):
        return None
    dtype = np.dtype({"names": list(names), "formats": ["<f4" if not msg.is_bigendian
                                                         else ">f4"] * len(names),
                      "offsets": offsets, "itemsize": step})
    arr = np.frombuffer(bytes(msg.data[:count * step]), dtype=dtype, count=count)
    return np.column_stack([arr[n].astype(float) for n in names]).reshape(count, len(names))
