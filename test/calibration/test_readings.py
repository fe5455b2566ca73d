"""The session measurement file: round trip, columns in any order, blank lines, the limits'
boundary rows. (Refusals, one per reason, are in test/tools/test_calibrate_cli.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.calibration.readings import (
    Readings,
    format_readings,
    parse_readings,
)
from crawler_motion.errors import CalibrationError
from crawler_motion.model.config import load_config

ROBOT = load_config().robot


def test_round_trip_keeps_every_row_and_numbers_lines() -> None:
    rng = np.random.default_rng(0)
    rows = Readings(np.array([0, 3, 1]), rng.uniform(ROBOT.lower, ROBOT.upper, (3, 3)),
                    rng.normal(size=(3, 3)), np.array([2, 3, 4]))
    back = parse_readings(format_readings(ROBOT, rows), ROBOT, "m.csv")
    for field in ("legs", "q", "points", "lines"):
        np.testing.assert_allclose(getattr(back, field), getattr(rows, field), rtol=1e-11)
    assert back.measured_legs() == (0, 1, 3)


def test_columns_in_any_order_and_blank_lines() -> None:
    text = "x,y,z,leg,q_knee,q_shoulder,q_root\n\n0.1,0.2,0.3,rb,1.0,0.5,-0.2\n"
    back = parse_readings(text, ROBOT, "m.csv")
    assert back.legs.tolist() == [2] and back.lines.tolist() == [3]
    np.testing.assert_array_equal(back.q, [[-0.2, 0.5, 1.0]])
    np.testing.assert_array_equal(back.points, [[0.1, 0.2, 0.3]])


@pytest.mark.parametrize(("joint", "side", "ok"), [
    (2, "upper", True), (2, "above", False), (0, "lower", True), (0, "below", False)])
def test_joint_limit_boundary_rows(joint: int, side: str, ok: bool) -> None:
    q = 0.5 * (ROBOT.lower + ROBOT.upper)
    limit = ROBOT.upper[joint] if side in ("upper", "above") else ROBOT.lower[joint]
    q[joint] = limit + {"upper": 0.0, "lower": 0.0, "above": 1e-9, "below": -1e-9}[side]
    text = "leg,q_root,q_shoulder,q_knee,x,y,z\nlf," + ",".join(repr(float(v)) for v in q)
    text += ",0,0,0\n"
    if ok:
        assert parse_readings(text, ROBOT, "m.csv").q.shape == (1, 3)
    else:
        with pytest.raises(CalibrationError, match="line 2: pose outside the joint limits"):
            parse_readings(text, ROBOT, "m.csv")
