"""Tests of the protocol's exception tree: each error carries what was wrong as attributes."""

from __future__ import annotations

from pathlib import Path

import can
import numpy as np
import pytest
import yaml

from crawler_motion.canbus.axes import parse_axis_map
from crawler_motion.canbus.crc import frame_checksum
from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.errors import (
    CrawlerMotionError,
    FrameError,
    ProtocolDecodeError,
    ProtocolEncodeError,
    ProtocolError,
    ProtocolParseError,
)
from crawler_motion.model.config import config_path


def test_tree():
    for cls in (ProtocolParseError, ProtocolEncodeError, ProtocolDecodeError):
        assert issubclass(cls, ProtocolError) and issubclass(cls, ValueError)
        assert issubclass(cls, CrawlerMotionError)
    assert issubclass(ProtocolEncodeError, FrameError)
    assert issubclass(ProtocolDecodeError, FrameError)
    assert not issubclass(ProtocolParseError, FrameError)
    err = ProtocolDecodeError("bad", frame_id=0x100)
    assert str(err) == "bad" and (err.signal, err.joint, err.value) == (None, None, None)


def test_parse_error_of_a_duplicate_key(robot, tmp_path):
    text = config_path("axes.yaml").read_text(encoding="utf-8")
    line = next(x for x in text.splitlines() if "lb_root_joint" in x)
    path = tmp_path / "axes.yaml"
    path.write_text(text + line + "\n", encoding="utf-8")
    with pytest.raises(ProtocolParseError, match="duplicate key 'lb_root_joint'") as err:
        MotorProtocol.from_config(robot, axes_path=path)
    assert err.value.path == path and err.value.key == "lb_root_joint"
    assert err.value.line == len(text.splitlines()) + 1


def test_parse_error_of_a_bad_field(robot, tmp_path):
    data = yaml.safe_load(config_path("axes.yaml").read_text(encoding="utf-8"))
    data["axes"]["lf_knee_joint"]["direction"] = 2
    path = tmp_path / "axes.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ProtocolParseError, match=r"direction must be \+1 or -1, got 2") as err:
        MotorProtocol.from_config(robot, axes_path=path)
    assert err.value.path == path
    assert err.value.key == f"{path}: axes.lf_knee_joint.direction"
    with pytest.raises(ProtocolParseError) as err:
        parse_axis_map({"a": {"axis": 0, "direction": 1, "zero_offset": 0.0, "gear_ratio": 1},
                        "b": {"axis": 0, "direction": 1, "zero_offset": 0.0, "gear_ratio": 1}},
                       ["a", "b"])
    assert err.value.path is None and err.value.key == "axes.b.axis"


def test_parse_error_of_the_dbc(robot, tmp_path):
    missing = tmp_path / "none.dbc"
    with pytest.raises(ProtocolParseError, match="cannot read DBC file") as err:
        MotorProtocol.from_config(robot, dbc_path=missing)
    assert err.value.path == missing
    text = config_path("motor_manager.dbc").read_text(encoding="utf-8")
    bad = tmp_path / "mm.dbc"
    bad.write_text(text.replace("MM_Heartbeat", "MM_Beat"), encoding="utf-8")
    with pytest.raises(ProtocolParseError, match="missing message MM_Heartbeat") as err:
        MotorProtocol.from_config(robot, dbc_path=bad)
    assert err.value.path == Path(bad)


def test_encode_errors(proto):
    q = 0.5 * (proto.lower + proto.upper)
    q[4] = proto.upper[4] + 0.5
    with pytest.raises(ProtocolEncodeError, match="outside its limits") as err:
        proto.encode_targets(q, 0)
    assert err.value.joint == proto.joint_names[4]
    assert err.value.value == pytest.approx(proto.upper[4] + 0.5)
    q[4] = np.nan
    with pytest.raises(ProtocolEncodeError, match="finite angle") as err:
        proto.encode_targets(q, 0)
    assert err.value.joint == proto.joint_names[4] and np.isnan(err.value.value)
    with pytest.raises(ProtocolEncodeError, match="unknown command 'halt'") as err:
        proto.encode_control("halt")
    assert (err.value.frame_id, err.value.signal, err.value.value) == (
        proto.frame_ids("control")[0], "Command", "halt")
    with pytest.raises(ProtocolEncodeError, match="counter must be >= 0") as err:
        proto.encode_heartbeat("enabled", -1)
    assert (err.value.signal, err.value.value) == ("Counter", -1)
    with pytest.raises(ProtocolEncodeError, match="12 values"):
        proto.encode_targets([0.0] * 11, 0)


def test_encode_error_beyond_the_dbc_range(robot, tmp_path):
    data = yaml.safe_load(config_path("axes.yaml").read_text(encoding="utf-8"))
    data["axes"]["lf_knee_joint"]["zero_offset"] = 0.6  # limits map to [0.7, 3.2] rad: fits
    path = tmp_path / "axes.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    proto = MotorProtocol.from_config(robot, axes_path=path)
    axes = proto.to_axis(0.5 * (proto.lower + proto.upper))
    axes[2] = 3.3  # joint 2.7: within the feedback margin, beyond the int16 scaling
    with pytest.raises(ProtocolEncodeError, match="beyond Axis2_Position") as err:
        proto.encode_feedback(axes, 0)
    assert err.value.signal == "Axis2_Position" and err.value.value == pytest.approx(3.3)
    assert err.value.frame_id in proto.frame_ids("position")


def test_decode_errors(proto):
    good = proto.encode_targets(0.5 * (proto.lower + proto.upper), 0)[0]
    with pytest.raises(ProtocolDecodeError, match="unknown frame id 0x7FF") as err:
        proto.decode(can.Message(arbitration_id=0x7FF, data=good.data, is_extended_id=False))
    assert err.value.frame_id == 0x7FF and err.value.signal is None
    data = bytearray(good.data)
    data[7] ^= 0xFF
    with pytest.raises(ProtocolDecodeError, match="checksum") as err:
        proto.decode(can.Message(arbitration_id=good.arbitration_id, data=bytes(data),
                                 is_extended_id=False))
    assert (err.value.frame_id, err.value.signal, err.value.value) == (
        good.arbitration_id, "Checksum", data[7])
    with pytest.raises(ProtocolDecodeError, match="complement") as err:
        control = proto.encode_control("enable")
        raw = bytearray(control.data)
        raw[1] ^= 0x01
        proto.decode(can.Message(arbitration_id=control.arbitration_id, data=bytes(raw),
                                 is_extended_id=False))
    assert err.value.signal == "CommandInv"


def test_decode_error_of_a_position_beyond_the_limits(proto):
    message = proto.database.get_message_by_name("MM_Position_0")
    values = {s.name: 0 for s in message.signals}
    mapping = next(m for m in proto.axis_map if m.axis == 2)
    i = proto.joint_names.index(mapping.joint)
    joint = proto.lower[i] - proto.feedback_margin - 0.1  # 0.1 rad beyond the margin
    values["Axis2_Position"] = mapping.to_axis(joint)
    data = bytearray(message.encode(values, scaling=True, strict=False))
    data[7] = frame_checksum(message.frame_id, data, 7)
    with pytest.raises(ProtocolDecodeError, match="outside its limits") as err:
        proto.decode(can.Message(arbitration_id=message.frame_id, data=bytes(data),
                                 is_extended_id=False))
    assert (err.value.frame_id, err.value.signal, err.value.joint) == (
        message.frame_id, "Axis2_Position", mapping.joint)
    assert err.value.value == pytest.approx(joint, abs=1e-4)
