"""The terrain_mapper process: the content's stamp in map_load_time, counters in /diagnostics."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from nav_msgs.msg import OccupancyGrid, Odometry  # noqa: E402
from rclpy.time import Time  # noqa: E402
from sensor_msgs.msg import PointCloud2, PointField  # noqa: E402

from crawler_motion.testing.stack import (  # noqa: E402
    StackProcesses,
    isolated_env,
    node_command,
    ros_args,
)


def cloud(stamp, frame: str = "scanner_link") -> PointCloud2:
    pts = np.array([[0.5, y, -0.1] for y in np.linspace(-0.2, 0.2, 9)], dtype=np.float32)
    msg = PointCloud2()
    msg.header.stamp, msg.header.frame_id = stamp, frame
    msg.height, msg.width = 1, len(pts)
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate("xyz")]
    msg.is_bigendian, msg.point_step, msg.row_step = sys.byteorder == "big", 12, 12 * len(pts)
    msg.data = pts.tobytes()
    return msg


def test_the_map_carries_its_last_fused_scan_and_the_counters(tmp_path: Path,
                                                             ros_domain: int) -> None:
    procs = StackProcesses(tmp_path)
    procs.start({"mapper": [*node_command("terrain_mapper"), *ros_args({})]},
                isolated_env(ros_domain))
    node = rclpy.create_node("mapper_probe")
    maps: list[OccupancyGrid] = []
    diags: dict[str, dict[str, str]] = {}
    node.create_subscription(OccupancyGrid, "terrain_map", maps.append, 10)
    node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: diags.update(
        {s.name: {kv.key: kv.value for kv in s.values} for s in m.status}), 10)
    odom_pub = node.create_publisher(Odometry, "odom", 20)
    scan_pub = node.create_publisher(PointCloud2, "scan", 10)

    def spin(seconds: float, scans: bool, future_odom: bool = False) -> Time:
        end, last = time.monotonic() + seconds, None
        while time.monotonic() < end:
            now = node.get_clock().now()
            odom = Odometry()
            odom.header.frame_id = "odom"
            odom.header.stamp = (now + rclpy.duration.Duration(seconds=3600.0)).to_msg() \
                if future_odom else now.to_msg()
            odom.pose.pose.orientation.w = 1.0
            odom_pub.publish(odom)
            if scans:
                scan_pub.publish(cloud(now.to_msg()))
                last = now
            rclpy.spin_once(node, timeout_sec=0.05)
        return last

    try:
        end = time.monotonic() + 20.0
        while not maps and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
        assert maps, procs.log_tails(20)
        assert maps[-1].info.map_load_time.sec == 0  # nothing fused yet
        spin(1.0, scans=False)
        last = spin(1.0, scans=True)
        spin(0.5, scans=False)
        load = Time.from_msg(maps[-1].info.map_load_time)
        # the last fused scan (its stamp went through float seconds: within 1 µs)
        assert -1000 <= (last - load).nanoseconds <= 0.3e9, (last, load)
        spin(0.5, scans=False, future_odom=True)  # refused, counted
        other = node.create_publisher(PointCloud2, "scan", 10)
        end = time.monotonic() + 10.0  # a sample published before the match would be lost
        while other.get_subscription_count() == 0 and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        other.publish(cloud(last.to_msg(), "other"))
        end = time.monotonic() + 3.0
        while time.monotonic() < end and diags.get("terrain_mapper: terrain map", {}).get(
                "skipped_MALFORMED", "0") == "0":
            rclpy.spin_once(node, timeout_sec=0.1)
        values = diags["terrain_mapper: terrain map"]
        assert int(values["scans_fused"]) >= 5 and int(values["odom_FUTURE"]) >= 5, values
        assert values["skipped_MALFORMED"] == "1" and "skipped_STALE" in values
    finally:
        node.destroy_node()
        procs.stop()
