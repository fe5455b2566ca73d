"""The ``pose`` command: parsing, the pose move per tick, refusals and resuming after a fault."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.model.kinematics import forward_kinematics
from crawler_motion.model.rotations import rpy_matrix
from crawler_motion.motion.body_pose import NEUTRAL, BodyPose, check_pose
from crawler_motion.motion.gait import standing_pose
from crawler_motion.planner.commands import COMMAND_KEYS, parse_gait_command
from crawler_motion.planner.core import PlannerCore
from crawler_motion.planner.driver_view import DriverReport
from crawler_motion.planner.moves import sitting_pose
from crawler_motion.planner.pose_move import PoseMove
from crawler_motion.planner.state import IDLE, MOVING, SITTING, STANDING, WALKING

CFG = load_config()
ROBOT = CFG.robot
DT = 0.01
STEP = float(ROBOT.velocity.max()) * DT  # one velocity-limited step [rad]
HEIGHT = ROBOT.body_height


def world_feet(q: np.ndarray, pose: dict[str, float]) -> np.ndarray:
    """Feet of joint angles ``q`` (12,) in the neutral frame of the body at ``pose``."""
    p = BodyPose(**pose).vector()
    return forward_kinematics(ROBOT, q.reshape(4, 3)) @ rpy_matrix(p[3:]).T + p[:3]


# ---------------------------------------------------------------- parsing

@pytest.mark.parametrize(("text", "pose"), [
    ('{"command": "pose"}', NEUTRAL),  # keys left out are 0
    ('{"command": "pose", "x": 0.01, "roll": 0.05}', BodyPose(x=0.01, roll=0.05)),
    ('{"command": "pose", "x": 0.03, "y": -0.03, "z": 0.04, "roll": -0.2, "pitch": 0.2, '
     '"yaw": 0.2}', BodyPose(0.03, -0.03, 0.04, -0.2, 0.2, 0.2)),  # every range's edge
    ('{"command": "pose", "yaw": -1}', None),
])
def test_a_pose_command_parses_into_its_pose(text, pose):
    if pose is None:
        with pytest.raises(CommandError, match=r"'yaw' = -1 rad is outside \[-0\.2, 0\.2\] rad"):
            parse_gait_command(text, CFG)
        return
    cmd = parse_gait_command(text, CFG)
    assert cmd.kind == "pose" and cmd.pose == pose


@pytest.mark.parametrize(("text", "match"), [
    ('{"command": "pose", "x": 0.0301}', r"'x' = 0\.0301 m is outside \[-0\.03, 0\.03\] m"),
    ('{"command": "pose", "z": -0.0401}', r"'z' = -0\.0401 m is outside \[-0\.04, 0\.04\] m"),
    ('{"command": "pose", "roll": 0.2001}', r"'roll' = 0\.2001 rad is outside"),
    ('{"command": "pose", "pitch": "0.1"}', r"'pitch' must be a number"),
    ('{"command": "pose", "pitch": true}', r"'pitch' must be a number"),
    ('{"command": "pose", "y": NaN}', r"NaN is not a number JSON allows"),
    ('{"command": "pose", "speed": 1}', r"'pose' does not take \['speed'\]; it accepts x, y, z, "
                                        r"roll, pitch, yaw"),
    ('{"command": "walk", "roll": 0.1}', r"'walk' does not take \['roll'\]"),
    ('{"command": "stand", "x": 0.01}', r"'stand' does not take \['x'\]"),
])
def test_bad_pose_commands_are_refused_with_the_field(text, match):
    with pytest.raises(CommandError, match=match):
        parse_gait_command(text, CFG)


def test_pose_is_a_command_of_the_gait_command_topic():
    assert COMMAND_KEYS["pose"] == ("x", "y", "z", "roll", "pitch", "yaw")
    assert "x" not in COMMAND_KEYS["walk"]


# ---------------------------------------------------------------- the planner

class Run:
    """A core at 100 Hz fed back its own targets as measurements (a perfect robot), standing."""

    def __init__(self, height: float | None = None) -> None:
        self.core = PlannerCore(CFG, 100.0)
        self.t = 0.0
        self.q = standing_pose(CFG).reshape(-1)
        self.targets: list[tuple[np.ndarray, dict[str, float]]] = []
        self.tick()
        stand = {"command": "stand"} if height is None else {"command": "stand",
                                                              "body_height": height}
        self.submit(stand)
        self.until(STANDING)
        self.targets.clear()

    def submit(self, command: dict) -> None:
        self.core.submit(json.dumps(command), self.t)

    def tick(self, follow: bool = True) -> np.ndarray | None:
        self.core.set_measured(self.q, self.t)
        target = self.core.tick(self.t)
        pos = None if target is None else np.array(target.positions)
        if pos is not None:
            self.targets.append((pos, self.core.status()["body_pose"]))
            if follow:
                self.q = pos
        self.t = round(self.t + DT, 9)
        return pos

    def until(self, state, limit: float = 20.0) -> None:
        end = self.t + limit
        while self.core.state != state:
            assert self.t < end, f"still {self.core.state}"
            self.tick()

    def pose(self, **fields: float) -> None:
        self.submit({"command": "pose", **fields})
        assert self.core.state == MOVING and self.core.status()["target"] == "pose"
        self.until(STANDING)


def assert_feet_fixed(run: Run, height: float = HEIGHT) -> None:
    """Every target since the last clear, with the body pose the status gave at its tick."""
    assert run.targets
    for q, pose in run.targets:
        np.testing.assert_allclose(world_feet(q, pose), ROBOT.standing_feet(height), atol=1e-9)


PROPERTY = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
SMALL = st.builds(BodyPose, *(st.floats(-edge, edge) for edge in (0.015, 0.015, 0.01, 0.1, 0.1,
                                                                  0.1)))


@PROPERTY
@given(SMALL, SMALL)
@example(NEUTRAL, BodyPose(0.0, -0.01171875, 0.0078125, 0.0625, 0.0625, 0.09375))  # LB too far
def test_every_tick_of_a_pose_move_keeps_every_foot_fixed(first, second):
    """Two pose moves in a row: FK of every published target, moved by the body pose in the
    status at that tick, is the standing feet within 1e-9 m; each ends at its pose exactly."""
    run = Run()
    for pose in (first, second):
        try:
            run.pose(**pose.as_dict())
        except CommandError as exc:  # small fields can still combine out of reach
            assert "pose refused" in str(exc) and "leg" in str(exc), exc
            assume(False)
        assert run.core.status()["body_pose"] == pose.as_dict()
        held = check_pose(CFG, HEIGHT, pose).reshape(-1)  # the held pose is the pose's IK
        np.testing.assert_allclose(run.q, held, atol=1e-12)
    assert_feet_fixed(run)


def test_the_ticks_follow_the_checked_move_and_respect_the_joint_rates():
    run = Run()
    t0 = run.t
    run.submit({"command": "pose", "x": 0.02, "pitch": -0.1, "yaw": 0.15})
    move = run.core.moves.move
    assert isinstance(move, PoseMove) and run.core.status()["body_pose"] == NEUTRAL.as_dict()
    run.until(STANDING)
    positions = np.array([q for q, _ in run.targets])
    expected = move.path.joints(np.arange(len(positions)) * DT + (t0 - move.t0))[0]
    np.testing.assert_allclose(positions[:-1], expected[:-1].reshape(-1, 12), atol=1e-12)
    assert np.abs(np.diff(positions, axis=0)).max() <= 0.5 * STEP + 1e-12
    assert len(positions) == pytest.approx(move.duration / DT, abs=2)
    assert any(event == ("info", "pose done: STANDING") for event in run.core.pop_events())


def test_stand_returns_a_posed_body_to_neutral_with_the_feet_fixed():
    run = Run()
    run.pose(y=0.02, roll=-0.1)
    run.targets.clear()
    run.submit({"command": "stand"})
    assert run.core.status()["target"] == "stand"
    run.until(STANDING)
    assert_feet_fixed(run)
    assert run.core.status()["body_pose"] == NEUTRAL.as_dict()
    np.testing.assert_allclose(run.q, standing_pose(CFG).reshape(-1), atol=1e-12)


def test_stand_at_a_new_height_from_a_posed_body_keeps_the_feet_fixed():
    run = Run()
    run.pose(x=0.01, z=0.01, pitch=0.1)
    run.targets.clear()
    run.submit({"command": "stand", "body_height": 0.06})
    assert run.core.status()["body_pose"]["z"] == pytest.approx(0.01 + 0.07 - 0.06)
    run.until(STANDING)
    assert_feet_fixed(run, 0.06)  # the poses are relative to the new standing height
    assert run.core.status()["body_height"] == 0.06
    np.testing.assert_allclose(run.q, standing_pose(CFG, 0.06).reshape(-1), atol=1e-12)


def test_a_pose_is_relative_to_the_standing_height():
    run = Run(height=0.09)
    with pytest.raises(CommandError, match=r"z = 0\.001 m puts the body at 0\.091 m, outside "
                                           r"body_height_range"):
        run.submit({"command": "pose", "z": 0.001})
    run.pose(z=-0.04)
    np.testing.assert_allclose(run.q, standing_pose(CFG, 0.05).reshape(-1), atol=1e-9)


def test_a_pose_out_of_reach_is_refused_with_the_leg_and_nothing_moves():
    run = Run()
    run.pose(x=0.01)
    before = run.core.revision
    with pytest.raises(CommandError, match=r"^pose refused: a foot would leave its workspace: "
                                           r"leg rb: foot target"):
        run.submit({"command": "pose", "y": 0.03, "z": 0.02})
    status = run.core.status()
    assert status["state"] == STANDING and status["body_pose"] == BodyPose(x=0.01).as_dict()
    assert status["refusals"] == 1 and run.core.revision > before


@pytest.mark.parametrize(("command", "match"), [
    ({"command": "walk", "steps": 1}, r"^walk refused: the body is posed \(roll 0\.1 rad\); "
                                      r"walks start from the neutral pose: send stand first"),
    ("twist", r"^cmd_vel ignored: the body is posed \(roll 0\.1 rad\)"),
])
def test_a_walk_from_a_posed_body_is_refused_until_stand(command, match):
    run = Run()
    run.pose(roll=0.1)
    with pytest.raises(CommandError, match=match):
        if command == "twist":
            run.core.on_twist(0.02, 0.0, 0.0, run.t)
        else:
            run.submit(command)
    run.core.on_twist(0.0, 0.0, 0.0, run.t)  # a zero twist changes nothing
    assert run.core.state == STANDING
    run.submit({"command": "stand"})
    run.until(STANDING)
    run.submit({"command": "walk", "steps": 1})
    assert run.core.state == WALKING


def test_a_pose_while_walking_or_moving_is_refused_with_the_reason():
    run = Run()
    run.submit({"command": "walk", "steps": 1})
    with pytest.raises(CommandError, match=r"^pose refused while WALKING: send stop"):
        run.submit({"command": "pose", "x": 0.01})
    assert run.core.state == WALKING
    run.until(STANDING)
    run.submit({"command": "pose", "x": 0.01})
    with pytest.raises(CommandError, match=r"^pose refused: a pose move is in progress"):
        run.submit({"command": "pose", "x": 0.02})


@pytest.mark.parametrize("state", [IDLE, SITTING])
def test_a_pose_needs_standing(state):
    core = PlannerCore(CFG, 100.0)
    core.set_measured(sitting_pose(CFG), 0.0)
    t = 0.0
    if state == SITTING:
        core.submit('{"command": "sit"}', t)
        while core.state != SITTING:
            t += DT
            core.set_measured(sitting_pose(CFG), t)
            core.tick(t)
    with pytest.raises(CommandError, match=rf"^pose refused in state {state}: the body pose is "
                                           rf"set while STANDING; send stand first"):
        core.submit('{"command": "pose", "x": 0.01}', t)


def test_sit_from_a_posed_body_ends_neutral():
    run = Run()
    run.pose(pitch=0.1)
    run.submit({"command": "sit"})
    run.until(SITTING)
    assert run.core.status()["body_pose"] == NEUTRAL.as_dict()


@pytest.mark.parametrize("fault", ["pause", "re-enable"])
def test_a_pose_move_interrupted_by_a_fault_resumes_to_where_it_was_not_beyond(fault):
    run = Run()
    run.core.on_driver(DriverReport("enabled", 1), run.t)
    run.submit({"command": "pose", "x": 0.02, "roll": 0.1})
    for _ in range(20):
        run.tick()
    held, pose_then = run.targets[-1]
    assert 0 < pose_then["x"] < 0.02
    if fault == "pause":
        run.core.set_paused(True, run.t, "axis fault")
        assert run.core.state == STANDING and run.core.status()["resuming"]
        for _ in range(30):  # held while paused; the joints sag
            assert np.array_equal(run.tick(follow=False), held)
        with pytest.raises(CommandError, match="paused"):
            run.submit({"command": "pose", "x": 0.02, "roll": 0.1})
        run.core.set_paused(False, run.t)
    else:  # between two ticks
        run.core.on_driver(DriverReport("enabled", 2), run.t - DT / 2)
        assert run.core.state == STANDING and run.core.status()["resuming"]
    with pytest.raises(CommandError, match="pose refused: resuming from the measured pose"):
        run.submit({"command": "pose", "x": 0.02, "roll": 0.1})
    run.q = run.q - 0.03  # where the joints are now
    first = run.tick()
    assert first is not None and np.abs(first - (run.q)).max() <= STEP
    assert run.core.status()["target"].startswith("resume after")
    run.until(STANDING)
    for _ in range(50):
        run.tick()
    np.testing.assert_allclose(run.q, held, atol=1e-12)  # where it was: not the pose's end
    status = run.core.status()
    assert status["body_pose"] == pose_then and not status["resuming"]
    np.testing.assert_allclose(world_feet(run.q, pose_then), ROBOT.standing_feet(), atol=1e-9)


def test_stand_during_a_due_resume_is_the_joint_move_from_the_measured_pose():
    run = Run()
    run.pose(y=0.01)
    run.core.set_paused(True, run.t, "axis fault")
    run.tick(follow=False)
    run.core.set_paused(False, run.t)
    run.q = run.q + 0.02
    run.submit({"command": "stand"})
    assert run.core.status()["target"] == "stand" and not run.core.status()["resuming"]
    first = run.tick()
    assert first is not None and np.abs(first - run.q).max() <= STEP  # from the measured pose
    run.until(STANDING)
    np.testing.assert_allclose(run.q, standing_pose(CFG).reshape(-1), atol=1e-12)


def test_a_refused_stand_keeps_an_interrupted_move_resumable():
    """A stand refused while paused leaves the resume of the interrupted stand move due."""
    core = PlannerCore(CFG, 100.0)
    core.set_measured(sitting_pose(CFG), 0.0)
    core.submit('{"command": "stand"}', 0.0)
    core.tick(0.01)
    core.set_paused(True, 0.02, "axis fault")
    with pytest.raises(CommandError, match="paused"):
        core.submit('{"command": "stand"}', 0.03)
    assert core.state == MOVING and core.status()["resuming"]
    core.set_paused(False, 0.04)
    core.set_measured(sitting_pose(CFG), 0.05)
    target = core.tick(0.05)
    assert target is not None and core.status()["target"] == "stand"
