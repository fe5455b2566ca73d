"""Operator input: gait commands, twists, measured joint states."""

from __future__ import annotations

import json
import math
import os
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.errors import CommandError
from crawler_motion.model.config import load_config
from crawler_motion.model.joint_state import validate_joint_state
from crawler_motion.motion.gait import GaitSequencer, WalkParams, validate_params
from crawler_motion.planner.commands import (
    MAX_COMMAND_BYTES,
    MAX_STEPS,
    Command,
    parse_gait_command,
    twist_limits,
    twist_to_params,
)

CFG = load_config()
G = CFG.gait
NAMES = list(CFG.robot.joint_names)
#: The study's diagonal walk (the figures below are its timing; the default gait's own row:
#: test_the_default_gait_takes_its_own_defaults).
BASE = validate_params(WalkParams.defaults(G, gait="diagonal"), CFG)
#: Examples per property test; FUZZ_EXAMPLES=100000 for a long run.
EXAMPLES = int(os.environ.get("FUZZ_EXAMPLES", "150"))


# ------------------------------------------------------------------ gait commands
@pytest.mark.parametrize(("text", "expected"), [
    ('{"command": "stand"}', Command("stand")),
    ('{"command": "stand", "body_height": 0.05}', Command("stand", body_height=0.05)),
    ('{"command": "stand", "body_height": 0.09}', Command("stand", body_height=0.09)),
    ('{"command": "stop"}', Command("stop")),
    ('{"command": "sit"}', Command("sit")),
    ('{"command": "estop"}', Command("estop")),
    ('{"command": "reset"}', Command("reset")),
    ('  {"command": "walk"}  ', Command("walk")),
    ('{"command": "walk", "steps": 1}', Command("walk", steps=1)),
    (f'{{"command": "walk", "steps": {MAX_STEPS}}}', Command("walk", steps=MAX_STEPS)),
    ('{"command": "walk", "stride": 0}', Command("walk", overrides=(("stride", 0.0),))),
    ('{"command": "walk", "stride": 0.08}', Command("walk", overrides=(("stride", 0.08),))),
    ('{"command": "walk", "turn": -0.35}', Command("walk", overrides=(("turn", -0.35),))),
    ('{"command": "walk", "heading": 3.141592653589793}',
     Command("walk", overrides=(("heading", math.pi),))),
    ('{"command": "walk", "gait": "wave", "profile": "rest"}',
     Command("walk", overrides=(("gait", "wave"), ("profile", "rest")))),
    ('{"command": "walk", "lift": 0.001, "arc": 0.039}',
     Command("walk", overrides=(("lift", 0.001), ("arc", 0.039)))),
    ('{"command": "walk", "swing_time": 0.1, "stance_time": 0.1}',
     Command("walk", overrides=(("swing_time", 0.1), ("stance_time", 0.1)))),
    ('{"command": "walk", "swing_time": 5, "stance_time": 50}',
     Command("walk", overrides=(("swing_time", 5.0), ("stance_time", 50.0)))),
])
def test_parse_valid(text, expected):
    assert parse_gait_command(text, CFG) == expected


@pytest.mark.parametrize(("text", "fragment"), [
    ("", "not valid JSON"),
    ("{", "not valid JSON"),
    ("stand", "not valid JSON"),
    ('"stand"', "must be a JSON object"),
    ('["stand"]', "must be a JSON object"),
    ("null", "must be a JSON object"),
    ("{}", "'command' must be one of"),
    ('{"command": "jump"}', "'command' must be one of"),
    ('{"command": 1}', "'command' must be one of"),
    ('{"command": "stand", "command": "stop"}', "appears twice"),
    ('{"command": "stop", "steps": 1}', "'stop' does not take ['steps']"),
    ('{"command": "stand", "stride": 0.1}', "it accepts body_height"),
    ('{"command": "walk", "speed": 1}', "does not take ['speed']"),
    ('{"command": "walk", "body_height": 0.07}', "does not take ['body_height']"),
    ('{"command": "stand", "body_height": 0.0499}', "outside [0.05, 0.09]"),
    ('{"command": "stand", "body_height": 0.0901}', "outside [0.05, 0.09]"),
    ('{"command": "stand", "body_height": null}', "must be a number"),
    ('{"command": "stand", "body_height": "0.07"}', "must be a number"),
    ('{"command": "walk", "steps": 0}', "'steps' must be an integer in [1,"),
    ('{"command": "walk", "steps": -3}', "'steps' must be an integer"),
    (f'{{"command": "walk", "steps": {MAX_STEPS + 1}}}', "'steps' must be an integer"),
    ('{"command": "walk", "steps": 2.0}', "'steps' must be an integer"),
    ('{"command": "walk", "steps": true}', "'steps' must be an integer"),
    ('{"command": "walk", "steps": "2"}', "'steps' must be an integer"),
    ('{"command": "walk", "stride": true}', "'stride' must be a number"),
    ('{"command": "walk", "stride": -0.001}', "outside [0, 0.08] m"),
    ('{"command": "walk", "stride": 0.0801}', "outside [0, 0.08] m"),
    ('{"command": "walk", "stride": NaN}', "NaN is not a number"),
    ('{"command": "walk", "stride": Infinity}', "Infinity is not a number"),
    ('{"command": "walk", "stride": 1e400}', "outside"),
    ('{"command": "walk", "turn": 0.3501}', "outside [-0.35, 0.35] rad"),
    ('{"command": "walk", "heading": 3.2}', "outside [-3.14159"),
    ('{"command": "walk", "gait": "gallop"}',
     "'gait' must be one of ['diagonal', 'diagonal_sway', 'diagonal_zmp', 'wave']"),
    ('{"command": "walk", "profile": 1}', "'profile' must be one of"),
    ('{"command": "walk", "lift": 0.0009}', "'lift' = 0.0009 m is outside"),
    ('{"command": "walk", "arc": -0.001}', "'arc' = -0.001 m is outside"),
    ('{"command": "walk", "lift": 0.03, "arc": 0.011}', "exceeds the maximum clearance 0.04"),
    ('{"command": "walk", "swing_time": 0.09}', "outside [0.1, 5] s"),
    ('{"command": "walk", "swing_time": 5.01}', "outside [0.1, 5] s"),
    ('{"command": "walk", "swing_time": 0.6, "stance_time": 0.5}', "needs stance_time in"),
    ('{"command": "walk", "gait": "wave", "swing_time": 0.5, "stance_time": 1.0}',
     "wave gait (4 groups) needs stance_time in [1.7, 15] s"),
    ('{"command": "walk", "swing_time": 0.5, "stance_time": 5.1}', "needs stance_time in"),
])
def test_parse_refused(text, fragment):
    with pytest.raises(CommandError) as info:
        parse_gait_command(text, CFG)
    assert fragment in str(info.value)


def test_parse_length_bound():
    pad = " " * (MAX_COMMAND_BYTES - len('{"command": "stop"}'))
    assert parse_gait_command('{"command": "stop"}' + pad, CFG).kind == "stop"
    with pytest.raises(CommandError, match="too long"):
        parse_gait_command('{"command": "stop"}' + pad + " ", CFG)
    # multi-byte characters count as bytes
    with pytest.raises(CommandError, match="too long"):
        parse_gait_command('{"command": "stop", "x": "' + "é" * 2100 + '"}', CFG)


def test_parse_not_text_and_deep_nesting():
    with pytest.raises(CommandError, match="JSON text"):
        parse_gait_command(b'{"command": "stop"}', CFG)  # type: ignore[arg-type]
    with pytest.raises(CommandError):
        parse_gait_command("[" * 2000 + "]" * 2000, CFG)


def test_apply_merges_and_validates_with_base():
    cmd = parse_gait_command('{"command": "walk", "stride": 0.04, "gait": "wave"}', CFG)
    p = cmd.apply(BASE, CFG)
    assert (p.stride, p.gait, p.lift) == (0.04, "wave", BASE.lift)
    # recomputed for the new gait: 3 swings and 4 all-feet-down transfers (the body's sway)
    assert p.stance_time == pytest.approx(3 * BASE.swing_time + 4 * CFG.gait.transfer_time)
    # arc is fine on its own, but not with this base's lift
    cmd = parse_gait_command('{"command": "walk", "arc": 0.035}', CFG)
    with pytest.raises(CommandError, match="walk refused: arc"):
        cmd.apply(BASE, CFG)
    assert cmd.apply(replace(BASE, lift=0.005), CFG).arc == 0.035


@pytest.mark.parametrize(("base_swing", "command", "swing"), [
    # a default swing time follows the gait: the swaying diagonal's own, then the config's
    (G.swing_time, '{"command": "walk", "gait": "diagonal_sway"}', G.swings["diagonal_sway"]),
    (G.swing_time, '{"command": "walk", "gait": "wave"}', G.swing_time),  # no own swing time
    (0.5, '{"command": "walk", "gait": "diagonal_sway"}', 0.5),  # a chosen one is kept
    (G.swing_time, '{"command": "walk", "gait": "diagonal_sway", "swing_time": 0.7}', 0.7),
    (G.swing_time, '{"command": "walk", "gait": "diagonal"}', G.swing_time),  # same gait
])
def test_a_new_gait_takes_its_own_default_swing_time(base_swing, command, swing):
    base = validate_params(replace(BASE, swing_time=base_swing, stance_time=None), CFG)
    p = parse_gait_command(command, CFG).apply(base, CFG)
    assert p.swing_time == swing
    back = parse_gait_command('{"command": "walk", "gait": "diagonal"}', CFG).apply(p, CFG)
    assert back.swing_time == (G.swing_time if swing == G.swings.get(p.gait) else swing)


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                max_size=3),
    max_leaves=8)
KEYS = st.sampled_from(["command", "steps", "gait", "profile", "stride", "heading", "turn",
                        "lift", "arc", "swing_time", "stance_time", "body_height", "x"])
COMMAND_OBJECTS = st.dictionaries(
    KEYS, st.sampled_from(["stand", "walk", "stop", "sit", "estop", "reset", "wave", "rest"])
    | st.integers(-5, 20_000) | st.floats(allow_nan=True, allow_infinity=True) | JSON_VALUES,
    max_size=6)


def _parse_or_command_error(text):
    try:
        cmd = parse_gait_command(text, CFG)
    except CommandError as exc:
        assert str(exc)
        return
    assert isinstance(cmd, Command)
    if cmd.kind == "walk":
        try:
            p = cmd.apply(BASE, CFG)
        except CommandError:
            return
        assert validate_params(p, CFG) == p


@settings(max_examples=EXAMPLES, deadline=None)
@given(COMMAND_OBJECTS)
def test_fuzz_command_objects(obj):
    _parse_or_command_error(json.dumps(obj, allow_nan=True))


@settings(max_examples=EXAMPLES, deadline=None)
@given(JSON_VALUES)
def test_fuzz_any_json(value):
    _parse_or_command_error(json.dumps(value, allow_nan=True))


@settings(max_examples=EXAMPLES, deadline=None)
@given(st.text(max_size=200))
def test_fuzz_any_text(text):
    _parse_or_command_error(text)


# ------------------------------------------------------------------ twists
def test_twist_forward_matches_the_sequencer_speed():
    v_max, w_max = twist_limits(CFG, BASE)
    assert w_max == pytest.approx(G.max_turn / (BASE.swing_time + BASE.stance_time))
    assert v_max == pytest.approx(G.max_stride / BASE.stance_time)
    p = twist_to_params(0.05, 0.0, 0.0, CFG, BASE)
    assert p.heading == 0.0 and p.turn == 0.0
    # per slot the body moves b * stride: over one step (n slots) the body travels v * step time
    seq = GaitSequencer(CFG, p)
    slot, b, _ = seq._fractions(p)
    n = seq.n_groups
    assert n * b * p.stride / (n * slot) == pytest.approx(0.05)


@pytest.mark.parametrize(("vx", "vy", "wz", "stride", "heading", "turn"), [
    (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    (-0.05, 0.0, 0.0, 0.03, math.pi, 0.0),
    (0.0, 0.1, 0.0, 0.06, math.pi / 2, 0.0),
    (0.0, 0.0, 0.2, 0.0, 0.0, 0.2 * 1.2),
    (0.0, 0.0, -0.35 / 1.2, 0.0, 0.0, -0.35),
    (0.08 / 0.6, 0.0, 0.35 / 1.2, 0.08, 0.0, 0.35),  # both exactly at the limits
])
def test_twist_table(vx, vy, wz, stride, heading, turn):
    p = twist_to_params(vx, vy, wz, CFG, BASE)
    assert p.stride == pytest.approx(stride)
    assert p.heading == pytest.approx(heading)
    assert p.turn == pytest.approx(turn)
    assert (p.gait, p.swing_time, p.lift) == (BASE.gait, BASE.swing_time, BASE.lift)


@pytest.mark.parametrize(("vx", "vy", "wz", "fragment"), [
    (0.14, 0.0, 0.0, "exceeds the maximum 0.1333 m/s"),
    (0.1, 0.1, 0.0, "speed 0.1414 m/s exceeds"),
    (0.0, 0.0, 0.3, "yaw rate 0.3 rad/s exceeds the maximum 0.2917"),
    (math.nan, 0.0, 0.0, "linear.x must be a finite number"),
    (0.0, math.inf, 0.0, "linear.y must be a finite number"),
    (0.0, 0.0, -math.inf, "angular.z must be a finite number"),
    (True, 0.0, 0.0, "linear.x must be a finite number"),
])
def test_twist_refused(vx, vy, wz, fragment):
    with pytest.raises(CommandError) as info:
        twist_to_params(vx, vy, wz, CFG, BASE)
    assert fragment in str(info.value)


def test_twist_limits_follow_the_base_timing():
    slow = validate_params(replace(BASE, swing_time=1.2, stance_time=None), CFG)
    assert twist_to_params(0.06, 0, 0, CFG, slow).stride == pytest.approx(0.072)
    with pytest.raises(CommandError):
        twist_to_params(0.07, 0, 0, CFG, slow)


@settings(max_examples=EXAMPLES, deadline=None)
@given(st.floats(), st.floats(), st.floats())
def test_fuzz_twists(vx, vy, wz):
    try:
        p = twist_to_params(vx, vy, wz, CFG, BASE)
    except CommandError:
        return
    assert validate_params(p, CFG) == p
    assert 0.0 <= p.stride <= G.max_stride and abs(p.turn) <= G.max_turn


# ------------------------------------------------------------------ joint states
def test_joint_state_reorders_by_name():
    values = np.arange(12, dtype=float) / 10
    order = list(reversed(range(12)))
    q = validate_joint_state([NAMES[i] for i in order], values[order], [], NAMES)
    assert q.shape == (4, 3)
    np.testing.assert_array_equal(q.reshape(-1), values)
    q = validate_joint_state(NAMES, values, values, NAMES)
    np.testing.assert_array_equal(q.reshape(-1), values)


@pytest.mark.parametrize(("names", "positions", "velocities", "fragment"), [
    (NAMES[:11], [0.0] * 11, [], "missing ['rf_knee_joint']"),
    ([*NAMES, "tail_joint"], [0.0] * 13, [], "unknown ['tail_joint']"),
    ([*NAMES[:11], NAMES[0]], [0.0] * 12, [], "appear more than once"),
    (NAMES, [0.0] * 11, [], "12 names but 11 positions"),
    (NAMES, [0.0] * 12, [0.0] * 3, "12 names but 3 velocities"),
    (NAMES, [0.0] * 11 + [math.nan], [], "NaN or inf"),
    (NAMES, [0.0] * 12, [math.inf] + [0.0] * 11, "NaN or inf"),
    (NAMES, ["a"] * 12, [], "must be numbers"),
    ([1] * 12, [0.0] * 12, [], "names must be strings"),
])
def test_joint_state_refused(names, positions, velocities, fragment):
    with pytest.raises(CommandError) as info:
        validate_joint_state(names, positions, velocities, NAMES)
    assert fragment in str(info.value)


def test_the_default_gait_takes_its_own_defaults():
    # the default walk and a walk command switching to and from it carry each table's own
    # swing time, stride and stance profile
    default = validate_params(WalkParams.defaults(G), CFG)
    assert (default.gait, default.swing_time, default.stride, default.stance_profile) == (
        "diagonal_zmp", G.swings["diagonal_zmp"], G.strides["diagonal_zmp"], "continuous")
    back = parse_gait_command('{"command": "walk", "gait": "diagonal"}', CFG).apply(default, CFG)
    assert (back.swing_time, back.stride, back.stance_profile) == (G.swing_time, G.stride,
                                                                  G.stance_profile)
    again = parse_gait_command('{"command": "walk", "gait": "diagonal_zmp"}', CFG).apply(back,
                                                                                        CFG)
    assert again == default
    kept = parse_gait_command('{"command": "walk", "gait": "diagonal", "stride": 0.03}',
                              CFG).apply(default, CFG)
    assert kept.stride == 0.03  # a chosen one is kept
