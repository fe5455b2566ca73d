"""Messages the recorder could not keep up with, counted from the publishers' numbers."""

from __future__ import annotations

from pathlib import Path

import pytest

from crawler_motion.recording.gaps import SequenceGaps


def test_numbers_skipped_within_a_stream_are_dropped_messages() -> None:
    gaps = SequenceGaps()
    assert [gaps.note("/imu", s) for s in (1, 2, 3, 7, 8)] == [0, 0, 0, 3, 0]
    # a second publisher interleaved: its own stream, nothing dropped
    assert [gaps.note("/imu", s) for s in (1, 9, 2, 10, 3)] == [0, 0, 0, 0, 0]
    assert gaps.note("/odom", 5) == 0 and gaps.note("/odom", None) == 0
    assert gaps.dropped["/imu"] == 3 and gaps.dropped["/odom"] == 0 and gaps.total == 3


def test_the_recorder_counts_what_a_flood_made_it_drop(tmp_path: Path, ros_domain: int) -> None:
    rclpy = pytest.importorskip("rclpy")
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Imu

    from crawler_motion.recording.recorder import RecorderNode, progress
    from crawler_motion.recording.sink import McapSink

    sink = McapSink(tmp_path / "flood.mcap")
    recorder = RecorderNode(sink, ["imu"])
    source = rclpy.create_node("flooder")
    pub = source.create_publisher(Imu, "imu", qos_profile_sensor_data)
    try:
        for _ in range(50):  # matched
            rclpy.spin_once(recorder, timeout_sec=0.05)
            if pub.get_subscription_count():
                break
        pub.publish(Imu())
        rclpy.spin_once(recorder, timeout_sec=0.5)  # the first message: a stream starts
        for _ in range(2000):  # far more than the queue holds while nobody takes
            pub.publish(Imu())
        for _ in range(40):
            rclpy.spin_once(recorder, timeout_sec=0.05)
        pub.publish(Imu())  # the last: the gap before it is known
        for _ in range(20):
            rclpy.spin_once(recorder, timeout_sec=0.05)
        kept, dropped = sink.counts["/imu"], recorder.gaps.dropped["/imu"]
        # best effort: the tail may be lost in transit too, uncounted until a later message
        assert dropped >= 1000 and kept + dropped <= 2002
        assert f"{dropped} dropped" in progress(sink, 1.0, None, recorder.gaps)
    finally:
        source.destroy_node()
        recorder.destroy_node()
        sink.close()
