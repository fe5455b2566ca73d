"""Effort frames of the motor-manager protocol: layout, round trip, refusals, a DBC without
them, the bus load they add."""

from __future__ import annotations

import math
import re

import can
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crawler_motion.canbus.busload import frame_bits_worst_case, load_percent
from crawler_motion.canbus.crc import crc8_sae_j1850
from crawler_motion.canbus.protocol import EffortFeedback, MotorProtocol
from crawler_motion.errors import ProtocolError
from crawler_motion.model.config import config_path, joint_names

JOINTS = joint_names()
RES = 0.001  # N m per bit
EFFORT_IDS = [0x170, 0x171, 0x172, 0x173]
#: The documented bus load at a 100 Hz command rate, 1 Mbit/s (docs/protocol.md) [%].
LOAD_100HZ = 18.975
#: ... and before the effort frames [%].
LOAD_100HZ_WITHOUT_EFFORT = 13.575


def raw_slot(msgs: list[can.Message], axis: int) -> int:
    data = msgs[axis // 3].data
    return int.from_bytes(data[2 * (axis % 3):2 * (axis % 3) + 2], "little", signed=True)


def crafted(proto: MotorProtocol, name: str, raw: dict, *, counter: int = 0) -> can.Message:
    """An effort frame of raw signal values, range unchecked, with a valid checksum."""
    message = proto.database.get_message_by_name(name)
    signals = {s.name: 0 for s in message.signals}
    signals.update(raw, Counter=counter)
    data = bytearray(message.encode(signals, scaling=False, strict=False))
    data[7] = crc8_sae_j1850(message.frame_id.to_bytes(2, "little") + bytes(data[:7]))
    return can.Message(arbitration_id=message.frame_id, data=bytes(data), is_extended_id=False)


def decode_all(proto: MotorProtocol, msgs: list[can.Message]) -> dict[str, float]:
    efforts: dict[str, float] = {}
    for msg in msgs:
        frame = proto.decode(msg)
        assert isinstance(frame, EffortFeedback)
        efforts.update(frame.efforts)
    return efforts


def without_effort_frames(text: str) -> str:
    """The DBC text with every MM_Effort_<g> message, comment and attribute removed."""
    ids = {str(fid) for fid in (368, 369, 370, 371)}
    out, skipping = [], False
    for line in text.splitlines():
        if line.startswith("BO_ ") and "MM_Effort_" in line:
            skipping = True
        if skipping:
            skipping = bool(line.strip())
            continue
        words = line.split()
        if line.startswith(("CM_ SG_", "CM_ BO_")) and words[2] in ids:
            continue
        if line.startswith('BA_ "GenMsgCycleTime" BO_') and words[3] in ids:
            continue
        out.append(line)
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def old_proto(robot, tmp_path_factory):
    """The protocol of a manager without effort frames."""
    path = tmp_path_factory.mktemp("dbc") / "old.dbc"
    text = config_path("motor_manager.dbc").read_text(encoding="utf-8")
    path.write_text(without_effort_frames(text), encoding="utf-8")
    return MotorProtocol.from_config(robot, dbc_path=path)


def test_layout(proto):
    db = proto.database
    for g, fid in enumerate(EFFORT_IDS):
        message = db.get_message_by_frame_id(fid)
        assert message.name == f"MM_Effort_{g}" and message.length == 8
        assert message.senders == ["MotorManager"] and message.cycle_time == 10
        for k in range(3):
            signal = message.get_signal_by_name(f"Axis{3 * g + k}_Effort")
            assert (signal.start, signal.length, signal.is_signed) == (16 * k, 16, True)
            assert (signal.scale, signal.minimum, signal.maximum) == (RES, -32.767, 32.767)
            assert signal.unit == "Nm" and signal.comment
        assert message.get_signal_by_name("Counter").start == 48
        assert message.get_signal_by_name("Checksum").start == 56
    assert max(EFFORT_IDS) < min(proto.frame_ids("position"))  # sent before the positions
    assert sorted(proto.frame_ids("effort")) == EFFORT_IDS
    assert proto.has_effort and proto.period("effort") == pytest.approx(0.01)
    assert proto.sender(can.Message(arbitration_id=0x170, is_extended_id=False)) == "manager"


@pytest.mark.parametrize(("joint", "torque", "raw"), [
    ("lf_root_joint", 0.0, 0),
    ("lf_root_joint", RES, 1),
    ("lf_root_joint", -RES, -1),
    ("lf_root_joint", 0.0004, 0),  # rounds to nearest
    ("lf_root_joint", 0.0006, 1),
    ("lf_shoulder_joint", 4.0, 4000),  # the effort limit
    ("lf_knee_joint", 32.767, 32767),  # the DBC range
    ("lf_knee_joint", -32.767, -32767),
    ("rb_shoulder_joint", 1.5, -1500),  # direction -1: the axis turns the other way
    ("rf_knee_joint", -0.25, 250),
    ("rf_root_joint", -0.25, -250),  # direction +1 on a right leg's root
])
def test_effort_encoding_table(proto, joint, torque, raw):
    tau = np.zeros(12)
    i = JOINTS.index(joint)
    tau[i] = torque
    msgs = proto.encode_efforts(proto.effort_to_axis(tau), 3)
    assert [m.arbitration_id for m in msgs] == EFFORT_IDS
    assert raw_slot(msgs, proto.axis_map[i].axis) == raw
    decoded = decode_all(proto, msgs)
    assert decoded[joint] == pytest.approx(raw * RES * proto.axis_map[i].direction, abs=1e-12)
    assert all(proto.decode(m).counter == 3 for m in msgs)


def test_a_zero_offset_does_not_shift_an_effort(robot, tmp_path):
    text = config_path("axes.yaml").read_text(encoding="utf-8")
    path = tmp_path / "axes.yaml"
    path.write_text(re.sub(r"(lf_knee_joint: +\{.*zero_offset: )0\.0", r"\g<1>0.6", text),
                    encoding="utf-8")
    proto = MotorProtocol.from_config(robot, axes_path=path)
    assert proto.axis_map[2].zero_offset == 0.6
    tau = np.zeros(12)
    tau[2] = 1.0
    np.testing.assert_allclose(proto.effort_to_axis(tau), tau)
    np.testing.assert_allclose(proto.effort_to_joint(proto.effort_to_axis(tau)), tau)


@pytest.mark.parametrize(("torque", "pattern"), [
    (32.768, "beyond Axis1_Effort's range"),
    (-40.0, "beyond Axis1_Effort's range"),
    (math.nan, "not finite"),
    (math.inf, "not finite"),
])
def test_effort_encoding_refuses_never_clips(proto, torque, pattern):
    axes = np.zeros(12)
    axes[1] = torque
    with pytest.raises(ProtocolError, match=f"lf_shoulder_joint.*{pattern}"):
        proto.encode_efforts(axes, 0)


def test_effort_vector_of_wrong_size_raises(proto):
    with pytest.raises(ProtocolError, match=r"12 values \[N m\]"):
        proto.encode_efforts(np.zeros(11), 0)


@settings(max_examples=100, deadline=None)
@given(tau=st.lists(st.floats(-32.767, 32.767), min_size=12, max_size=12),
       counter=st.integers(0, 2**20))
def test_round_trip_within_resolution(proto, tau, counter):
    msgs = proto.encode_efforts(proto.effort_to_axis(tau), counter)
    assert {proto.decode(m).counter for m in msgs} == {counter % 16}
    decoded = decode_all(proto, msgs)
    got = np.array([decoded[j] for j in JOINTS])
    assert np.max(np.abs(got - np.array(tau))) <= RES / 2 + 1e-9


def test_bad_effort_frames_are_refused(proto):
    good = proto.encode_efforts(np.zeros(12), 0)[1]
    flipped = bytearray(good.data)
    flipped[2] ^= 0x10
    reserved = bytearray(good.data)
    reserved[6] |= 0x20  # bit 53, reserved
    rows = [
        (crafted(proto, "MM_Effort_0", {"Axis1_Effort": -32768}), "outside its range"),
        (crafted(proto, "MM_Effort_3", {"Axis11_Effort": -32768}), "outside its range"),
        (can.Message(arbitration_id=0x171, data=bytes(flipped), is_extended_id=False),
         "checksum"),
        (can.Message(arbitration_id=0x171, data=bytes(reserved), is_extended_id=False),
         "reserved bits"),
        (can.Message(arbitration_id=0x171, data=bytes(good.data[:6]), is_extended_id=False),
         "must carry 8 bytes"),
    ]
    for msg, pattern in rows:
        with pytest.raises(ProtocolError, match=pattern):
            proto.decode(msg)
    edge = proto.decode(crafted(proto, "MM_Effort_0", {"Axis1_Effort": -32767}))
    assert edge.efforts["lf_shoulder_joint"] == pytest.approx(-32.767)


def test_a_dbc_without_effort_frames_still_works(old_proto):
    assert not old_proto.has_effort and old_proto.frame_ids("effort") == ()
    assert old_proto.encode_efforts(np.zeros(12), 0) == []
    assert old_proto.period("effort") is None
    assert old_proto.cycle_period("effort") == pytest.approx(0.01)
    assert "effort" not in old_proto.cycle_bits()


def test_a_partial_effort_family_is_refused(robot, tmp_path):
    text = config_path("motor_manager.dbc").read_text(encoding="utf-8")
    text = text.replace("Axis5_Effort", "Axis12_Effort")
    path = tmp_path / "bad.dbc"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ProtocolError, match=r"MM_Effort_<g>.*\(or none at all\)"):
        MotorProtocol.from_config(robot, dbc_path=path)


def test_bus_load_with_effort_frames(proto, old_proto):
    bits = proto.cycle_bits()
    assert bits["effort"] == 4 * frame_bits_worst_case(8) == 540
    assert proto.bus_load(100.0) == pytest.approx(LOAD_100HZ)
    assert proto.bus_load(100.0) <= 25.0
    assert old_proto.bus_load(100.0) == pytest.approx(LOAD_100HZ_WITHOUT_EFFORT)
    assert proto.bus_load(200.0) == pytest.approx(LOAD_100HZ + 5.4)  # 540 bits at +100 Hz
    assert proto.bus_load(100.0, bitrate=500_000) == pytest.approx(2 * LOAD_100HZ)


@pytest.mark.parametrize(("bits", "rates", "load"), [
    ({}, {}, 0.0),
    ({"target": 540}, {"target": 100.0}, 5.4),
    ({"target": 540, "control": 75}, {"target": 100.0}, 5.4),  # sporadic: not counted
    ({"heartbeat": 75}, {"heartbeat": 10.0}, 0.075),
])
def test_load_percent_rows(bits, rates, load):
    assert load_percent(bits, rates) == pytest.approx(load)


def test_load_percent_needs_a_bitrate():
    with pytest.raises(ProtocolError, match="bitrate"):
        load_percent({"target": 540}, {"target": 100.0}, 0.0)
