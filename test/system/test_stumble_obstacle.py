"""Closed-loop stumble in the seabed simulator (lock-step: physics, the planner's contact
estimate from the simulated joint angles and torques, planner core, on simulated time): a
front foot that hits a block taller than its lifted swing is lifted higher and retried once,
and when it hits again the walk holds with the leg and the place."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco", reason="the seabed simulator needs the mujoco package")

from crawler_motion.model.config import load_config
from crawler_motion.motion.foothold import FootholdSettings
from crawler_motion.motion.gait import WalkParams
from crawler_motion.motion.stumble import StumbleSettings
from crawler_motion.testing.foothold_loop import FootholdLoop

#: A block 4.5 cm high (the swing clears 2 cm, a retry 3.5 cm), its near face 4 cm ahead of
#: the front feet.
BLOCK = """<mujoco model="block">
  <worldbody>
    <geom name="seabed" type="plane" size="5 5 0.1"/>
    <geom name="block" type="box" pos="0.16 0 0.0225" size="0.02 0.4 0.0225"/>
  </worldbody>
</mujoco>
"""


@pytest.mark.slow
def test_a_foot_that_hits_a_block_is_lifted_retried_and_then_holds_the_walk(
        tmp_path: Path) -> None:
    world = tmp_path / "block.xml"
    world.write_text(BLOCK)
    cfg = load_config()
    loop = FootholdLoop(cfg, str(world), FootholdSettings(enabled=True),
                        stumble=StumbleSettings())
    footholds = loop.core.walk.foothold
    retries: list[tuple[str, float]] = []
    stumbles = footholds._stumbles

    def watch(*args: object) -> object:
        track = stumbles(*args)  # type: ignore[arg-type]
        for i, leg in enumerate(cfg.robot.legs):
            if footholds.hits.retried[i] and (leg, footholds._base) not in retries:
                retries.append((leg, footholds._base))
        return track

    footholds._stumbles = watch  # type: ignore[method-assign]
    params = WalkParams.defaults(cfg.gait, gait="wave")
    rec = loop.walk(params, 2, limit=12.0)
    events = " ".join(rec.events)
    assert rec.state == "HOLDING", events
    assert retries and {leg for leg, _ in retries} <= {"lf", "rf"}  # front feet, retried
    leg = retries[-1][0].upper()  # the last retried swing hit again
    assert f"leg {leg} hit an obstacle again after lifting 15 mm higher, at x +0.1" in events
    assert "send stand (or sit) to recover" in events
    at_limit = np.max(rec.torque, axis=1) >= 0.95
    assert at_limit.sum() <= 3  # at most the ticks of the second hit, then held
    held = loop.data.ctrl.copy()
    for _ in range(50):  # nothing restarts by itself: the servo targets stay
        loop.tick()
        assert loop.core.state == "HOLDING"
        np.testing.assert_array_equal(loop.data.ctrl, held)


@pytest.mark.slow
def test_a_fast_diagonal_walk_on_flat_ground_has_no_hit(tmp_path: Path) -> None:
    """The lift-off's drag of a foot that read unloaded in its stance (a light robot in water)
    is no hit: a fast diagonal walk (stride 8 cm, 0.25 s swings) on a plane ends standing."""
    world = tmp_path / "flat.xml"
    world.write_text(BLOCK.replace('<geom name="block"', '<!-- no block').replace(
        '0.0225"/>\n', '0.0225" -->\n'))
    cfg = load_config()
    loop = FootholdLoop(cfg, str(world), FootholdSettings(enabled=True),
                        stumble=StumbleSettings())
    params = replace(WalkParams.defaults(cfg.gait, gait="diagonal"), stride=0.08,
                     swing_time=0.25)
    rec = loop.walk(params, 6, limit=30.0)
    assert rec.state == "STANDING" and not [e for e in rec.events if "hit" in e], rec.events
