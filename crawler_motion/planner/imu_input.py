"""The planner's IMU: ``imu`` (sensor_msgs/Imu) levels the body in the ``imu`` attitude mode.

With ``foothold_adapt`` and ``attitude_mode: imu`` the body's roll and pitch over each gait
slot cancel the mean tilt the IMU measured over the slot before (`motion.attitude`). The IMU is
taken as mounted aligned with ``base_link`` (there is no tf here to rotate it): its
``orientation`` is the body's attitude against a gravity-aligned frame (REP-103, REP-145), and
a message in another frame is refused. So is one without an orientation
(``orientation_covariance[0] == -1``, the sensor_msgs convention), or whose quaternion is not
finite or not unit (within `UNIT_TOLERANCE`); refusals are counted and logged.

A slot after one without a sample follows the plane of the stance feet instead; a walk in the
``imu`` mode without a sample for `IMU_TIMEOUT` reports the IMU ``missing`` in
``planner_status`` (key ``imu``) with a warning in the log; the walk goes on.
While the mode is not ``imu`` (the default) one sample is taken every `IMU_IDLE_PERIOD`,
counted and set aside without the core's lock (the status still dates the IMU); the others
wait in the subscription's queue and are dropped there. The topic is read by a thread of its
own (`runtime.ros_reader.SubscriptionReader`): at the simulator's 100 Hz, through the
executor each sample cost a wake-up and a rebuild of the wait set of every entity of the node
(of both nodes in the composed controller).
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
from crawler_motion.planner.state import WALK_STATES
from crawler_motion.runtime.ros_reader import SubscriptionReader

#: QoS of the ``imu`` subscription (only fresh samples matter).
IMU_QOS = qos_profile_sensor_data
#: A walk in the ``imu`` mode without a sample for this long [s] reports the IMU missing.
IMU_TIMEOUT = 0.5
#: The IMU's frame: the body's (``base_link``, or a prefixed ``<robot>/base_link``; empty: the
#: publisher's default, taken as the body's).
IMU_FRAME = "base_link"
#: Largest accepted deviation of the orientation quaternion's norm from 1.
UNIT_TOLERANCE = 0.01
#: While the attitude mode does not take the IMU, a sample is taken at most this often [s].
IMU_IDLE_PERIOD = 1.0


def imu_roll_pitch(msg: Imu) -> tuple[float, float]:
    """Roll and pitch [rad] of an Imu message's orientation; raises CommandError for one
    without an orientation or with an invalid quaternion."""
    if msg.orientation_covariance[0] == -1.0:
        raise CommandError("imu has no orientation (orientation_covariance[0] = -1): "
                           "the imu attitude mode needs an IMU that estimates its attitude")
    frame = msg.header.frame_id
    if frame and frame != IMU_FRAME and not frame.endswith("/" + IMU_FRAME):
        raise CommandError(f"imu in frame {frame!r}: the planner has no transform; publish it "
                           f"in {IMU_FRAME!r} (an IMU mounted aligned with the body)")
    q = msg.orientation
    wxyz = (q.w, q.x, q.y, q.z)
    if not all(math.isfinite(v) for v in wxyz):
        raise CommandError(f"imu orientation {wxyz} (w, x, y, z) is not finite")
    norm = math.sqrt(sum(v * v for v in wxyz))
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise CommandError(f"imu orientation {wxyz} (w, x, y, z) has norm {norm:.4g}: a unit "
                           f"quaternion is expected (within {UNIT_TOLERANCE:g})")
    return roll_pitch(quaternion_matrix(wxyz))


class ImuInput:
    """The ``imu`` subscription of ``node``: each valid sample goes to the walk's attitude
    (`FootholdPlanner.measure_attitude`, under ``lock``) while ``core``'s attitude mode is
    ``imu``; refusals go to ``warn``. `start` starts its reader thread, `close` ends it."""

    def __init__(self, node: Node, core: PlannerCore, lock: threading.Lock,
                 warn: Callable[[str], None]) -> None:
        self._core, self._lock, self._warn = core, lock, warn
        self.samples = 0  # valid samples taken
        self.refused = 0  # invalid samples
        self._last = -math.inf  # steady time of the last valid sample [s]
        self._taken = -math.inf  # steady time of the last sample taken [s]
        self._reader = SubscriptionReader(node, Imu, "imu", IMU_QOS,
                                          lambda msg, _info: self._on_imu(msg),
                                          on_error=warn, name="planner-imu", when=self._taking)

    def start(self) -> None:
        """Start taking samples."""
        self._reader.start()

    def close(self) -> None:
        """Stop taking samples and destroy the subscription."""
        self._reader.close()

    def _taking(self) -> bool:
        """Every sample in the ``imu`` mode, else one every `IMU_IDLE_PERIOD` (reader
        thread; the mode read without the lock: a flag)."""
        return (self._wanted(self._core.walk.foothold)
                or time.monotonic() - self._taken >= IMU_IDLE_PERIOD)

    def _on_imu(self, msg: Imu) -> None:
        self._taken = time.monotonic()
        try:
            roll, pitch = imu_roll_pitch(msg)
        except CommandError as exc:
            self.refused += 1
            self._warn(f"imu ignored: {exc}")
            return
        self.samples += 1
        self._last = time.monotonic()
        if not self._wanted(self._core.walk.foothold):  # read without the lock: a flag
            return
        with self._lock:
            footholds = self._core.walk.foothold
            if self._wanted(footholds):
                footholds.measure_attitude(roll, pitch)

    @staticmethod
    def _wanted(footholds: Any) -> bool:
        """True when the walk's attitude takes the IMU (foothold_adapt, attitude_mode imu)."""
        return bool(footholds.settings.enabled and footholds.attitude.mode is AttitudeMode.IMU)

    def report(self, now: float | None = None) -> dict[str, Any]:
        """``samples``, ``refused``, ``age`` of the last sample [s] (None: never) and
        ``missing`` (the ``imu`` mode while walking without a sample for `IMU_TIMEOUT`; a
        warning then)."""
        now = time.monotonic() if now is None else now
        age = now - self._last
        with self._lock:
            wanted = self._wanted(self._core.walk.foothold) and self._core.state in WALK_STATES
        missing = wanted and not age <= IMU_TIMEOUT
        if missing:
            self._warn(f"attitude_mode imu: no imu sample for {IMU_TIMEOUT:g} s: the body "
                       "follows the plane of the stance feet until the imu is back")
        return {"samples": self.samples, "refused": self.refused,
                "age": round(age, 3) if math.isfinite(age) else None, "missing": missing}
