"""The planner's IMU: ``imu`` (sensor_msgs/Imu) levels the body in the ``imu`` attitude mode.

With ``foothold_adapt`` and ``attitude_mode: imu`` the body's roll and pitch over each gait
slot cancel the mean tilt the IMU measured over the slot before (`motion.attitude`). The IMU is
taken as mounted aligned with ``base_link`` (there is no tf here to rotate it): its
``orientation`` is the body's attitude against a gravity-aligned frame (REP-103, REP-145).
A message without an orientation (``orientation_covariance[0] == -1``, the sensor_msgs
convention) or with a quaternion that is not finite or has no direction is refused and counted.

Without samples (no publisher, or none for `IMU_TIMEOUT`), a slot's attitude follows the plane
of the stance feet instead, and ``missing`` says so in ``planner_status`` (key ``imu``) with a
warning in the log; the walk goes on.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Imu

from crawler_motion.errors import CommandError
from crawler_motion.model.rotations import quaternion_matrix, roll_pitch
from crawler_motion.motion.attitude import AttitudeMode
from crawler_motion.planner.core import PlannerCore

#: QoS of the ``imu`` subscription (only fresh samples matter).
IMU_QOS = qos_profile_sensor_data
#: A walk in the ``imu`` mode without a sample for this long [s] reports the IMU missing.
IMU_TIMEOUT = 0.5


def imu_roll_pitch(msg: Imu) -> tuple[float, float]:
    """Roll and pitch [rad] of an Imu message's orientation; raises CommandError for one
    without an orientation or with an invalid quaternion."""
    if msg.orientation_covariance[0] == -1.0:
        raise CommandError("imu has no orientation (orientation_covariance[0] = -1): "
                           "the imu attitude mode needs an IMU that estimates its attitude")
    q = msg.orientation
    wxyz = (q.w, q.x, q.y, q.z)
    if not all(math.isfinite(v) for v in wxyz):
        raise CommandError(f"imu orientation {wxyz} (w, x, y, z) is not finite")
    try:
        return roll_pitch(quaternion_matrix(wxyz))
    except ValueError as exc:
        raise CommandError(f"imu orientation: {exc}; a unit quaternion is expected") from None


class ImuInput:
    """The ``imu`` subscription of ``node``: each valid sample goes to the walk's attitude
    (`FootholdPlanner.measure_attitude`, under ``lock``) while ``core``'s attitude mode is
    ``imu``; refusals go to ``warn``."""

    def __init__(self, node: Node, core: PlannerCore, lock: threading.Lock,
                 warn: Callable[[str], None]) -> None:
        self._core, self._lock, self._warn = core, lock, warn
        self.samples = 0  # valid samples taken
        self.refused = 0  # invalid samples
        self._last = -math.inf  # steady time of the last valid sample [s]
        node.create_subscription(Imu, "imu", self._on_imu, IMU_QOS)

    def _on_imu(self, msg: Imu) -> None:
        try:
            roll, pitch = imu_roll_pitch(msg)
        except CommandError as exc:
            self.refused += 1
            self._warn(f"imu ignored: {exc}")
            return
        self.samples += 1
        self._last = time.monotonic()
        with self._lock:
            footholds = self._core.walk.foothold
            if footholds.settings.enabled and footholds.attitude.mode is AttitudeMode.IMU:
                footholds.measure_attitude(roll, pitch)

    def report(self, now: float | None = None) -> dict[str, Any]:
        """``samples``, ``refused``, ``age`` of the last sample [s] (None: never) and
        ``missing`` (the ``imu`` mode while walking without a sample for `IMU_TIMEOUT`; a
        warning then)."""
        now = time.monotonic() if now is None else now
        age = now - self._last
        with self._lock:
            footholds = self._core.walk.foothold
            wanted = (footholds.settings.enabled and footholds.attitude.mode is AttitudeMode.IMU
                      and self._core.state == "WALKING")
        missing = wanted and not age <= IMU_TIMEOUT
        if missing:
            self._warn(f"attitude_mode imu: no imu sample for {IMU_TIMEOUT:g} s: the body "
                       "follows the plane of the stance feet until the imu is back")
        return {"samples": self.samples, "refused": self.refused,
                "age": round(age, 3) if math.isfinite(age) else None, "missing": missing}
