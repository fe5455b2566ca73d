"""Tests of crawler_motion.canbus.protocol: the DBC and axis map of the motor manager, as data."""

from __future__ import annotations

import math
from pathlib import Path

import can
import cantools
import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.canbus.busload import frame_bits_worst_case
from crawler_motion.canbus.crc import crc8_sae_j1850
from crawler_motion.canbus.protocol import (
    AxisFlags,
    AxisStatus,
    ControlFrame,
    Heartbeat,
    MotorProtocol,
    PositionFeedback,
    TargetFrame,
)
from crawler_motion.errors import ProtocolError
from crawler_motion.model.config import config_path, joint_names, load_config

JOINTS = joint_names()
RES = 0.0001


def mid_pose(proto: MotorProtocol) -> np.ndarray:
    """A valid pose: the middle of every joint range."""
    return 0.5 * (proto.lower + proto.upper)


def raw_slot(msgs: list[can.Message], axis: int) -> int:
    """Raw int16 of an axis in the default layout (3 axes per frame, 2 bytes each)."""
    data = msgs[axis // 3].data
    slot = axis % 3
    return int.from_bytes(data[2 * slot:2 * slot + 2], "little", signed=True)


def crafted(proto: MotorProtocol, name: str, values: dict, *, fix_checksum: bool = True,
            reserved: int = 0) -> can.Message:
    """A frame built with cantools without range checks, with a valid checksum."""
    message = proto.database.get_message_by_name(name)
    signals = {s.name: 0 for s in message.signals}
    signals.update(values)
    data = bytearray(message.encode(signals, scaling=False, strict=False))
    data = bytearray((int.from_bytes(data, "little") | reserved).to_bytes(len(data), "little"))
    if fix_checksum and "Checksum" in signals:
        body = bytes(data[:7])
        data[7] = crc8_sae_j1850(message.frame_id.to_bytes(2, "little") + body)
    return can.Message(arbitration_id=message.frame_id, data=bytes(data), is_extended_id=False)


def default_axes() -> dict:
    return yaml.safe_load(config_path("axes.yaml").read_text(encoding="utf-8"))


def write_axes(tmp_path: Path, data: object) -> Path:
    path = tmp_path / "axes.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def build(robot, axes: Path, dbc: Path | None = None) -> MotorProtocol:
    return MotorProtocol.from_config(robot, dbc_path=dbc, axes_path=axes)


# ---- loading ------------------------------------------------------------------------------


def test_shipped_files_load_with_expected_shape(proto):
    assert proto.joint_names == JOINTS
    assert proto.n_axes == 12
    assert proto.resolution_rad == pytest.approx(RES, rel=0, abs=1e-15)
    assert proto.commands == ("disable", "enable", "hold", "estop", "reset")
    assert proto.states == ("disabled", "enabled", "hold", "estop", "fault")
    assert [m.axis for m in proto.axis_map] == list(range(12))
    flipped = sorted(m.joint for m in proto.axis_map if m.direction == -1)
    assert flipped == ["rb_knee_joint", "rb_shoulder_joint", "rf_knee_joint",
                       "rf_shoulder_joint"]
    assert proto.period("target") == pytest.approx(0.01)
    assert proto.period("position") == pytest.approx(0.01)
    assert proto.period("heartbeat") == pytest.approx(0.1)
    assert sorted(proto.frame_ids("target")) == [0x100, 0x101, 0x102, 0x103]


def test_every_dbc_signal_is_documented(proto):
    db = cantools.database.load_file(str(config_path("motor_manager.dbc")), strict=True)
    for message in db.messages:
        assert message.comment, message.name
        assert message.frame_id < 0x800 and not message.is_extended_frame
        for signal in message.signals:
            assert signal.comment, f"{message.name}.{signal.name}"
            assert signal.byte_order == "little_endian"
            if signal.name.endswith(("_Target", "_Position")):
                assert signal.unit == "rad"
                assert (signal.scale, signal.minimum, signal.maximum) == (RES, -3.2767, 3.2767)


# ---- targets: boundary table ---------------------------------------------------------------


@pytest.mark.parametrize(("joint", "angle", "raw"), [
    ("lf_root_joint", 0.0, 0),
    ("lf_root_joint", RES, 1),  # exactly one resolution step
    ("lf_root_joint", -RES, -1),
    ("lf_root_joint", 0.00004, 0),  # rounds to nearest, not truncation
    ("lf_root_joint", 0.00006, 1),
    ("lf_root_joint", 0.9, 9000),  # upper limit
    ("lf_root_joint", -0.9, -9000),  # lower limit
    ("lf_shoulder_joint", -1.0, -10000),
    ("lf_shoulder_joint", 1.4, 14000),
    ("lf_knee_joint", 0.1, 1000),
    ("lf_knee_joint", 2.6, 26000),
    ("rb_knee_joint", 2.6, -26000),  # direction -1 applied
    ("rf_shoulder_joint", 1.4, -14000),
    ("rf_shoulder_joint", -1.0, 10000),
    ("rf_root_joint", -0.9, -9000),  # direction +1 on a right leg's root
])
def test_target_encoding_table(proto, joint, angle, raw):
    q = mid_pose(proto)
    i = JOINTS.index(joint)
    q[i] = angle
    msgs = proto.encode_targets(q, 0)
    assert [m.arbitration_id for m in msgs] == [0x100, 0x101, 0x102, 0x103]
    assert all(m.dlc == 8 and not m.is_extended_id for m in msgs)
    assert raw_slot(msgs, i) == raw
    frame = proto.decode(msgs[i // 3])
    assert isinstance(frame, TargetFrame)
    assert frame.group == i // 3
    assert frame.positions[joint] == pytest.approx(angle, abs=RES / 2 + 1e-12)
    assert frame.axes[i] == pytest.approx(raw * RES, abs=1e-12)


@pytest.mark.parametrize(("joint", "angle"), [
    ("lf_root_joint", 0.9 + 1e-9),
    ("lf_root_joint", -0.9 - 1e-9),
    ("lf_shoulder_joint", 1.4 + 1e-6),
    ("lf_knee_joint", 0.1 - 1e-6),
    ("rf_knee_joint", 2.6 + 1e-9),
    ("rb_shoulder_joint", -1.0 - 1e-9),
    ("lb_root_joint", 10.0),
])
def test_target_just_beyond_limits_raises_naming_the_joint(proto, joint, angle):
    q = mid_pose(proto)
    q[JOINTS.index(joint)] = angle
    with pytest.raises(ProtocolError, match=joint) as err:
        proto.encode_targets(q, 0)
    assert "limits" in str(err.value)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_target_nan_and_inf_raise(proto, bad):
    q = mid_pose(proto)
    q[5] = bad
    with pytest.raises(ProtocolError, match=r"lb_knee_joint.*finite"):
        proto.encode_targets(q, 0)


@pytest.mark.parametrize("size", [0, 11, 13])
def test_target_vector_of_wrong_size_raises(proto, size):
    with pytest.raises(ProtocolError, match="12 values"):
        proto.encode_targets(np.full(size, 0.2), 0)


def test_targets_accept_a_4x3_array(proto):
    q = mid_pose(proto)
    flat = proto.encode_targets(q, 3)
    shaped = proto.encode_targets(q.reshape(4, 3), 3)
    assert [m.data for m in flat] == [m.data for m in shaped]


@pytest.mark.parametrize(("counter", "sent"), [
    (0, 0), (1, 1), (15, 15), (16, 0), (17, 1), (31, 15), (1_000_003, 3), (np.int64(18), 2),
])
def test_counter_wraps_modulo_16(proto, counter, sent):
    msgs = proto.encode_targets(mid_pose(proto), counter)
    assert all(m.data[6] == sent for m in msgs)  # upper nibble reserved, 0
    assert {proto.decode(m).counter for m in msgs} == {sent}


@pytest.mark.parametrize("counter", [-1, 1.0, True, "3", None])
def test_bad_counter_raises(proto, counter):
    with pytest.raises(ProtocolError, match="counter"):
        proto.encode_targets(mid_pose(proto), counter)


def test_zero_offset_and_direction_are_applied(robot, tmp_path):
    data = default_axes()
    data["axes"]["lf_root_joint"]["zero_offset"] = 0.5
    data["axes"]["lf_knee_joint"].update(direction=-1, zero_offset=0.25)
    proto = build(robot, write_axes(tmp_path, data))
    q = mid_pose(proto)
    q[0], q[2] = 0.0, 1.0
    msgs = proto.encode_targets(q, 0)
    assert raw_slot(msgs, 0) == 5000
    assert raw_slot(msgs, 2) == -7500  # -1 * 1.0 + 0.25
    frame = proto.decode(msgs[0])
    assert frame.positions["lf_root_joint"] == pytest.approx(0.0, abs=1e-12)
    assert frame.positions["lf_knee_joint"] == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(proto.to_joint(proto.to_axis(q)), q, atol=1e-12)


def test_axis_order_differs_from_joint_order(robot, tmp_path):
    data = default_axes()
    data["axes"]["lf_root_joint"]["axis"] = 11
    data["axes"]["rf_knee_joint"]["axis"] = 0
    proto = build(robot, write_axes(tmp_path, data))
    q = mid_pose(proto)
    q[0] = 0.3
    msgs = proto.encode_targets(q, 0)
    assert raw_slot(msgs, 11) == 3000
    frame = proto.decode(msgs[3])
    assert frame.positions["lf_root_joint"] == pytest.approx(0.3)
    assert frame.axes[11] == pytest.approx(0.3)
    assert proto.to_axis(q)[11] == pytest.approx(0.3)


# ---- hypothesis: round trip within resolution ---------------------------------------------


_LOWER = np.asarray(load_config().robot.lower_limits()).reshape(-1)
_UPPER = np.asarray(load_config().robot.upper_limits()).reshape(-1)


@st.composite
def in_limit_poses(draw):
    return np.array([draw(st.floats(min_value=float(lo), max_value=float(hi),
                                    allow_nan=False, allow_infinity=False))
                     for lo, hi in zip(_LOWER, _UPPER, strict=True)])


@settings(max_examples=150, deadline=None)
@given(q=in_limit_poses(), counter=st.integers(min_value=0, max_value=2**40))
def test_round_trip_within_resolution(proto, q, counter):
    decoded: dict[str, float] = {}
    for msg in proto.encode_targets(q, counter):
        frame = proto.decode(msg)
        assert isinstance(frame, TargetFrame)
        assert frame.counter == counter % 16
        decoded.update(frame.positions)
    assert list(decoded) == list(JOINTS)
    got = np.array([decoded[j] for j in JOINTS])
    assert np.max(np.abs(got - q)) <= RES / 2 + 1e-12


# ---- other frames ---------------------------------------------------------------------------


@pytest.mark.parametrize(("command", "byte"), [
    ("disable", 0), ("enable", 1), ("hold", 2), ("estop", 3), ("reset", 4),
])
def test_control_round_trip(proto, command, byte):
    msg = proto.encode_control(command)
    assert msg.arbitration_id == 0x080
    assert bytes(msg.data) == bytes([byte, byte ^ 0xFF])
    assert proto.decode(msg) == ControlFrame(command)


def test_unknown_command_raises(proto):
    with pytest.raises(ProtocolError, match=r"unknown command 'halt'.*estop"):
        proto.encode_control("halt")


@pytest.mark.parametrize(("state", "counter", "sent"), [
    ("disabled", 0, 0), ("enabled", 255, 255), ("estop", 256, 0), ("fault", 300, 44),
])
def test_heartbeat_round_trip(proto, state, counter, sent):
    msg = proto.encode_heartbeat(state, counter)
    assert msg.arbitration_id == 0x701
    assert proto.decode(msg) == Heartbeat(state, sent)


def test_unknown_state_raises(proto):
    with pytest.raises(ProtocolError, match="unknown manager state 'asleep'"):
        proto.encode_heartbeat("asleep", 0)


@pytest.mark.parametrize("flag", ["enabled", "tracking", "over_current", "over_temp",
                                  "encoder_fault", "stalled", "command_timeout"])
@pytest.mark.parametrize("axis", [0, 5, 6, 11])
def test_status_flags_round_trip(proto, flag, axis):
    flags = [AxisFlags() for _ in range(12)]
    flags[axis] = AxisFlags(**{flag: True})
    msgs = proto.encode_status(flags, 7)
    assert [m.arbitration_id for m in msgs] == [0x190, 0x191]
    decoded = [proto.decode(m) for m in msgs]
    assert all(isinstance(d, AxisStatus) and d.counter == 7 for d in decoded)
    by_axis = {**decoded[0].axes, **decoded[1].axes}
    assert by_axis == {a: flags[a] for a in range(12)}
    by_joint = {**decoded[0].flags, **decoded[1].flags}
    assert by_joint[JOINTS[axis]] == AxisFlags(**{flag: True})
    assert by_joint[JOINTS[axis]].fault == (flag in ("over_current", "over_temp",
                                                     "encoder_fault"))


def test_feedback_is_reported_in_joint_space(proto):
    axes = np.zeros(12)
    axes[7] = 0.5  # rb_shoulder, direction -1
    axes[2] = 1.25
    msgs = proto.encode_feedback(axes, 9)
    assert [m.arbitration_id for m in msgs] == [0x180, 0x181, 0x182, 0x183]
    positions: dict[str, float] = {}
    for msg in msgs:
        frame = proto.decode(msg)
        assert isinstance(frame, PositionFeedback) and frame.counter == 9
        positions.update(frame.positions)
    assert positions["rb_shoulder_joint"] == pytest.approx(-0.5)
    assert positions["lf_knee_joint"] == pytest.approx(1.25)
    assert positions["lf_root_joint"] == 0.0


@pytest.mark.parametrize(("axis", "value", "ok"), [
    (2, 0.1 - 0.2, True),  # knee: lower limit - margin
    (2, 0.1 - 0.2 - 0.001, False),
    (0, 0.9 + 0.2, True),
    (0, 0.9 + 0.2 + 0.001, False),
    (8, -(2.6 + 0.2) - 0.001, False),  # rb knee, direction -1
])
def test_feedback_margin_boundaries(proto, axis, value, ok):
    axes = np.zeros(12)
    axes[axis] = value
    raw = round(value / RES)
    frame = crafted(proto, f"MM_Position_{axis // 3}", {f"Axis{axis}_Position": raw})
    if ok:
        proto.encode_feedback(axes, 0)
        assert proto.decode(frame).axes[axis] == pytest.approx(value, abs=RES)
    else:
        with pytest.raises(ProtocolError, match=JOINTS[axis]):
            proto.encode_feedback(axes, 0)
        with pytest.raises(ProtocolError, match=JOINTS[axis]):
            proto.decode(frame)


def test_cantools_strict_range_error_is_wrapped(robot, tmp_path):
    data = default_axes()
    data["axes"]["lf_knee_joint"]["zero_offset"] = 0.6  # limits map to [0.7, 3.2] rad: fits
    proto = build(robot, write_axes(tmp_path, data))
    axes = proto.to_axis(mid_pose(proto))
    axes[2] = 3.3  # joint 2.7: within the feedback margin, beyond the int16 scaling
    with pytest.raises(ProtocolError, match=r"lf_knee_joint.*beyond Axis2_Position") as err:
        proto.encode_feedback(axes, 0)
    assert isinstance(err.value.__cause__, cantools.database.EncodeError)


def test_frame_bits_worst_case():
    assert frame_bits_worst_case(8) == 135
    assert frame_bits_worst_case(2) == 75
    assert frame_bits_worst_case(0) == 55
    assert frame_bits_worst_case(8, extended=True) == 160
    with pytest.raises(ProtocolError, match=r"0\.\.8"):
        frame_bits_worst_case(9)


def test_cycle_bits(proto):
    assert proto.cycle_bits() == {"control": 75, "target": 540, "position": 540,
                                  "effort": 540, "status": 270, "heartbeat": 75}


def test_crc8_check_value():
    assert crc8_sae_j1850(b"123456789") == 0x4B
    assert crc8_sae_j1850(b"") == 0x00  # init 0xFF, xorout 0xFF


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=16))
def test_crc8_table_equals_the_bitwise_definition(data):
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    assert crc8_sae_j1850(data) == crc ^ 0xFF


# ---- decoding refuses what is not a valid frame ---------------------------------------------


def _target0(proto: MotorProtocol) -> can.Message:
    return proto.encode_targets(mid_pose(proto), 0)[0]


def _bad_frames(proto: MotorProtocol) -> list[tuple[str, can.Message, str]]:
    good = _target0(proto)
    flipped = bytearray(good.data)
    flipped[0] ^= 0x01
    return [
        ("unknown id", can.Message(arbitration_id=0x123, data=bytes(8), is_extended_id=False),
         "unknown frame id 0x123"),
        ("short", can.Message(arbitration_id=0x100, data=bytes(good.data[:7]),
                              is_extended_id=False), "must carry 8 bytes, got 7"),
        ("long", can.Message(arbitration_id=0x080, data=bytes([1, 0xFE, 0]),
                             is_extended_id=False), "must carry 2 bytes, got 3"),
        ("empty", can.Message(arbitration_id=0x701, data=b"", is_extended_id=False),
         "must carry 2 bytes, got 0"),
        ("garbage", can.Message(arbitration_id=0x101, data=bytes.fromhex("deadbeef0badf00d"),
                                is_extended_id=False), "reserved bits|checksum"),
        ("bit flip", can.Message(arbitration_id=0x100, data=bytes(flipped),
                                 is_extended_id=False), "checksum"),
        ("reserved bits", crafted(proto, "MM_Target_0", {"Axis0_Target": 0, "Axis1_Target": 0,
                                                         "Axis2_Target": 1000},
                                  reserved=1 << 52), "reserved bits"),
        ("status reserved bit", crafted(proto, "MM_Status_1", {}, reserved=1 << 7),
         "reserved bits"),
        ("beyond scaling", crafted(proto, "MM_Position_0", {"Axis0_Position": -32768}),
         "outside its range"),
        ("beyond joint limit", crafted(proto, "MM_Target_0", {"Axis0_Target": 9001,
                                                             "Axis2_Target": 1000}),
         "lf_root_joint.*limits"),
        ("below knee limit", crafted(proto, "MM_Target_0", {"Axis2_Target": 999}),
         "lf_knee_joint.*limits"),
        ("control complement", can.Message(arbitration_id=0x080, data=bytes([3, 0xFB]),
                                           is_extended_id=False), "complement"),
        ("control out of range", can.Message(arbitration_id=0x080, data=bytes([5, 0xFA]),
                                             is_extended_id=False), "outside its range"),
        ("all-zero control", can.Message(arbitration_id=0x080, data=bytes(2),
                                         is_extended_id=False), "complement"),
        ("state out of range", can.Message(arbitration_id=0x701, data=bytes([9, 0]),
                                           is_extended_id=False), "outside its range"),
        ("extended id", can.Message(arbitration_id=0x100, data=bytes(good.data),
                                    is_extended_id=True), "extended-id"),
        ("remote", can.Message(arbitration_id=0x100, is_remote_frame=True, dlc=8,
                               is_extended_id=False), "remote"),
        ("error frame", can.Message(arbitration_id=0x100, is_error_frame=True,
                                    is_extended_id=False), "error"),
        ("fd", can.Message(arbitration_id=0x100, data=bytes(good.data), is_fd=True,
                           is_extended_id=False), "CAN FD"),
    ]


def test_bad_frame_table_is_complete(proto):
    assert len(_bad_frames(proto)) == 19


@pytest.mark.parametrize("index", range(19))
def test_decode_refuses_bad_frames(proto, index):
    _name, msg, pattern = _bad_frames(proto)[index]
    with pytest.raises(ProtocolError, match=pattern):
        proto.decode(msg)


def test_target_limit_boundary_rows_decode(proto):
    assert proto.decode(crafted(proto, "MM_Target_0", {"Axis0_Target": 9000,
                                                      "Axis2_Target": 1000})).positions[
        "lf_root_joint"] == pytest.approx(0.9)
    assert proto.decode(crafted(proto, "MM_Target_0", {"Axis2_Target": 26000})).positions[
        "lf_knee_joint"] == pytest.approx(2.6)


# ---- bad axis maps and DBC files ------------------------------------------------------------


def _mutations():
    def drop(d):
        del d["axes"]["rf_knee_joint"]

    def extra(d):
        d["axes"]["tail_joint"] = {"axis": 3, "direction": 1, "zero_offset": 0.0,
                                   "gear_ratio": 1.0}

    def setter(joint, key, value):
        def apply(d):
            d["axes"][joint][key] = value
        return apply

    def unknown_key(d):
        d["axes"]["lf_root_joint"]["offset"] = 0.1

    def missing_key(d):
        del d["axes"]["lb_knee_joint"]["gear_ratio"]

    def no_section(d):
        d["joints"] = d.pop("axes")

    return [
        (drop, r"missing \['rf_knee_joint'\]"),
        (extra, r"unknown \['tail_joint'\]"),
        (setter("lb_root_joint", "axis", 0), "axis 0 is used by both lf_root_joint and "
                                             "lb_root_joint"),
        (setter("lf_root_joint", "axis", 12), r"lf_root_joint.axis must be an integer 0..11"),
        (setter("lf_root_joint", "axis", -1), r"integer 0..11, got -1"),
        (setter("lf_root_joint", "axis", "3"), r"integer 0..11, got '3'"),
        (setter("lf_root_joint", "axis", 2.0), r"integer 0..11, got 2.0"),
        (setter("rb_knee_joint", "direction", 0), r"rb_knee_joint.direction must be \+1 or -1"),
        (setter("rb_knee_joint", "direction", 2), r"\+1 or -1, got 2"),
        (setter("rb_knee_joint", "direction", True), r"\+1 or -1, got True"),
        (setter("lf_knee_joint", "gear_ratio", 0), r"gear_ratio must be a finite number > 0"),
        (setter("lf_knee_joint", "gear_ratio", -3.0), r"> 0, got -3.0"),
        (setter("lf_knee_joint", "zero_offset", float("nan")),
         r"zero_offset must be a finite angle in rad, got nan"),
        (setter("lf_knee_joint", "zero_offset", "0.1"),
         r"zero_offset must be a finite angle in rad, got '0.1'"),
        (setter("lf_knee_joint", "zero_offset", 1.0), r"lf_knee_joint limits .* beyond "
                                                      r"Axis2_Target's range"),
        (unknown_key, r"unknown \['offset'\]"),
        (missing_key, r"missing \['gear_ratio'\]"),
        (no_section, r"top-level 'axes:'"),
    ]


@pytest.mark.parametrize("index", range(18))
def test_bad_axis_maps_raise(robot, tmp_path, index):
    mutate, pattern = _mutations()[index]
    data = default_axes()
    mutate(data)
    with pytest.raises(ProtocolError, match=pattern):
        build(robot, write_axes(tmp_path, data))


def test_mutation_table_is_complete():
    assert len(_mutations()) == 18


def test_duplicate_yaml_key_raises(robot, tmp_path):
    text = config_path("axes.yaml").read_text(encoding="utf-8")
    line = next(x for x in text.splitlines() if "lb_root_joint" in x)
    path = tmp_path / "axes.yaml"
    path.write_text(text + line + "\n", encoding="utf-8")
    with pytest.raises(ProtocolError, match="duplicate key 'lb_root_joint'"):
        build(robot, path)


def test_missing_axes_file_raises(robot, tmp_path):
    with pytest.raises(ProtocolError, match="cannot read axis map"):
        build(robot, tmp_path / "nope.yaml")


@pytest.mark.parametrize(("old", "new", "pattern"), [
    ("MM_Heartbeat", "MM_Beat", "missing message MM_Heartbeat"),
    ("MM_Control", "MM_Ctrl", "missing message MM_Control"),
    ("MM_Status_1", "MM_Stat_1", "unexpected message MM_Stat_1"),
    ("Axis11_Target", "Axis12_Target", "MM_Target_<g> frames must carry each axis 0..11"),
    ("Axis4_Position", "Axis4_Pos", "unexpected signal Axis4_Pos"),
    ("Axis7_Stalled", "Axis7_Stuck", "unexpected signal Axis7_Stuck in MM_Status_1"),
    ("Axis7_Stalled", None, r"axis 7 lacks the flags \['Stalled'\]"),
    ("Axis5_Position", None, "MM_Position_<g> frames must carry each axis"),
    ("SG_ Checksum : 56|8@1+", "SG_ Checksum : 55|8@1+", "Checksum must be one unsigned"),
    ("0|16@1- (0.0001,0)", "0|16@0- (0.0001,0)", "little-endian|invalid"),
])
def test_bad_dbc_raises(robot, tmp_path, old, new, pattern):
    text = config_path("motor_manager.dbc").read_text(encoding="utf-8")
    assert old in text
    if new is None:  # drop the signal and its comment
        text = "\n".join(line for line in text.splitlines() if old not in line)
    else:
        text = text.replace(old, new)
    path = tmp_path / "mm.dbc"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ProtocolError, match=pattern):
        build(robot, config_path("axes.yaml"), path)


def test_regrouped_dbc_needs_no_code_change(robot, tmp_path):
    """Swapping two axes between frames in the DBC is picked up by name."""
    text = config_path("motor_manager.dbc").read_text(encoding="utf-8")
    text = (text.replace("Axis0_Target", "AxisX").replace("Axis3_Target", "Axis0_Target")
            .replace("AxisX", "Axis3_Target"))
    path = tmp_path / "mm.dbc"
    path.write_text(text, encoding="utf-8")
    proto = build(robot, config_path("axes.yaml"), path)
    q = mid_pose(proto)
    q[3] = 0.5
    msgs = proto.encode_targets(q, 0)
    assert int.from_bytes(msgs[0].data[0:2], "little", signed=True) == 5000
    assert proto.decode(msgs[0]).positions["lb_root_joint"] == pytest.approx(0.5)


def test_missing_dbc_raises(robot, tmp_path):
    with pytest.raises(ProtocolError, match="cannot read DBC file"):
        build(robot, config_path("axes.yaml"), tmp_path / "none.dbc")


def test_sender_of_each_family(proto):
    """Each side skips its own (looped-back) frames by id, without decoding them."""
    q = mid_pose(proto)
    rows = [(proto.encode_control("enable"), "controller"),
            (proto.encode_targets(q, 1)[0], "controller"),
            (proto.encode_feedback(proto.to_axis(q), 1)[0], "manager"),
            (can.Message(arbitration_id=0x7FF, is_extended_id=False), None),  # unknown id
            (can.Message(arbitration_id=0x100, is_extended_id=True), None),  # extended
            ("not a frame", None)]
    for msg, side in rows:
        assert proto.sender(msg) == side, msg


@pytest.mark.parametrize(("range_text", "enabled", "refused"), [
    ("[0|1]", False, False), ("[0|1]", True, False), ("[1|1]", True, False),
    ("[1|1]", False, True)])
def test_a_flag_narrower_than_its_bit_is_range_checked(robot, tmp_path, range_text, enabled,
                                                       refused):
    """Signals whose bits cannot leave their range skip the check; a narrower range keeps it:
    Axis0_Enabled = 0 is refused when the DBC allows [1|1] only."""
    text = config_path("motor_manager.dbc").read_text(encoding="utf-8")
    old = 'SG_ Axis0_Enabled : 0|1@1+ (1,0) [0|1] "" Controller'
    assert old in text
    path = tmp_path / "mm.dbc"
    path.write_text(text.replace(old, old.replace("[0|1]", range_text)), encoding="utf-8")
    shipped = MotorProtocol.from_config(robot)
    proto = build(robot, config_path("axes.yaml"), path)
    frame = shipped.encode_status([AxisFlags(enabled=enabled)] * 12, 1)[0]
    if refused:
        with pytest.raises(ProtocolError, match=r"Axis0_Enabled = 0 is outside its range"):
            proto.decode(frame)
    else:
        assert proto.decode(frame).axes[0].enabled is enabled
