"""The ``terrain_mapper`` ROS node: ``scan`` + ``odom`` in, the elevation map out.

Subscribes ``scan`` (sensor_msgs/PointCloud2 in the scanner frame, float32 x y z) and ``odom``
(nav_msgs/Odometry); publishes at ``publish_rate`` ``terrain_map`` (nav_msgs/OccupancyGrid in
the map frame: 100 obstacle, 0 free, -1 unknown) and ``terrain_heights``
(sensor_msgs/PointCloud2 in the map frame: one point per known cell centre, fields x y z
variance float32, z the fused height [m], variance [m²]). A scan newer than the latest odometry
is held until the odometry reaches its stamp (`mapper` has the rule). A skipped scan (when it
arrives, or a held one later) is counted by reason and logged (at most once a second per
reason). ``terrain_map``'s ``info.map_load_time`` is the stamp of the last scan fused (zero
before the first and after an odometry restart): the age of the map's content, which the
navigator checks (``map_max_age``); the header stamp is the publication time. Once a second
``/diagnostics`` gets the status ``terrain_mapper: terrain map`` (hardware_id
``crawler_mapper``): scans fused, skips by reason (``skipped_<REASON>``), odometry refusals
by verdict (``odom_<VERDICT>``), the content's age; WARN when no scan was fused in the last
period while scans were skipped. All the work is in `mapper.TerrainMapper`; ``odom`` is taken
by a thread of its own (`runtime.ros_reader.SubscriptionReader`), the rest by the executor,
under one lock.
"""

from __future__ import annotations

import sys
import threading
from collections import Counter
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import OccupancyGrid, Odometry
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2, PointField

from crawler_motion.mapping.clouds import read_float32
from crawler_motion.mapping.mapper import Pose, SkipReason, TerrainMapper
from crawler_motion.mapping.odometry import OdometryVerdict
from crawler_motion.mapping.odometry_pose import odometry_pose, stamp_seconds
from crawler_motion.mapping.parameters import mapper_parameters, mapper_settings
from crawler_motion.mapping.points import Mount
from crawler_motion.model.config import load_config, load_scanner
from crawler_motion.runtime.callback_guard import CallbackGuard
from crawler_motion.runtime.log import Throttle
from crawler_motion.runtime.ros_diagnostics import counters_array
from crawler_motion.runtime.ros_main import run_node
from crawler_motion.runtime.ros_parameters import descriptor
from crawler_motion.runtime.ros_reader import SubscriptionReader

NAME = "terrain_mapper"
#: A skip or refusal reason is logged at most once per this period [s] (each reason apart).
LOG_PERIOD = 1.0
FIELDS = ("x", "y", "z", "variance")
#: Period of the ``/diagnostics`` status [s].
DIAGNOSTICS_PERIOD = 1.0
HARDWARE_ID = "crawler_mapper"


def read_xyz(msg: PointCloud2) -> np.ndarray | None:
    """The x y z float32 fields of a cloud as ``(k, 3)`` float64; None if it has none or they
    do not fit the cloud (`clouds.read_float32`)."""
    return read_float32(msg, ("x", "y", "z"))


class TerrainMapperNode(Node):
    """Subscriptions, timer and publishers around a `TerrainMapper`."""

    def __init__(self) -> None:
        super().__init__(NAME)
        specs = mapper_parameters(load_config())
        for spec in specs:
            self.declare_parameter(spec.name, spec.default, descriptor(spec))
        values = {s.name: self.get_parameter(s.name).value for s in specs}
        cfg_file = values["config_file"] or None
        scanner = load_scanner(cfg_file)
        if cfg_file is not None:  # the threshold default of that robot
            specs = mapper_parameters(load_config(cfg_file))
        self.mapper = TerrainMapper(mapper_settings(specs, values),
                                    Mount.from_config(scanner))
        self.frame, self.scanner_frame = values["map_frame"], values["scanner_frame"]
        self._map = self.create_publisher(OccupancyGrid, "terrain_map", 2)
        self._heights = self.create_publisher(PointCloud2, "terrain_heights", 2)
        self.guard = CallbackGuard(self.get_logger(), alive=self.context.ok)
        self.create_subscription(PointCloud2, "scan", self.guard.wrap("scan", self._on_scan),
                                 qos_profile_sensor_data)
        # odom (50 Hz in the simulator) by a thread of its own: through the executor each
        # sample cost a wake-up and a wait-set rebuild; ``_lock`` guards the mapper
        self._lock = threading.Lock()
        self._odom = SubscriptionReader(self, Odometry, "odom", 20,
                                        self.guard.wrap("odom", lambda m, _: self._on_odom(m)),
                                        on_error=self.get_logger().error, name="mapper-odom")
        self._odom.start()
        self._throttle = Throttle(LOG_PERIOD)  # warnings by reason
        self.create_timer(1.0 / values["publish_rate"], self._publish)
        self._diagnostics = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._counted = (0, 0)  # scans fused and skipped at the last diagnostics
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        self.get_logger().info(f"{NAME}: {self.mapper.settings.cells}² cells of "
                               f"{self.mapper.settings.resolution:g} m in {self.frame}")

    def _skip(self, reason: SkipReason) -> None:
        if self._throttle.allow(reason):  # once a second per reason, not per call site
            self.get_logger().warning(
                f"scan skipped: {reason.value} ({self.mapper.skipped[reason]} so far)")

    def destroy_node(self) -> None:
        """Stop the odometry reader, then the node."""
        self._odom.close()
        super().destroy_node()

    def _on_odom(self, msg: Odometry) -> None:
        pose = odometry_pose(msg)
        now = self.get_clock().now().nanoseconds * 1e-9
        with self._lock:
            self._take_odometry(pose, now)

    def _take_odometry(self, pose: Pose, now: float) -> None:
        before = Counter(self.mapper.skipped)
        verdict = self.mapper.add_odometry(pose, now)
        if verdict is OdometryVerdict.RESET:
            self.get_logger().error(f"odom: {verdict.value}")
        elif verdict is not None and self._throttle.allow(verdict):
            self.get_logger().warning(
                f"odom skipped: {verdict.value} "
                f"({self.mapper.odometry_refused[verdict]} so far)")
        else:  # held scans it released and could not fuse
            self._report(before)

    def _on_scan(self, msg: PointCloud2) -> None:
        points = read_xyz(msg)
        with self._lock:
            if msg.header.frame_id != self.scanner_frame or points is None:
                self.mapper.skipped[SkipReason.MALFORMED] += 1
                self._skip(SkipReason.MALFORMED)
                return
            before = Counter(self.mapper.skipped)
            self.mapper.add_scan(points, stamp_seconds(msg.header.stamp))
            self._report(before)

    def _report(self, before: Counter[SkipReason]) -> None:
        """Log every reason counted since ``before``."""
        for reason, count in self.mapper.skipped.items():
            if count > before[reason]:
                self._skip(reason)

    def _publish_diagnostics(self) -> None:
        with self._lock:
            array = self._diagnose()
        self._diagnostics.publish(array)  # outside the lock: a publish may wait on discovery

    def _diagnose(self) -> DiagnosticArray:
        m = self.mapper
        counted = (m.scans_fused, sum(m.skipped.values()))
        starved = counted[0] == self._counted[0] and counted[1] > self._counted[1]
        self._counted = counted
        now = self.get_clock().now().nanoseconds * 1e-9
        age = "none" if m.last_fused_stamp is None else f"{now - m.last_fused_stamp:.3f}"
        values = {"scans_fused": m.scans_fused, "scans_held": m.held, "map_age": age,
                  "callback_errors": self.guard.total,
                  **{f"skipped_{r.name}": m.skipped[r] for r in SkipReason},
                  **{f"odom_{v.name}": m.odometry_refused[v] for v in OdometryVerdict
                     if v is not OdometryVerdict.ACCEPT}}
        message = "scans skipped, none fused in the last period" if starved else "ok"
        return counters_array(self, "terrain map", HARDWARE_ID, "warn" if starved else "ok",
                              message, values)

    def _publish(self) -> None:
        with self._lock:
            grid, heights = self._map_messages()
        self._map.publish(grid)  # outside the lock: a publish may wait on discovery
        self._heights.publish(heights)

    def _map_messages(self) -> tuple[OccupancyGrid, PointCloud2]:
        """``terrain_map`` and ``terrain_heights`` of the map now (the lock held)."""
        stamp = self.get_clock().now().to_msg()
        g = self.mapper.grid
        grid = OccupancyGrid()
        grid.header.stamp, grid.header.frame_id = stamp, self.frame
        fused = self.mapper.last_fused_stamp
        if fused is not None:
            sec = int(fused // 1)
            grid.info.map_load_time = Time(sec=sec, nanosec=min(round((fused - sec) * 1e9),
                                                                 999_999_999))
        grid.info.resolution = float(g.resolution)
        grid.info.width = grid.info.height = g.cells
        grid.info.origin.position.x, grid.info.origin.position.y = (float(v) for v in g.origin)
        grid.info.origin.orientation.w = 1.0
        grid.data = self.mapper.occupancy().ravel().tolist()
        xs, ys = g.centres()
        known = g.known
        cloud = np.column_stack((xs[known], ys[known], g.height[known], g.variance[known]))
        msg = PointCloud2()
        msg.header.stamp, msg.header.frame_id = stamp, self.frame
        msg.height, msg.width = 1, len(cloud)
        msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                      for i, n in enumerate(FIELDS)]
        msg.is_bigendian, msg.is_dense = sys.byteorder == "big", True
        msg.point_step, msg.row_step = 16, 16 * len(cloud)
        msg.data = np.ascontiguousarray(cloud, dtype=np.float32).tobytes()
        return grid, msg


def main(args: Sequence[str] | None = None) -> None:
    """Console script ``terrain_mapper``: run until Ctrl-C; a bad parameter prints one line and
    exits 1."""
    run_node(TerrainMapperNode, f"{NAME}: error", args)


if __name__ == "__main__":
    main()
