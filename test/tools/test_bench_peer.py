"""The bench's peer (`tools.bench_peer`): loading a clone, its refusals, the verdicts."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from crawler_motion.tools.bench_peer import PeerError, load_peer, target_lines

#: A stand-in for the peer's clone: the modules and names the bench uses, nothing more.
FAKE = {
    "src/__init__.py": "",
    "pupper/__init__.py": "",
    "src/State.py": (
        "from enum import Enum\n"
        "class BehaviorState(Enum):\n    REST = 0\n    TROT = 1\n"
        "class State:\n    def __init__(self):\n"
        "        self.behavior_state = BehaviorState.REST\n        self.ticks = 0\n"),
    "src/Command.py": (
        "class Command:\n    def __init__(self):\n        self.trot_event = False\n"
        "        self.horizontal_velocity = None\n"),
    "src/Controller.py": (
        "from src.State import BehaviorState\n"
        "class Controller:\n    def __init__(self, config, ik):\n        self.ik = ik\n"
        "    def run(self, state, command):\n"
        "        if command.trot_event:\n            state.behavior_state = {TROT}\n"
        "        state.ticks += 1\n"),
    "pupper/Config.py": "class Configuration:\n    pass\n",
    "pupper/Kinematics.py": "def four_legs_inverse_kinematics(feet, config):\n    return feet\n",
}


def fake_clone(root: Path, trots: bool = True, drop: str = "") -> Path:
    for name, text in FAKE.items():
        if name == drop:
            continue
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text.replace("{TROT}", "BehaviorState.TROT" if trots
                                     else "BehaviorState.REST"))
    return root


def test_a_clone_gives_one_trotting_call_and_leaves_no_module_behind(tmp_path):
    path_before = list(sys.path)
    run = load_peer(str(fake_clone(tmp_path)))
    assert not [m for m in sys.modules if m.split(".")[0] in ("src", "pupper")]
    assert sys.path == path_before
    run()
    run()  # the controller and its state live on in the call


@pytest.mark.parametrize(("drop", "trots", "message"), [
    ("src/Controller.py", True, "is not a clone of StanfordQuadruped"),
    ("pupper/Kinematics.py", True, "cannot import the peer"),
    ("", False, "did not start trotting"),
])
def test_a_clone_that_cannot_be_timed_is_refused_with_the_reason(tmp_path, drop, trots,
                                                                 message):
    with pytest.raises(PeerError, match=message):
        load_peer(str(fake_clone(tmp_path, trots, drop)))
    assert not [m for m in sys.modules if m.split(".")[0] in ("src", "pupper")]


def test_a_missing_dependency_is_named(tmp_path, monkeypatch):
    root = fake_clone(tmp_path)
    (root / "pupper/Kinematics.py").write_text("import transforms3d_missing_here\n")
    with pytest.raises(PeerError, match="pip install transforms3d"):
        load_peer(str(root))


@pytest.mark.parametrize(("tick", "cal", "peer", "beside", "verdicts"), [
    (10.0, 15.0, 120.0, None, ["met", "met", "met"]),  # every boundary exactly
    (10.1, 15.2, 120.0, None, ["NOT met", "NOT met", "NOT met"]),
    (13.0, 19.5, 130.0, 10.8, ["NOT met", "met", "met"]),  # the ratio from the pair
    (13.0, None, None, None, ["NOT met", "not measured"]),
])
def test_target_lines_give_each_verdict_at_its_boundary(tick, cal, peer, beside, verdicts):
    lines = target_lines(tick, 90.0, cal, peer, "no clone", beside)
    assert len(lines) == len(verdicts)
    for line, verdict in zip(lines, verdicts, strict=True):
        if verdict == "not measured":
            assert "not measured (no clone)" in line
        else:
            assert line.endswith(f"-> {verdict}"), line
