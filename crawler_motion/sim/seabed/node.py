"""The ``seabed_sim`` ROS node: the simulated motor manager on CAN, moved by seabed physics.

It speaks the protocol of ``motor_manager_sim`` (the same `MotorManagerSim`, whose axes are
moved by a `SeabedPlant`; its effort frames carry the servo torques averaged over each feedback
period) on the bus of ``can_interface`` / ``can_channel`` / ``can_port`` and publishes the
body's truth and sensors: ``imu`` (sensor_msgs/Imu, base_link) once per physics state (the
manager's step: 100 Hz with the DBC's feedback cycle; none while the physics stands still or
failed), ``odom`` (nav_msgs/Odometry, odom -> base_link) with every second of them (50 Hz),
``scan`` (sensor_msgs/PointCloud2, scanner_link, x y z float32, at the scanner's rate) and
``/diagnostics`` (ERROR with the reason once the physics went unstable; the manager then
holds). The physics runs in the manager's thread, lock-stepped to the steady clock. Servos hold
where the manager last held them while it is disabled, holds or is stopped (the robot keeps
standing). With ``record`` it keeps the state at ``record_fps`` during the run and renders a
PNG and a GIF from it on shutdown (headless; where no GL backend works it says so in one line
and runs without pictures).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import Imu, PointCloud2, PointField

from crawler_motion.canbus.bus import describe_bus, open_bus
from crawler_motion.runtime.diagnostic_names import (
    BODY_CONTACTS_KEY,
    FIRST_CONTACTS_KEY,
    OBSTACLE_CONTACTS_KEY,
)
from crawler_motion.runtime.ros_main import run_node
from crawler_motion.runtime.ros_parameters import descriptor
from crawler_motion.sim.motor_manager import MotorManagerSim
from crawler_motion.sim.seabed.parameters import SEABED_PARAMETERS, Simulator, build_simulator
from crawler_motion.sim.seabed.plant import BodySample
from crawler_motion.sim.seabed.render import gl_unavailable, record_paths, render_snapshots

NAME = "seabed_sim"
#: The sensors look for a new physics state this many times per step of the manager (its
#: `step_period`), so that no state is missed between two looks (each is published once).
SENSOR_LOOKS_PER_STEP = 2
SCAN_POLL_PERIOD = 0.02  # [s]
DIAGNOSTICS_PERIOD = 1.0  # [s]
HARDWARE_ID = "seabed_sim"
FRAME_ODOM, FRAME_BASE, FRAME_SCANNER = "odom", "base_link", "scanner_link"


def _xyzw(target: Any, wxyz: np.ndarray) -> None:
    target.w, target.x, target.y, target.z = (float(v) for v in wxyz)


def _stamp(seconds: float) -> Any:
    """A header stamp of ``seconds`` [s] of the node's clock."""
    return Time(nanoseconds=round(seconds * 1e9)).to_msg()


def _xyz(target: Any, values: np.ndarray) -> None:
    target.x, target.y, target.z = (float(v) for v in values)


def cloud_message(points: np.ndarray) -> PointCloud2:
    """A PointCloud2 of ``points`` ``(k, 3)`` [m]: fields x, y, z float32, dense."""
    msg = PointCloud2()
    msg.height, msg.width = 1, len(points)
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate("xyz")]
    msg.is_bigendian, msg.is_dense = sys.byteorder == "big", True
    msg.point_step = 12
    msg.row_step = 12 * len(points)
    msg.data = np.ascontiguousarray(points, dtype=np.float32).tobytes()
    return msg


class SeabedSimNode(Node):
    """Parameters, bus and manager thread, and the publishers of the body's truth."""

    def __init__(self) -> None:
        super().__init__(NAME)
        for spec in SEABED_PARAMETERS:
            self.declare_parameter(spec.name, spec.default, descriptor(spec))
        values = {spec.name: self._value(spec.name) for spec in SEABED_PARAMETERS}
        # states stamped when the physics reaches them (ConfigError: nothing started)
        self.sim: Simulator = build_simulator(values, self._seconds)
        where = describe_bus(values["can_interface"], values["can_channel"],
                             values["can_port"])
        self._bus = open_bus(values["can_interface"], values["can_channel"],
                             values["can_port"])
        plant = self.sim.plant
        self.manager = MotorManagerSim(
            self._bus, self.sim.protocol, command_timeout=self.sim.command_timeout,
            initial_positions=self.sim.protocol.to_joint(plant.initial_axes), plant=plant)
        self._noise = (float(values["imu_noise"]), float(values["imu_accel_noise"]))
        self._odom = self.create_publisher(Odometry, "odom", 10)
        self._imu = self.create_publisher(Imu, "imu", 10)
        self._scan = self.create_publisher(PointCloud2, "scan", 5)
        self._diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._ticks = 0
        self._reported_failure = False
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(self.manager.step_period / SENSOR_LOOKS_PER_STEP,
                          self._publish_sensors, clock=steady)
        self.create_timer(SCAN_POLL_PERIOD, self._publish_scan, clock=steady)
        self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics, clock=steady)
        self._record = self._picture_target()
        self.manager.start()
        self.get_logger().info(f"{NAME}: running on {where}, world {self.sim.model.world.source}")

    def _picture_target(self) -> str:
        """The ``record`` target, or '' when off or when no GL backend works (said once)."""
        if not self.sim.record:
            return ""
        reason = gl_unavailable()
        if reason is not None:
            self.get_logger().warning(f"{NAME}: {reason}; running without pictures")
            return ""
        return self.sim.record

    def write_pictures(self) -> None:
        """Render the kept states as the final PNG and a GIF (once, after the run)."""
        target, self._record = self._record, ""
        snapshots = self.sim.plant.snapshots
        if not target or not snapshots:
            return
        png, gif = record_paths(target)
        try:
            render_snapshots(self.sim.model, snapshots, self.sim.record_fps, png, gif)
        except Exception as exc:  # pictures are extras: a failure must not fail the shutdown
            self.get_logger().error(f"{NAME}: no pictures: {exc}")
            return
        self.get_logger().info(f"{NAME}: pictures {png} {gif} ({len(snapshots)} states)")

    def _seconds(self) -> float:
        """The node's clock [s] (called from the manager thread)."""
        return self.get_clock().now().nanoseconds * 1e-9

    def _value(self, name: str) -> Any:
        value = self.get_parameter(name).value
        return value if isinstance(value, (bool, int, float, str)) else tuple(value)

    def _publish_sensors(self) -> None:
        sample = self.sim.plant.take_sample()  # each state once: never a repeated stamp
        if sample is not None:
            stamp = _stamp(sample.stamp)
            self._imu.publish(self._imu_message(sample, stamp))
            self._ticks += 1
            if self._ticks % 2 == 0:
                self._odom.publish(self._odom_message(sample, stamp))
        if self.sim.plant.failure is not None and not self._reported_failure:
            self._reported_failure = True
            self.get_logger().error(self.sim.plant.failure)
            self._publish_diagnostics()

    def _odom_message(self, sample: BodySample, stamp: Any) -> Odometry:
        msg = Odometry()
        msg.header.stamp, msg.header.frame_id = stamp, FRAME_ODOM
        msg.child_frame_id = FRAME_BASE
        _xyz(msg.pose.pose.position, sample.position)
        _xyzw(msg.pose.pose.orientation, sample.orientation)
        _xyz(msg.twist.twist.linear, sample.linear_velocity)
        _xyz(msg.twist.twist.angular, sample.angular_velocity)
        return msg

    def _imu_message(self, sample: BodySample, stamp: Any) -> Imu:
        msg = Imu()
        msg.header.stamp, msg.header.frame_id = stamp, FRAME_BASE
        _xyzw(msg.orientation, sample.imu_orientation)
        _xyz(msg.angular_velocity, sample.imu_angular_velocity)
        _xyz(msg.linear_acceleration, sample.imu_linear_acceleration)
        gyro, accel = self._noise
        msg.orientation_covariance = list(np.diag([1e-6] * 3).ravel())
        msg.angular_velocity_covariance = list(np.diag([gyro**2] * 3).ravel())
        msg.linear_acceleration_covariance = list(np.diag([accel**2] * 3).ravel())
        return msg

    def _publish_scan(self) -> None:
        scan = self.sim.plant.take_scan()
        if scan is None:
            return
        msg = cloud_message(scan.points)
        # stamped when the physics took it, as the odometry of the same instant: a scan and
        # the pose it was taken from agree whenever either message is sent (a late timer on
        # a busy computer would otherwise pair a scan with another instant's pose)
        msg.header.stamp = _stamp(scan.stamp)
        msg.header.frame_id = FRAME_SCANNER
        self._scan.publish(msg)

    def _publish_diagnostics(self) -> None:
        plant, manager = self.sim.plant, self.manager
        failure = plant.failure
        if failure is None and not manager.running:
            failure = f"the manager thread stopped: {manager.last_error}"
        status = DiagnosticStatus(
            level=DiagnosticStatus.ERROR if failure else DiagnosticStatus.OK,
            name=f"{NAME}: physics", hardware_id=HARDWARE_ID,
            message=failure or "running")
        status.values = [KeyValue(key="simulated time [s]", value=f"{plant.sample().time:.3f}"),
                         KeyValue(key="physics steps", value=str(plant.steps)),
                         KeyValue(key="manager state", value=str(manager.state)),
                         KeyValue(key=BODY_CONTACTS_KEY, value=str(plant.body_contacts)),
                         KeyValue(key=OBSTACLE_CONTACTS_KEY,
                                  value=str(plant.obstacle_contacts)),
                         KeyValue(key=FIRST_CONTACTS_KEY, value="; ".join(
                             f"{k}: {v}" for k, v in plant.first_contacts.items()))]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag.publish(msg)

    def destroy_node(self) -> None:
        """Stop the manager thread, close the bus, write the pictures, destroy the node."""
        if self.manager.running:
            self.manager.stop()
        self._bus.shutdown()
        self.write_pictures()
        super().destroy_node()


def main(args: Sequence[str] | None = None) -> None:
    """Console script ``seabed_sim``: run until Ctrl-C or shutdown; a bad parameter or world
    file prints one line naming it and exits 1 before anything starts."""
    run_node(SeabedSimNode, f"{NAME}: error", args)


if __name__ == "__main__":
    main()
