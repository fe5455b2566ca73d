"""Closed-loop walk of the swaying diagonal gait over the shipped 2 cm relief in the seabed
simulator (lock-step, as `crawler-motion rough`), with the terrain-adaptive touch-down in each
attitude mode."""

from __future__ import annotations

import math

import pytest

from crawler_motion.model.config import load_config
from crawler_motion.motion.attitude import AttitudeMode, AttitudeSettings
from crawler_motion.motion.foothold import FootholdSettings
from crawler_motion.motion.gait import WalkParams
from crawler_motion.testing.foothold_loop import FootholdLoop


@pytest.mark.slow
@pytest.mark.parametrize("mode", list(AttitudeMode))
def test_the_swaying_diagonal_crosses_the_2cm_relief_without_tipping(mode: AttitudeMode) -> None:
    # Before its own 0.4 s swing (the 0.6 s of the other gaits): pitch 9.2° with the attitude
    # off, 7.4° imu, 8.9° stance_plane, advance 0.92-0.94 (the body tipping about its support
    # line over the long swing, the touch-down holding the tip as terrain).
    cfg = load_config()
    loop = FootholdLoop(cfg, "relief_2cm", FootholdSettings(enabled=True),
                        attitude=AttitudeSettings(mode=mode))
    rec = loop.walk(WalkParams.defaults(cfg.gait, gait="diagonal_sway"), 3)
    print(f"\n{mode.value}: {rec.summary()}, max roll {math.degrees(rec.max_roll):.1f} deg")
    assert rec.state == "STANDING", rec.events
    assert rec.advance_ratio >= 0.95
    assert max(rec.max_roll, rec.max_pitch) <= math.radians(5.0)
