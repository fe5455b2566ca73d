"""The seabed physics as the plant of the simulated motor manager: servo targets in, angles out."""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from crawler_motion.canbus.protocol import MotorProtocol
from crawler_motion.sim.seabed.contacts import body_touches
from crawler_motion.sim.seabed.model import IMU_SENSORS, SeabedModel
from crawler_motion.sim.seabed.scanner import RangeScanner
from crawler_motion.sim.seabed.water import check_range

#: Time the robot settles on the seabed before the manager starts [s].
SETTLE_TIME = 0.3
#: Deepest contact penetration still taken as sane [m]; deeper means the simulation broke.
MAX_PENETRATION = 0.02
#: MuJoCo's warnings of a broken state (it then resets the state to the model's start itself).
BAD_STATE_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                      mujoco.mjtWarning.mjWARN_BADQACC)


@dataclass(frozen=True)
class BodySample:
    """The body's state at simulated ``time`` [s], reached at ``stamp`` [s] of the plant's
    clock (the simulated time without one); vectors of base_link unless said.

    ``position`` [m] and ``orientation`` (w, x, y, z) in the world; ``linear_velocity`` [m/s]
    and ``angular_velocity`` [rad/s] in base_link (the twist of ``odom``); ``imu_*``: the IMU's
    measurement with noise: orientation (w, x, y, z), angular velocity [rad/s], specific force
    [m/s²].
    """

    time: float
    position: np.ndarray
    orientation: np.ndarray
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray
    imu_orientation: np.ndarray
    imu_angular_velocity: np.ndarray
    imu_linear_acceleration: np.ndarray
    stamp: float = 0.0


@dataclass(frozen=True)
class Scan:
    """A scan taken at simulated ``time`` [s], reached at ``stamp`` [s] of the plant's clock
    (as `BodySample`): ``points`` ``(k, 3)`` in scanner_link [m]."""

    time: float
    stamp: float
    points: np.ndarray


@dataclass(frozen=True)
class PlantSettings:
    """IMU noise (standard deviations), the scan period and the period of the state snapshots
    kept for pictures (0: none) of the plant (SI units)."""

    gyro_noise: float = 0.0  # [rad/s]
    accel_noise: float = 0.0  # [m/s²]
    scan_period: float = 0.1  # [s]
    max_penetration: float = MAX_PENETRATION  # [m]
    seed: int = 0
    snapshot_period: float = 0.0  # [s]

    def __post_init__(self) -> None:
        check_range("gyro_noise", self.gyro_noise, 0.0, 10.0, "rad/s")
        check_range("accel_noise", self.accel_noise, 0.0, 100.0, "m/s²")
        check_range("scan_period", self.scan_period, 1e-3, 10.0, "s")
        check_range("max_penetration", self.max_penetration, 1e-4, 1.0, "m")
        check_range("snapshot_period", self.snapshot_period, 0.0, 60.0, "s")


def unstable_reason(sm: SeabedModel, data: mujoco.MjData, max_penetration: float) -> str | None:
    """Why the state is not sane (non-finite, or reset by MuJoCo after it was, or a contact
    deeper than ``max_penetration`` [m]); None when it is."""
    reset = any(data.warning[int(w)].number > 0 for w in BAD_STATE_WARNINGS)
    if reset or not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
        return f"simulation unstable at t = {data.time:.3f} s: non-finite state"
    if data.ncon:
        depth = -float(data.contact.dist[:data.ncon].min())
        if depth > max_penetration:
            return (f"simulation unstable at t = {data.time:.3f} s: penetration {depth:.3f} m "
                    f"> {max_penetration:g} m")
    return None


class SeabedPlant:
    """Steps the seabed model as the manager's time advances (thread-safe snapshots out).

    The robot starts at the configured standing pose, settled on the seabed. `advance` takes
    axis targets [rad] (axis order of ``protocol``), steps the physics by ``dt`` (whole time
    steps; the remainder is carried over) and returns the measured axis positions;
    `take_efforts` gives the servo torques averaged over the steps since its last call (what a
    drive reports: a mean over the feedback period, not one instant of the servo's ripple).
    ``on_step(data)``, when set, sees the state after every physics step. On an
    unstable state the physics stops, `failure` says why and the last sane positions stay.
    With a ``snapshot_period`` it keeps ``qpos`` every period of simulated time in `snapshots`
    (cheap: pictures are rendered from them after the run).
    """

    def __init__(self, sm: SeabedModel, protocol: MotorProtocol,
                 scanner: RangeScanner | None = None,
                 settings: PlantSettings | None = None,
                 clock: Callable[[], float] | None = None) -> None:
        self.sm, self.protocol, self.scanner = sm, protocol, scanner
        #: Time [s] of the host's clock when a state is reached (None: the simulated time):
        #: the stamp of every sample and scan, so that they agree with each other whenever
        #: the messages carrying them are sent.
        self.clock = clock
        self.settings = settings or PlantSettings()
        self.data = sm.make_data()
        self.failure: str | None = None
        self.steps = 0  # physics steps taken
        #: Advances (manager ticks) that ended with the hull or a leg link (not a foot)
        #: touching the world: a collision with an obstacle or the seabed.
        self.body_contacts = 0
        #: Of them, the advances with the hull or a leg link touching anything but the seabed
        #: (a box, a rock: an obstacle).
        self.obstacle_contacts = 0
        #: The first such contact with the seabed and with an obstacle, "<robot geom> on
        #: <world geom>" (what a contact figure means).
        self.first_contacts: dict[str, str] = {}
        self._lock = threading.Lock()
        self._rng = np.random.default_rng(self.settings.seed)
        self._carry = 0.0  # [s] not yet stepped
        self._torque_sum = np.zeros(sm.model.nu)  # [N m s / timestep] since take_efforts
        self._torque_steps = 0
        self.on_step: Callable[[mujoco.MjData], None] | None = None
        self._next_scan = 0.0  # [s] simulated time
        self._scan: Scan | None = None
        self.snapshots: list[np.ndarray] = []  # qpos, one per snapshot period
        sm.settle(self.data, SETTLE_TIME)
        self._sample = self._measure(self.clock() if self.clock else float(self.data.time))
        self._sample_new = True  # `_sample` not yet taken by `take_sample`
        self._next_snapshot = float(self.data.time)  # [s] simulated time
        self._keep_snapshot()
        self._pos = self.protocol.to_axis(self.data.qpos[sm.qpos_index])

    @property
    def initial_axes(self) -> np.ndarray:
        """Axis positions [rad] at the start (after settling)."""
        return self._pos.copy()

    def advance(self, dt: float, targets: np.ndarray) -> np.ndarray:
        """Servos to ``targets`` (axis order [rad]), physics on by ``dt`` [s]; axis positions."""
        if self.failure is not None:
            return self._pos.copy()
        timestep = self.sm.timestep
        n = math.floor((self._carry + dt) / timestep + 1e-9)
        self._carry = self._carry + dt - n * timestep
        if n <= 0:
            return self._pos.copy()
        self.data.ctrl[:] = self.protocol.to_joint(targets)
        self._step(n)
        reason = unstable_reason(self.sm, self.data, self.settings.max_penetration)
        if reason is not None:
            self.failure = reason
            return self._pos.copy()
        self._pos = self.protocol.to_axis(self.data.qpos[self.sm.qpos_index])
        self._count_contacts()
        stamp = self.clock() if self.clock is not None else float(self.data.time)
        sample = self._measure(stamp)
        scan = self._scan_if_due(stamp)
        self._keep_snapshot()
        with self._lock:
            self._sample, self._sample_new = sample, True
            if scan is not None:
                self._scan = scan
        return self._pos.copy()

    def _count_contacts(self) -> None:
        """Counts the advance in `body_contacts` / `obstacle_contacts` when the hull or a leg
        link touches the world, and keeps the first touch of each kind."""
        touches = body_touches(self.sm, self.data)
        if len(touches) == 0:
            return
        self.body_contacts += 1
        on_obstacle = touches[:, 1] != self.sm.seabed_geom
        if on_obstacle.any():
            self.obstacle_contacts += 1
        for kind, pairs in (("seabed", touches[~on_obstacle]),
                            ("obstacle", touches[on_obstacle])):
            if len(pairs) and kind not in self.first_contacts:
                names = [mujoco.mj_id2name(self.sm.model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or
                         f"geom {g}" for g in pairs[0]]
                self.first_contacts[kind] = (f"{names[0]} on {names[1]} at "
                                             f"{self.data.time:.2f} s")

    def _step(self, n: int) -> None:
        """``n`` physics steps, summing the servo torques (joint order [N m])."""
        model, data, hook = self.sm.model, self.data, self.on_step
        for _ in range(n):
            mujoco.mj_step(model, data)
            self._torque_sum += data.actuator_force
            if hook is not None:
                hook(data)
        self._torque_steps += n
        self.steps += n

    def take_efforts(self) -> np.ndarray:
        """Servo torques averaged over the physics steps since the last call, axis order
        [N m] (the last instant's when no step was taken since)."""
        if self._torque_steps:
            tau = self._torque_sum / self._torque_steps
        else:
            tau = np.array(self.data.actuator_force, dtype=float)
        self._torque_sum[:] = 0.0
        self._torque_steps = 0
        return self.protocol.effort_to_axis(tau)

    def sample(self) -> BodySample:
        """The latest body state."""
        with self._lock:
            return self._sample

    def take_sample(self) -> BodySample | None:
        """The latest body state once; None when the physics has not advanced since (a
        sensor that published it again would send a stale reading with a repeated stamp)."""
        with self._lock:
            sample, self._sample_new = (self._sample if self._sample_new else None), False
            return sample

    def take_scan(self) -> Scan | None:
        """The latest scan once; None when there is no new one."""
        with self._lock:
            scan, self._scan = self._scan, None
            return scan

    def _keep_snapshot(self) -> None:
        period = self.settings.snapshot_period
        if period > 0.0 and self.data.time + 1e-9 >= self._next_snapshot:
            self.snapshots.append(self.data.qpos.copy())
            self._next_snapshot += period

    def _scan_if_due(self, stamp: float) -> Scan | None:
        if self.scanner is None or self.data.time < self._next_scan:
            return None
        self._next_scan = max(self._next_scan + self.settings.scan_period, self.data.time)
        return Scan(float(self.data.time), stamp, self.scanner.points(self.data))

    def _measure(self, stamp: float) -> BodySample:
        d, s = self.data, self.settings
        quat = d.qpos[3:7].copy()
        rot = d.xmat[self.sm.base_body].reshape(3, 3)
        gyro, accel, imu_quat = (d.sensor(name).data.copy() for name in IMU_SENSORS)
        return BodySample(
            time=float(d.time), position=d.qpos[:3].copy(), orientation=quat,
            linear_velocity=rot.T @ d.qvel[:3], angular_velocity=d.qvel[3:6].copy(),
            imu_orientation=imu_quat,
            imu_angular_velocity=gyro + self._rng.normal(0.0, s.gyro_noise, 3),
            imu_linear_acceleration=accel + self._rng.normal(0.0, s.accel_noise, 3),
            stamp=stamp)
