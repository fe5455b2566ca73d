"""Property-based fuzzing of the whole input chain, pure Python on in-process ``virtual`` buses.

Inputs: gait-command text and twists into a standing, ticking `PlannerCore`; joint commands into
an activated `DriverCore`; and the planner's targets forwarded tick by tick into the driver.
Invariants:

- planner: `submit` / `on_twist` raise nothing but `CommandError`; `tick` never raises, returns
  None only in IDLE / ESTOP, and every `JointTarget` is finite with its positions within the
  joint limits;
- driver: `submit` never raises (a refusal is a `CommandResult`), accepts exactly the valid
  commands while motion is allowed, and target frames appear on the bus only for an accepted
  command, decoding to the commanded angles;
- bus: every frame decodes with `MotorProtocol`, and no target frame, decoded raw through the
  DBC and the axis map, carries a NaN or an angle outside the joint limits;
- chain: every target the planner publishes is accepted and sent by the driver.

``FUZZ_EXAMPLES`` sets the examples per test (``make fuzz`` runs 10 000); the module prints how
many examples and inputs it fuzzed.
"""

from __future__ import annotations

import array
import copy
import json
import math
import os
import re
import uuid
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from functools import cache
from typing import Any

import can
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crawler_motion.canbus.protocol import MotorProtocol, TargetFrame
from crawler_motion.driver.control import CommandResult
from crawler_motion.driver.core import DriverCore
from crawler_motion.driver.settings import DriverSettings
from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.motion.gait import standing_pose
from crawler_motion.planner.commands import COMMAND_KEYS, MAX_STEPS, field_ranges
from crawler_motion.planner.core import JointTarget, PlannerCore
from crawler_motion.planner.state import ESTOP, IDLE, STANDING, STOPPING, WALKING

CFG = load_config()
ROBOT = CFG.robot
JOINTS: tuple[str, ...] = ROBOT.joint_names
LO = ROBOT.lower_limits().reshape(-1)
HI = ROBOT.upper_limits().reshape(-1)
LIMITS = dict(zip(JOINTS, zip(LO.tolist(), HI.tolist(), strict=True), strict=True))
STAND = standing_pose(CFG).reshape(-1)
PROTO = MotorProtocol.from_config(ROBOT)
#: Half a step of the DBC's position grid [rad]: a decoded target is this close to the command.
HALF_STEP = 0.5 * PROTO.resolution_rad * (1 + 1e-6)
#: Float rounding allowed beyond a limit [rad]: the shipped limits lie on the DBC grid, so
#: rounding a command onto the grid never leaves them (1.4 decodes as 1.4000000000000001).
LIMIT_TOL = 1e-9
AXES = {m.axis: m for m in PROTO.axis_map}
TARGET_SIGNAL = re.compile(r"Axis(\d+)_Target")

#: Examples per test; FUZZ_EXAMPLES=10000 for a long run.
EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "25"))
FUZZ = settings(max_examples=EXAMPLES, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
#: Examples run and inputs fed (commands, twists, joint commands, forwarded targets).
RUNS: Counter[str] = Counter()


@pytest.fixture(scope="module", autouse=True)
def _report() -> Iterator[None]:
    yield
    print(f"\nfuzzed {RUNS['inputs']} inputs in {RUNS['examples']} examples "
          f"({RUNS['ticks']} planner ticks, {RUNS['walking']} of them walking; "
          f"{RUNS['accepted']} joint commands sent; {RUNS['frames']} CAN frames decoded)")


# ------------------------------------------------------------------ strategies: gait commands
RANGES = field_ranges(CFG)
#: Integers up to beyond the float range (10**400 has no float: refused, not an OverflowError).
JUNK = (st.none() | st.booleans() | st.text(max_size=6) | st.integers(-10**400, 10**400)
        | st.floats() | st.lists(st.integers(-2, 2), max_size=3)
        | st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))


def _number(key: str) -> st.SearchStrategy[Any]:
    """In-range values of a numeric field (accepted alone), its ends, anything numeric, junk."""
    lo, hi, _ = RANGES[key]
    return (st.floats(lo, hi) | st.sampled_from([lo, hi]) | st.floats()
            | st.integers(-10**400, 10**400) | JUNK)


KINDS = sorted(COMMAND_KEYS)
VALUES: dict[str, st.SearchStrategy[Any]] = {
    "steps": st.integers(1, 3) | st.integers(-5, MAX_STEPS + 5) | JUNK,
    "gait": st.sampled_from(sorted(CFG.gait.gaits)) | JUNK,
    "profile": st.sampled_from(sorted(CFG.gait.profiles)) | JUNK,
    **{key: _number(key) for key in RANGES},
}
PAIRS = st.one_of(*(st.tuples(st.just(k), v) for k, v in VALUES.items()),
                  st.tuples(st.just("command"), st.sampled_from(KINDS) | JUNK),
                  st.tuples(st.text(max_size=8), JUNK))
VALID_PAIRS = st.one_of(*(st.tuples(st.just(k), st.floats(lo, hi))
                          for k, (lo, hi, _) in RANGES.items() if k in COMMAND_KEYS["walk"]),
                        st.tuples(st.just("steps"), st.integers(1, 3)),
                        st.tuples(st.just("gait"), st.sampled_from(sorted(CFG.gait.gaits))))
JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                max_size=3),
    max_leaves=8)
#: The keys of a pose in range (many poses still leave a foot's workspace: refused).
POSE_PAIRS = st.one_of(*(st.tuples(st.just(k), st.floats(*RANGES[k][:2]))
                         for k in COMMAND_KEYS["pose"]))
NASTY = [
    "", " ", "{", "}", "[]", "null", "NaN", '"walk"', "{}", '{"command": null}',
    '{"command": "walk", "stride": NaN}', '{"command": "walk", "stride": Infinity}',
    '{"command": "walk", "stride": 1e999}', '{"command": "walk", "steps": 1e3}',
    '{"command": "walk", "command": "walk"}', '{"command": "stand"} {"command": "walk"}',
    '{"command": "walk\\u0000"}', '\ufeff{"command": "stop"}', '{"command": "\ud800"}',
    '{"command": "walk", "x": "' + "a" * 5000 + '"}', "[" * 4000, '{"a":' * 800,
    '{"command": "walk", "steps": ' + "9" * 5000 + "}",
]


def _dump(pairs: Sequence[tuple[str, Any]]) -> str:
    """A JSON object of ``pairs`` in order (duplicates kept; NaN / Infinity as Python writes)."""
    return "{" + ", ".join(f"{json.dumps(k)}: {json.dumps(v, allow_nan=True)}"
                           for k, v in pairs) + "}"


@st.composite
def command_texts(draw: st.DrawFn) -> Any:
    """One ``gait_command`` input: mostly JSON text, sometimes a non-text object."""
    branch = draw(st.integers(0, 11))
    if branch <= 5:  # a plausible command: a known kind and in-range walk fields
        kind = draw(st.sampled_from(["walk", "walk", "walk", "stop", "stand", "sit", "estop",
                                     "reset", "pose"]))
        pairs = draw(st.lists(VALID_PAIRS, max_size=4, unique_by=lambda p: p[0]))
        if kind == "stand":
            lo, hi, _ = RANGES["body_height"]
            pairs = draw(st.lists(st.tuples(st.just("body_height"), st.floats(lo, hi)),
                                  max_size=1))
        elif kind == "pose":
            pairs = draw(st.lists(POSE_PAIRS, max_size=3, unique_by=lambda p: p[0]))
        elif kind != "walk":
            pairs = []
        return _dump([("command", kind), *pairs])
    if branch <= 8:  # any keys, values of any type and range
        pairs = draw(st.lists(PAIRS, max_size=6, unique_by=lambda p: p[0]))
        if draw(st.booleans()):
            pairs.insert(0, ("command", draw(st.sampled_from(KINDS))))
        if pairs and draw(st.integers(0, 7)) == 0:  # a key twice
            pairs.append(pairs[draw(st.integers(0, len(pairs) - 1))])
        text = _dump(pairs)
        if draw(st.integers(0, 3)) == 0:  # cut short
            return text[:draw(st.integers(0, len(text)))]
        return text
    if branch == 9:
        return json.dumps(draw(JSON_VALUES), allow_nan=True)
    if branch == 10:
        return draw(st.text(max_size=40) | st.sampled_from(NASTY))
    return draw(st.sampled_from([None, b'{"command": "stop"}', 7, ["walk"],
                                 {"command": "walk"}]))


# ------------------------------------------------------------------ strategies: time and twists
DT = st.sampled_from([0.0, 0.001, 0.01, 0.01, 0.02, 0.05, 0.1, 0.25]) | st.floats(0.0, 0.3)
#: ("tick", n, dt [s]): n ticks dt apart, each optionally followed by planning ahead.
TICKS = st.tuples(st.just("tick"), st.integers(1, 20), DT, st.booleans())
#: Fewer ticks for the chain, where each tick costs a joint command and four frames.
FEW_TICKS = st.tuples(st.just("tick"), st.integers(1, 8), DT, st.booleans())
#: One late tick (a stalled timer), up to a few seconds.
JUMP = st.tuples(st.just("tick"), st.just(1), st.floats(0.3, 4.0), st.booleans())
#: ("measure", offset [rad]): a new measurement, the last target moved by ``offset``.
MEASURE = st.tuples(st.just("measure"), st.floats(-0.05, 0.05))
PAUSE = st.tuples(st.just("pause"), st.booleans())
COMMAND = st.tuples(st.just("command"), command_texts())
SPEED = st.floats(-0.2, 0.2)  # around the twist limits (0.13 m/s, 0.29 rad/s by default)
TWIST_VALUE = (SPEED | SPEED | st.floats() | st.integers(-3, 3)
               | st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 1e-5, 1e308, math.nan, math.inf,
                                  -math.inf, True]))
TWIST = (st.tuples(st.just("twist"), SPEED, SPEED, SPEED)
         | st.tuples(st.just("twist"), TWIST_VALUE, TWIST_VALUE, TWIST_VALUE))


# ------------------------------------------------------------------ planner under test
@cache
def _template() -> tuple[PlannerCore, float]:
    """A planner standing at the default height, and its clock [s]."""
    core = PlannerCore(CFG, 100.0)
    now = 10.0
    core.set_measured(STAND, now)
    core.submit('{"command": "stand"}', now)
    while core.state != STANDING:
        now = round(now + 0.01, 9)
        core.tick(now)
    return core, now


def check_target(core: PlannerCore, target: JointTarget | None) -> None:
    """The planner's output invariants (see the module docstring)."""
    # nothing in IDLE and ESTOP, nor while a resume waits for a measurement taken after the
    # interruption (a late tick, see planner.resume)
    waiting = bool(core.resumer.pending) and not core.paused
    assert (target is None) == (core.state in (IDLE, ESTOP) or waiting), (core.state, target)
    if target is None:
        return
    q, qd = np.asarray(target.positions), np.asarray(target.velocities)
    assert q.shape == qd.shape == (len(JOINTS),), (q.shape, qd.shape)
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(qd)), (core.state, q, qd)
    outside = [f"{JOINTS[i]}={q[i]!r}" for i in np.flatnonzero((q < LO) | (q > HI))]
    assert not outside, f"target outside the joint limits in {core.state}: {outside}"


class PlannerRun:
    """A copy of the standing planner, driven by fuzz actions; ``on_target`` sees each target."""

    def __init__(self, on_target: Callable[[JointTarget, float], None] | None = None) -> None:
        template, self.now = _template()
        self.core = copy.deepcopy(template)
        self.last = STAND
        self.on_target = on_target

    def run(self, actions: Sequence[tuple[Any, ...]], playout: int = 10) -> None:
        """Do ``actions``, then ``playout`` ticks 0.25 s apart to let the last one play out."""
        RUNS["examples"] += 1
        for action in actions:
            getattr(self, action[0])(*action[1:])
        self.tick(playout, 0.25, False)
        assert isinstance(self.core.status(), dict)
        self.core.pop_events()

    def tick(self, n: int, dt: float, ahead: bool) -> None:
        for _ in range(n):
            self.now += dt
            target = self.core.tick(self.now)
            RUNS["ticks"] += 1
            RUNS["walking"] += self.core.state in (WALKING, STOPPING)
            check_target(self.core, target)
            if target is not None:
                self.last = np.asarray(target.positions)
                if self.on_target is not None:
                    self.on_target(target, self.now)
            if ahead:  # as the node's ticker does between ticks
                self.core.plan_ahead(self.now)

    def command(self, text: Any) -> None:
        RUNS["inputs"] += 1
        try:
            self.core.submit(text, self.now)
        except CommandError:
            pass

    def twist(self, vx: Any, vy: Any, wz: Any) -> None:
        RUNS["inputs"] += 1
        try:
            self.core.on_twist(vx, vy, wz, self.now)
        except CommandError:
            pass

    def measure(self, offset: float) -> None:
        self.core.set_measured(self.last + offset, self.now)

    def pause(self, paused: bool) -> None:
        self.core.set_paused(paused, self.now, "fuzz")


@FUZZ
@given(st.lists(COMMAND | COMMAND | TICKS | TICKS | JUMP | MEASURE | PAUSE, max_size=12))
def test_fuzz_gait_commands_into_the_planner(actions):
    PlannerRun().run(actions)


@FUZZ
@given(st.lists(TWIST | TWIST | TICKS | TICKS | JUMP | COMMAND | MEASURE, max_size=10))
def test_fuzz_twists_into_the_planner(actions):
    PlannerRun().run(actions)


@pytest.mark.parametrize("call", ["gait command", "twist"])
def test_integer_beyond_the_float_range_is_a_command_error(call):
    run = PlannerRun()
    huge = 10**400
    with pytest.raises(CommandError):
        if call == "twist":
            run.core.on_twist(huge, 0.0, 0.0, run.now)
        else:
            run.core.submit(f'{{"command": "walk", "stride": {huge}}}', run.now)


# ------------------------------------------------------------------ driver under test
class _Quiet:
    """A logger that drops everything (an e-stop per example would flood the captured log)."""

    def info(self, message: str) -> None:
        pass

    warning = error = info


class BusRig:
    """An activated `DriverCore` and a listener on a fresh ``virtual`` channel.

    ``now`` is the driver's steady clock [s]. `drain` decodes every frame the listener heard.
    """

    def __init__(self, command_timeout: float = 0.2) -> None:
        channel = f"fuzz-{uuid.uuid4().hex}"
        self.bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        self.listener = can.Bus(interface="virtual", channel=channel,
                                receive_own_messages=False)
        self.now = 1000.0
        self.settings = DriverSettings(command_timeout=command_timeout, step_speed_limit=5.0,
                                       step_margin=0.5)
        self.core = DriverCore(PROTO, self.bus, clock=lambda: self.now, logger=_Quiet(),
                               settings=self.settings)
        self.core.open()
        self._feedback_counter = 0
        self.measure(STAND)
        ok, why = self.core.activate()
        assert ok, why
        assert self.drain() == []

    def close(self) -> None:
        self.core.close()
        self.bus.shutdown()
        self.listener.shutdown()

    def __enter__(self) -> BusRig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def measure(self, q: np.ndarray) -> None:
        """The manager reports the joints at ``q`` [rad, joint order] (a perfect robot)."""
        self._feedback_counter += 1
        for msg in PROTO.encode_feedback(PROTO.to_axis(np.asarray(q)), self._feedback_counter):
            self.listener.send(msg)
        self.core.poll(0.05)
        self.measured = np.asarray(q, dtype=float)

    def drain(self) -> list[TargetFrame]:
        """Decode every frame on the bus since the last call; the target frames among them."""
        targets = []
        while (msg := self.listener.recv(0.0)) is not None:
            RUNS["frames"] += 1
            frame = PROTO.decode(msg)  # a ProtocolError: the driver sent a bad frame
            if isinstance(frame, TargetFrame):
                check_raw_target(msg)
                targets.append(frame)
        return targets


def check_raw_target(msg: can.Message) -> None:
    """A target frame decoded by the DBC alone, mapped axis -> joint: finite, within limits."""
    values = PROTO.database.decode_message(msg.arbitration_id, msg.data, decode_choices=False)
    seen = 0
    for name, value in values.items():
        match = TARGET_SIGNAL.fullmatch(name)
        if match is None:
            continue
        seen += 1
        m = AXES[int(match.group(1))]
        q = m.to_joint(float(value))
        lo, hi = LIMITS[m.joint]
        assert math.isfinite(q) and lo - LIMIT_TOL <= q <= hi + LIMIT_TOL, (
            f"target frame 0x{msg.arbitration_id:03X}: {m.joint} = {q!r} rad outside "
            f"[{lo}, {hi}]")
    assert seen, f"target frame 0x{msg.arbitration_id:03X} carries no axis"


def check_sent(frames: Sequence[TargetFrame], q: dict[str, float]) -> None:
    """One complete set of target frames, decoding to the commanded angles ``q`` [rad]."""
    assert len(frames) == len(PROTO.frame_ids("target")), len(frames)
    got = {j: v for f in frames for j, v in f.positions.items()}
    assert set(got) == set(JOINTS)
    for joint, value in got.items():
        assert abs(value - q[joint]) <= HALF_STEP, (joint, value, q[joint])


# ------------------------------------------------------------------ strategies: joint commands
#: A value put in place of one angle: at a limit, beyond one by 1 ulp, 1e-5 rad (which rounds
#: onto the limit on the DBC grid) or 0.3 rad (within the DBC range), or no angle at all.
EDGES = ("lower", "upper", "below", "above", "beyond", "far below", "far above")
BAD_VALUE = (st.sampled_from(EDGES) | st.sampled_from(EDGES)
             | st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324])
             | st.floats() | st.none() | st.just("x"))
#: What is wrong with a joint command: nothing (most often), or one or all of these.
FLAWS = ("none", "none", "none", "values", "values", "names", "lengths", "all")


def _put(value: Any, lo: float, hi: float) -> Any:
    """``value``, or the angle an `EDGES` name stands for in [lo, hi] [rad]."""
    if value not in EDGES:
        return value
    return {"lower": lo, "upper": hi, "below": math.nextafter(lo, -math.inf),
            "above": math.nextafter(hi, math.inf), "beyond": hi + 1e-5,
            "far below": lo - 0.3, "far above": hi + 0.3}[value]


@st.composite
def joint_commands(draw: st.DrawFn) -> tuple[Any, Any, Any, Any]:
    """(names, positions, velocities, efforts) of one joint command, valid or subtly not."""
    flaw = draw(st.sampled_from(FLAWS))
    names = list(draw(st.permutations(JOINTS)))
    for _ in range(draw(st.integers(1, 2)) if flaw in ("names", "all") else 0):
        edit = draw(st.sampled_from(["drop", "duplicate", "unknown", "rename"]))
        i = draw(st.integers(0, max(len(names) - 1, 0)))
        if edit == "drop" and names:
            del names[i]
        elif edit == "duplicate" and names:
            names.insert(draw(st.integers(0, len(names))), names[i])
        elif edit == "unknown":
            names.insert(i, draw(st.text(max_size=12) | st.just("tail_joint")))
        elif names:
            names[i] = names[i].upper()
    bounds = [LIMITS.get(name, (-4.0, 4.0)) for name in names]
    fractions = draw(st.lists(st.floats(0.0, 1.0), min_size=len(names), max_size=len(names)))
    positions: list[Any] = [lo + f * (hi - lo) for f, (lo, hi) in zip(fractions, bounds,
                                                                      strict=True)]
    for i, value in draw(st.lists(st.tuples(st.integers(0, 11), BAD_VALUE), min_size=1,
                                  max_size=3)) if flaw in ("values", "all") else ():
        if i < len(positions):
            positions[i] = _put(value, *bounds[i])
    n = len(names)
    lengths = [draw(st.sampled_from([0, n])) for _ in range(2)]  # velocities, efforts
    if flaw in ("lengths", "all"):
        cut = draw(st.integers(0, 2))
        if cut == 2:
            positions = positions[:draw(st.integers(0, n))] + draw(
                st.lists(st.floats(-1, 1), max_size=2))
        else:
            lengths[cut] = draw(st.integers(0, 15))
    velocities = [draw(st.floats())] * lengths[0]  # only their number matters
    efforts = [0.0] * lengths[1]
    if all(type(v) is float for v in positions) and draw(st.booleans()):
        positions = array.array("d", positions)  # what a ROS message carries
    return names, positions, velocities, efforts


def expected_valid(names: Sequence[str], positions: Sequence[Any], velocities: Sequence[Any],
                   efforts: Sequence[Any]) -> bool:
    """The driver's contract for one command, written independently of it."""
    n = len(names)
    if Counter(names) != Counter(JOINTS) or len(positions) != n:
        return False
    if len(velocities) not in (0, n) or len(efforts) not in (0, n):
        return False
    if not all(type(v) is float and math.isfinite(v) for v in velocities):
        return False  # velocities are not sent, but must be finite numbers [rad/s]
    return all(type(q) is float and LIMITS[name][0] <= q <= LIMITS[name][1]
               for name, q in zip(names, positions, strict=True))


class StepModel:
    """The driver's step bound, written independently of it: from the last accepted command
    (after an enable: the measured pose), at most speed x elapsed + margin per joint, elapsed
    clamped to [one target period, command_timeout]."""

    def __init__(self, rig: BusRig) -> None:
        self.rig = rig
        self.last: dict[str, float] | None = None
        self.time = 0.0

    def forget(self) -> None:
        self.last = None

    def within(self, names: Sequence[str], positions: Sequence[float]) -> bool:
        s, period = self.rig.settings, PROTO.cycle_period("target")
        if self.last is None:
            ref, elapsed = dict(zip(JOINTS, self.rig.measured.tolist(), strict=True)), period
        else:
            ref = self.last
            elapsed = min(max(self.rig.now - self.time, period), s.command_timeout)
        allowed = s.step_speed_limit * elapsed + s.step_margin
        return all(abs(q - ref[n]) <= allowed for n, q in zip(names, positions, strict=True))

    def sent(self, names: Sequence[str], positions: Sequence[float]) -> None:
        self.last = dict(zip(names, (float(q) for q in positions), strict=True))
        self.time = self.rig.now


DRIVER_ACTIONS = st.one_of(
    st.tuples(st.just("submit"), joint_commands()),
    st.tuples(st.just("submit"), joint_commands()),
    st.tuples(st.just("submit"), joint_commands()),
    st.tuples(st.just("tick"), st.sampled_from([0.0, 0.01, 0.05, 0.3])),
    st.tuples(st.sampled_from(["enable", "estop", "reset", "deactivate", "activate"])))


@FUZZ
@given(st.lists(DRIVER_ACTIONS, max_size=12))
def test_fuzz_joint_commands_into_the_driver(actions):
    RUNS["examples"] += 1
    with BusRig() as rig:
        core = rig.core
        step = StepModel(rig)
        for action in actions:
            if action[0] == "submit":
                RUNS["inputs"] += 1
                names, positions, velocities, efforts = action[1]
                allowed = core.motion_allowed
                result = core.submit(names, positions, velocities, efforts)
                assert isinstance(result, CommandResult)
                valid = expected_valid(names, positions, velocities, efforts)
                within = valid and allowed and step.within(names, positions)
                assert result.accepted == (valid and allowed and within), (
                    valid, allowed, within, result)
                if result.accepted:
                    step.sent(names, positions)
                assert result.accepted or result.reason
                frames = rig.drain()
                if result.accepted:
                    RUNS["accepted"] += 1
                    assert result.sent, result  # a virtual bus never refuses a frame
                    check_sent(frames, dict(zip(names, positions, strict=True)))
                else:
                    assert frames == [], "target frames of a refused command"
                continue
            if action[0] == "tick":
                rig.now += action[1]
                core.poll()
                core.tick()
            else:
                getattr(core, action[0])()
                if action[0] in ("enable", "activate"):
                    step.forget()  # the next command is bounded from the measured pose
            assert rig.drain() == [], f"target frames after {action[0]}"


# ------------------------------------------------------------------ the chain
@FUZZ
@given(st.lists(COMMAND | TWIST | TWIST | FEW_TICKS | FEW_TICKS | JUMP | MEASURE, max_size=6))
def test_fuzz_planner_targets_through_the_driver_onto_the_bus(actions):
    with BusRig(command_timeout=10.0) as rig:
        last = [STAND]  # the last target forwarded

        def forward(target: JointTarget, now: float) -> None:
            RUNS["inputs"] += 1
            rig.now = 1000.0 + now
            rig.core.tick()
            if rig.core.watchdog_tripped:  # a long ESTOP / IDLE: the operator re-enables
                rig.measure(last[0])  # where the (perfect) robot holds
                rig.core.enable()
            q = np.asarray(target.positions).tolist()
            result = rig.core.submit(JOINTS, q, np.asarray(target.velocities).tolist())
            assert result.accepted and result.sent, result.reason
            last[0] = np.asarray(q)
            RUNS["accepted"] += 1
            check_sent(rig.drain(), dict(zip(JOINTS, q, strict=True)))

        PlannerRun(on_target=forward).run(actions, playout=6)
