"""The tick's peer and targets: StanfordQuadruped's ``Controller.run`` timed in this process.

The issue's measure of the tick is relative: the planner's tick of the default walk against
StanfordQuadruped's ``Controller.run`` (trot: gait, swing, stance and the IK of four legs), in
one process, so that the machine's speed cancels. None of the peer's code is in this package:
``crawler-motion bench --peer DIR`` imports it from a clone the user names
(``git clone https://github.com/stanfordroboticsclub/StanfordQuadruped DIR``; it needs
``transforms3d`` from PyPI). Without ``--peer`` the bench says how to add the row.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: Median planner tick of the default walk the project aims at [us], the least ratio of the
#: peer's median to it, and the most a tick with calibrated legs may take against it.
TICK_TARGET_US = 10.0
PEER_RATIO = 12.0
CALIBRATED_RATIO = 1.5
#: Forward speed the peer trots at [m/s] (the default walk's speed).
PEER_SPEED = 0.1
#: The peer's top-level packages (imported from its clone, removed again afterwards).
PEER_PACKAGES = ("src", "pupper")


class PeerError(Exception):
    """The peer cannot be timed (no clone at the path, a missing dependency)."""


def load_peer(path: str) -> Callable[[], object]:
    """One ``Controller.run`` of the peer trotting at `PEER_SPEED`, as a call; `PeerError`
    naming what is missing when the clone at ``path`` cannot be imported."""
    root = Path(path).expanduser().resolve()
    if not (root / "src" / "Controller.py").is_file():
        raise PeerError(f"{root} is not a clone of StanfordQuadruped (no src/Controller.py); "
                        f"git clone https://github.com/stanfordroboticsclub/StanfordQuadruped")
    clashing = [name for name in PEER_PACKAGES if name in sys.modules]
    if clashing:
        raise PeerError(f"modules named {clashing} are imported already; the peer's packages "
                        f"have the same names")
    sys.path.insert(0, str(root))
    try:
        modules = {name: importlib.import_module(name) for name in (
            "src.Controller", "src.State", "src.Command", "pupper.Config", "pupper.Kinematics")}
    except ImportError as exc:
        raise PeerError(f"cannot import the peer from {root}: {exc} (it needs numpy and "
                        f"transforms3d: pip install transforms3d)") from exc
    finally:
        sys.path.remove(str(root))
        for name in [m for m in sys.modules if m.split(".")[0] in PEER_PACKAGES]:
            del sys.modules[name]  # the objects made below keep what they need
    return _trotting(modules)


def _trotting(modules: dict[str, Any]) -> Callable[[], object]:
    import numpy as np

    config = modules["pupper.Config"].Configuration()
    controller = modules["src.Controller"].Controller(
        config, modules["pupper.Kinematics"].four_legs_inverse_kinematics)
    state = modules["src.State"].State()
    state.quat_orientation = np.array([1.0, 0.0, 0.0, 0.0])
    command = modules["src.Command"].Command()
    command.trot_event = True
    controller.run(state, command)  # REST -> TROT
    command.trot_event = False
    command.horizontal_velocity = np.array([PEER_SPEED, 0.0])
    if state.behavior_state != modules["src.State"].BehaviorState.TROT:
        raise PeerError(f"the peer did not start trotting (state {state.behavior_state})")
    return lambda: controller.run(state, command)


def target_lines(tick: float, tick_p99: float | None, calibrated: float | None,
                 peer: float | None, peer_problem: str, beside: float | None = None
                 ) -> list[str]:
    """The verdicts against the targets, from the medians [us] of the planner tick, of the
    tick with calibrated legs, of the peer (None: not measured, ``peer_problem`` says why)
    and of the tick measured beside it (``beside``; the ratio's denominator, else ``tick``)."""
    p99 = "-" if tick_p99 is None else f"{tick_p99:.1f}"
    lines = [f"- planner tick: {tick:.1f} us (p99 {p99} us) -> "
             + ("met" if tick <= TICK_TARGET_US else "NOT met")]
    if calibrated is not None:
        ratio = calibrated / tick
        lines.append(f"- calibrated legs: {calibrated:.1f} us = {ratio:.2f}x nominal -> "
                     + ("met" if ratio <= CALIBRATED_RATIO else "NOT met"))
    if peer is None:
        lines.append(f"- peer (StanfordQuadruped `Controller.run`, trot): not measured "
                     f"({peer_problem})")
    else:
        ours = tick if beside is None else beside
        ratio = peer / ours
        lines.append(f"- peer (StanfordQuadruped `Controller.run`, trot) {peer:.1f} us beside "
                     f"the tick's {ours:.1f} us: the tick is {ratio:.1f}x faster (target >= "
                     f"{PEER_RATIO:g}x) -> " + ("met" if ratio >= PEER_RATIO else "NOT met"))
    return lines
