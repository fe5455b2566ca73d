"""Recording files without a running stack: schemas, the sink, bad paths, damaged input."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from crawler_motion.errors import CrawlerMotionError, RecordingError
from crawler_motion.recording import recorder, report
from crawler_motion.recording.msgdefs import SEPARATOR, field_types, message_definition, split_type
from crawler_motion.recording.reader import read_recording
from crawler_motion.recording.sink import McapSink
from crawler_motion.recording.topics import STACK_TOPICS


@pytest.mark.parametrize(("name", "expected"), [
    ("sensor_msgs/msg/JointState", ("sensor_msgs", "JointState")),
    ("std_msgs/String", ("std_msgs", "String")),
    ("JointState", None), ("a/srv/B", None), ("/msg/B", None), ("a/msg/", None),
])
def test_type_names(name: str, expected: tuple[str, str] | None) -> None:
    if expected is None:
        with pytest.raises(CrawlerMotionError, match="pkg/msg/Type"):
            split_type(name)
    else:
        assert split_type(name) == expected


@pytest.mark.parametrize(("line", "used"), [
    ("Header header", [("std_msgs", "Header")]),
    ("geometry_msgs/Pose[] poses  # comment", [("geometry_msgs", "Pose")]),
    ("Point[<=3] p", [("pkg", "Point")]),
    ("string<=8 name", []), ("uint8 LEVEL=2", []), ("float64[36] covariance", []),
    ("# only a comment", []), ("", []),
])
def test_field_types_of_msg_lines(line: str, used: list[tuple[str, str]]) -> None:
    assert field_types(line, "pkg") == used


@pytest.mark.parametrize("type_name", sorted(set(STACK_TOPICS.values())))
def test_every_stack_type_has_a_schema_mcap_ros2_parses(type_name: str) -> None:
    from mcap_ros2._dynamic import generate_dynamic

    text = message_definition(type_name)
    assert generate_dynamic(type_name, text)
    assert text.count(SEPARATOR) == len(set(
        line for line in text.splitlines() if line.startswith("MSG: ")))


def _string_cdr(text: str) -> bytes:
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    return serialize_message(String(data=text))


def test_the_sink_writes_what_mcap_reads_back(tmp_path: Path) -> None:
    sink = McapSink(tmp_path / "a.mcap")
    for i in range(5):
        sink.write("/planner_status", "std_msgs/msg/String", _string_cdr(f"m{i}"), 1000 + i)
    sink.close()
    sink.close()  # idempotent
    with open(tmp_path / "a.mcap", "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        got = [(m.log_time, d.data) for _, _, m, d in reader.iter_decoded_messages()]
    assert got == [(1000 + i, f"m{i}") for i in range(5)]


@pytest.mark.parametrize("where", ["missing/dir/run.mcap", "."])
def test_an_unwritable_recording_path_is_one_line_and_exit_1(where: str, tmp_path: Path,
                                                            capsys: Any) -> None:
    path = tmp_path / where
    with pytest.raises(RecordingError):
        McapSink(path)
    assert recorder.main(["-o", str(path)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and str(path) in err[0]


def test_a_bad_can_log_leaves_no_recording_behind(tmp_path: Path, capsys: Any) -> None:
    assert recorder.main(["-o", str(tmp_path / "r.mcap"), "--can-log",
                          str(tmp_path / "bus.txt")]) == 1
    assert "suffix" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("content", [b"", b"not an mcap file at all" * 10, b"\x89MCAP0\r\n"])
def test_a_file_without_messages_is_one_line_naming_it(content: bytes, tmp_path: Path,
                                                       capsys: Any) -> None:
    path = tmp_path / "bad.mcap"
    path.write_bytes(content)
    with pytest.raises(RecordingError, match=r"bad\.mcap"):
        read_recording(path)
    assert report.main([str(path), "-o", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "bad.mcap" in err[0]


def test_a_missing_recording_is_one_line(tmp_path: Path, capsys: Any) -> None:
    assert report.main([str(tmp_path / "none.mcap")]) == 1
    assert "none.mcap" in capsys.readouterr().err


def test_a_recording_without_a_stack_gives_a_report_of_what_is_there(tmp_path: Path) -> None:
    sink = McapSink(tmp_path / "s.mcap")
    sink.write("/planner_status", "std_msgs/msg/String", _string_cdr('{"state": "IDLE"}'), 10)
    sink.write("/planner_status", "std_msgs/msg/String", _string_cdr('{"state": "WALKING"}'),
               2_000_000_010)
    sink.close()
    assert report.main([str(tmp_path / "s.mcap"), "-o", str(tmp_path / "r")]) == 0
    page = (tmp_path / "r" / "index.html").read_text()
    assert 'src="states.png"' in page and "WALKING" in page and "not recorded" in page
    assert not (tmp_path / "r" / "joints.png").exists()


def test_a_full_disk_stops_the_recording_with_a_clear_error() -> None:
    if not Path("/dev/full").exists():
        pytest.skip("needs /dev/full")
    sink = McapSink("/dev/full", chunk_size=64)
    with pytest.raises(RecordingError, match="recording stopped") as caught:
        for i in range(10_000):
            sink.write("/s", "std_msgs/msg/String", _string_cdr("x" * 100), i)
    assert caught.value.path == Path("/dev/full") and sink.closed
    sink.close()  # nothing more to do, no second error


def test_a_recording_cut_anywhere_is_read_or_refused_never_a_traceback(tmp_path: Path) -> None:
    sink = McapSink(tmp_path / "whole.mcap", chunk_size=200)
    for i in range(40):
        sink.write("/planner_status", "std_msgs/msg/String", _string_cdr(f"m{i}"), 10 + i)
    sink.close()
    data = (tmp_path / "whole.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    for end in range(0, len(data), 7):  # every 7th byte: inside records, headers, lengths
        cut.write_bytes(data[:end])
        try:
            rec = read_recording(cut)
        except RecordingError as exc:
            assert "cut.mcap" in str(exc)
        else:
            assert rec.damage is not None and 0 < rec.count <= 40, end
