"""The walk option table: keys, flags, config ranges and the rules tying two options."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from crawler_motion.model.config import load_config
from crawler_motion.motion.walk_options import (
    MIN_TRANSFER_TIME,
    OPTIONS,
    POSE_OPTIONS,
    WALK_OPTIONS,
    OptionType,
    Sign,
    clearance_error,
    default_stance_time,
    field_ranges,
    options_of,
    pose_height_error,
    stance_time_error,
    stance_time_range,
    sways,
)

CFG = load_config()
G = CFG.gait


def test_keys_and_flags():
    assert [o.name for o in options_of("walk")] == [
        "steps", "gait", "profile", "stride", "heading", "turn", "lift", "arc", "swing_time",
        "stance_time", "stance_profile", "margin"]
    assert [o.name for o in options_of("stand")] == ["body_height"]
    assert options_of("stop") == ()
    assert [o.flag for o in WALK_OPTIONS] == [
        "--steps", "--gait", "--profile", "--stride", "--heading", "--turn", "--lift", "--arc",
        "--swing-time", "--stance-time", "--stance-profile", "--margin", "--body-height"]
    assert OPTIONS["swing_time"].label == "swing time"
    assert [o.name for o in WALK_OPTIONS if o.parameter] == [
        "gait", "profile", "stride", "lift", "arc", "swing_time", "stance_profile", "margin",
        "body_height"]


@pytest.mark.parametrize(("name", "lo", "hi", "unit", "sign"), [
    ("stride", 0.0, 0.08, "m", Sign.NONNEGATIVE),
    ("heading", -math.pi, math.pi, "rad", Sign.ANY),
    ("turn", -0.35, 0.35, "rad", Sign.ANY),
    ("lift", 0.001, 0.04, "m", Sign.POSITIVE),
    ("arc", 0.0, 0.04, "m", Sign.NONNEGATIVE),
    ("swing_time", 0.1, 5.0, "s", Sign.POSITIVE),
    ("stance_time", 0.1, 150.0, "s", Sign.POSITIVE),  # 10 x (4 wave groups - 1) x 5 s
    ("body_height", 0.05, 0.09, "m", Sign.POSITIVE),
])
def test_ranges_from_the_config(name, lo, hi, unit, sign):
    option = OPTIONS[name]
    assert option.type is OptionType.NUMBER
    assert option.range(CFG) == pytest.approx((lo, hi))
    assert (option.unit, option.sign) == (unit, sign)
    assert field_ranges(CFG)[name] == (*option.range(CFG), unit)


def test_choices_from_the_config():
    assert OPTIONS["gait"].allowed(CFG) == tuple(G.gaits)
    assert OPTIONS["profile"].allowed(CFG) == tuple(G.profiles)
    assert OPTIONS["steps"].type is OptionType.COUNT
    assert set(field_ranges(CFG)) == {o.name for o in OPTIONS.values()
                                      if o.type is OptionType.NUMBER}


def test_pose_options_are_the_pose_command_keys():
    assert [o.name for o in options_of("pose")] == ["x", "y", "z", "roll", "pitch", "yaw"]
    assert [o.flag for o in POSE_OPTIONS] == ["--x", "--y", "--z", "--roll", "--pitch", "--yaw"]
    assert not any(o.parameter or o.default for o in POSE_OPTIONS)  # absent: 0
    assert not set(POSE_OPTIONS) & set(WALK_OPTIONS)


@pytest.mark.parametrize(("name", "lo", "hi", "unit"), [
    ("x", -0.03, 0.03, "m"),  # body_pose.max_shift
    ("y", -0.03, 0.03, "m"),
    ("z", -0.04, 0.04, "m"),  # the span of body_height_range [0.05, 0.09]
    ("roll", -0.2, 0.2, "rad"),  # body_pose.max_tilt
    ("pitch", -0.2, 0.2, "rad"),
    ("yaw", -0.2, 0.2, "rad"),  # body_pose.max_yaw
])
def test_pose_ranges_from_the_config(name, lo, hi, unit):
    option = OPTIONS[name]
    assert option.range(CFG) == pytest.approx((lo, hi))
    assert field_ranges(CFG)[name] == (*option.range(CFG), unit)


@pytest.mark.parametrize(("height", "z", "refused"), [
    (0.07, 0.02, False),  # exactly the top of body_height_range
    (0.07, -0.02, False),  # exactly the bottom
    (0.07, 0.02 + 1e-13, False),  # rounding
    (0.07, 0.0201, True),
    (0.07, -0.0201, True),
    (0.09, 0.001, True),
    (0.05, 0.04, False),
])
def test_pose_height_rule(height, z, refused):
    problem = pose_height_error(CFG, height, z)
    assert (problem is not None) == refused
    if refused:
        assert problem.startswith(f"z = {z:g} m") and "body_height_range [0.05, 0.09] m" in problem
        assert f"[{0.05 - height:g}, {0.09 - height:g}] m" in problem


@pytest.mark.parametrize(("lift", "arc", "refused"), [
    (0.03, 0.01, False),  # exactly the maximum clearance
    (0.03, 0.01 + 1e-13, False),  # rounding
    (0.03, 0.0101, True),
    (0.04, 0.0, False),
])
def test_clearance_rule(lift, arc, refused):
    problem = clearance_error(CFG, lift, arc)
    assert (problem is not None) == refused
    if refused:
        assert problem.startswith(f"arc = {arc:g} m") and "maximum clearance 0.04 m" in problem


@pytest.mark.parametrize(("gait", "swing", "stance", "refused"), [
    ("diagonal", 0.6, 0.6, False),
    ("diagonal", 0.6, 6.0, False),
    ("diagonal", 0.6, 0.6 - 1e-13, False),
    ("diagonal", 0.6, 0.59, True),
    ("diagonal", 0.6, 6.01, True),
    ("wave", 0.5, 1.7, False),  # 3 x swing + 4 x 0.05 s of transfer (the body's sway)
    ("wave", 0.5, 1.7 - 1e-13, False),
    ("wave", 0.5, 1.69, True),
    ("wave", 0.5, 1.5, True),
    ("wave", 0.5, 15.0, False),
    ("wave", 0.5, 15.01, True),
])
def test_stance_time_rule(gait, swing, stance, refused):
    lo, hi = stance_time_range(CFG, gait, swing)
    assert hi == pytest.approx(10 * (len(CFG.gait.gaits[gait]) - 1) * swing)
    problem = stance_time_error(CFG, gait, swing, stance)
    assert (problem is not None) == refused
    if refused:
        assert f"the {gait} gait" in problem
        assert f"needs stance_time in [{lo:g}, {hi:g}] s" in problem


@pytest.mark.parametrize(("transfers", "gait", "stance", "swaying"), [
    ({}, "diagonal", 0.6, False),  # shipped: the diagonal gait has no transfer (it rocks)
    ({}, "wave", 3.0, True),  # a crawl: 3 x 0.6 s + 4 x transfer_time 0.3 s
    ({"diagonal": 0.3}, "diagonal", 1.2, True),  # its table's own: its default walk sways
    ({"diagonal": MIN_TRANSFER_TIME}, "diagonal", 0.7, True),
    ({"diagonal": 0.04}, "diagonal", 0.68, False),  # below the shortest transfer: no sway
    ({"wave": 0.2}, "wave", 2.6, True),
])
def test_default_stance_time_adds_the_gaits_transfers(transfers, gait, stance, swaying):
    cfg = replace(CFG, gait=replace(CFG.gait, transfers=transfers))
    assert default_stance_time(cfg, gait, 0.6) == pytest.approx(stance, abs=1e-12)
    assert sways(cfg, gait, 0.6, default_stance_time(cfg, gait, 0.6)) is swaying
