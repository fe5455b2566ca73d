"""Tests of crawler_motion.canbus.layout: the compiled frame layouts pack and unpack exactly as
cantools does (scaling, strict), for the shipped DBC and for odd signal layouts."""

from __future__ import annotations

import math

import cantools
import pytest
from cantools.database import DecodeError, EncodeError
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.canbus.layout import FrameLayout, compile_layout
from crawler_motion.model.config import config_path

#: Signals at odd places: unaligned, 1 to 13 bits, signed and unsigned, offsets, open ranges,
#: a value table, a range narrower than the bits and one wider than them.
ODD_DBC = """VERSION ""

NS_ :

BS_:

BU_: A B

BO_ 300 Odd: 7 A
 SG_ Flag : 0|1@1+ (1,0) [0|1] "" B
 SG_ Small : 1|3@1- (1,0) [-4|3] "" B
 SG_ Offset : 4|13@1+ (0.5,-100) [-100|3995.5] "" B
 SG_ Wide : 17|11@1- (0.25,2) [-300|300] "" B
 SG_ Narrow : 28|8@1+ (1,0) [10|200] "" B
 SG_ Mode : 36|4@1+ (1,0) [0|3] "" B
 SG_ Loose : 40|12@1- (0.001,0) [0|0] "" B

VAL_ 300 Mode 0 "off" 1 "on" 9 "test" ;
"""


def _shipped() -> list:
    return list(cantools.database.load_file(str(config_path("motor_manager.dbc")),
                                            strict=True).messages)


def _odd() -> list:
    return list(cantools.database.load_string(ODD_DBC, "dbc", strict=True).messages)


MESSAGES = _shipped() + _odd()
IDS = [m.name for m in MESSAGES]


def _cantools_unpack(message, data: bytes):
    try:
        return message.decode(data, decode_choices=False, scaling=True, allow_truncated=False,
                              allow_excess=False)
    except Exception:
        return "refused"


def _layout_unpack(layout: FrameLayout, data: bytes):
    try:
        return layout.unpack(data)
    except DecodeError:
        return "refused"


def _cantools_pack(message, values):
    try:
        return message.encode(dict(values), scaling=True, padding=False, strict=True)
    except Exception:
        return "refused"


def _layout_pack(layout: FrameLayout, values):
    try:
        return layout.pack(dict(values))
    except (EncodeError, ValueError, OverflowError):
        return "refused"


def _same(a, b) -> bool:
    """Equal values of equal types (1 and 1.0 differ: cantools keeps ints unscaled)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return type(a) is type(b) and a == b


@pytest.mark.parametrize("message", MESSAGES, ids=IDS)
def test_every_frame_of_the_shipped_and_odd_dbc_compiles(message) -> None:
    layout = compile_layout(message)
    assert layout is not None and [s.name for s in layout.signals] == \
        [s.name for s in message.signals]


@pytest.mark.parametrize("message", MESSAGES, ids=IDS)
@settings(max_examples=150, deadline=None)
@given(data=st.binary(min_size=0, max_size=9))
def test_unpack_equals_cantools(message, data: bytes) -> None:
    layout = compile_layout(message)
    ours, theirs = _layout_unpack(layout, data), _cantools_unpack(message, data)
    assert _same(ours, theirs), (data.hex(), ours, theirs)


@pytest.mark.parametrize("message", MESSAGES, ids=IDS)
@settings(max_examples=150, deadline=None)
@given(data=st.binary(min_size=8, max_size=8), seed=st.data())
def test_pack_equals_cantools(message, data: bytes, seed) -> None:
    """Values near and beyond each signal's range and bits, whole and fractional; a missing or
    an unknown signal."""
    layout = compile_layout(message)
    values = dict(message.decode(data[:message.length], decode_choices=False, scaling=True))
    for signal in message.signals:
        span = max(abs(signal.minimum or 0.0), abs(signal.maximum or 0.0), 1.0)
        values[signal.name] = seed.draw(st.one_of(
            st.just(values[signal.name]),
            st.floats(-2 * span, 2 * span, allow_nan=False),
            st.integers(-(1 << signal.length), 1 << signal.length),
            st.sampled_from([signal.minimum, signal.maximum]).filter(lambda v: v is not None)
            .map(float)), label=signal.name)
    change = seed.draw(st.sampled_from(["none", "missing", "unknown"]), label="change")
    if change == "missing":
        values.pop(message.signals[0].name)
    elif change == "unknown":
        values["Nonexistent"] = 0
    ours, theirs = _layout_pack(layout, values), _cantools_pack(message, values)
    assert ours == theirs, (values, ours, theirs)


def test_pack_boundary_rows() -> None:
    """Each range end and one step beyond it, as cantools decides (slack: 1e-6 of a scale)."""
    message = next(m for m in _odd() if m.name == "Odd")
    layout = compile_layout(message)
    base = {s.name: 0 for s in message.signals} | {"Offset": 0.0, "Narrow": 10, "Wide": 2.0}
    rows = [("Narrow", 10, True), ("Narrow", 9, False), ("Narrow", 200, True),
            ("Narrow", 201, False), ("Mode", 9, True),  # beyond the range, in the value table
            ("Mode", 4, False), ("Small", -4, True), ("Small", -5, False),
            ("Offset", 3995.5, True), ("Offset", 3995.5 + 1e-7, True),
            ("Offset", 3996.0, False), ("Wide", 300.0, False),  # in range, not in 11 bits
            ("Loose", 2.0, True), ("Loose", -2.049, False)]  # [0|0]: open
    for name, value, ok in rows:
        values = base | {name: value}
        assert (_layout_pack(layout, values) != "refused") is ok, (name, value)
        assert _layout_pack(layout, values) == _cantools_pack(message, values), (name, value)


@pytest.mark.parametrize("value", [math.nan, math.inf, "1", True])
def test_pack_refuses_what_is_not_a_finite_number(value) -> None:
    message = _shipped()[1]
    layout = compile_layout(message)
    values = {s.name: 0 for s in message.signals} | {message.signals[0].name: value}
    assert _layout_pack(layout, values) == "refused"


def test_a_floating_point_signal_is_left_to_cantools() -> None:
    text = ODD_DBC.replace('VAL_', 'BO_ 301 Float: 4 A\n SG_ Value : 0|32@1- (1,0) [0|0] "" '
                                   'B\n\nSIG_VALTYPE_ 301 Value : 1;\n\nVAL_')
    messages = cantools.database.load_string(text, "dbc", strict=True).messages
    floats = [m for m in messages if m.name == "Float"]
    assert floats and compile_layout(floats[0]) is None
