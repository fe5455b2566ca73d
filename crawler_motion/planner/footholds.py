"""The walk's terrain-adaptive touch-down: the foot contacts and the gait slots in, the planned
foot targets with each leg's vertical offset out (`motion.foothold`; pure: no rclpy)."""

from __future__ import annotations

import numpy as np

from crawler_motion.model.config import RobotConfig
from crawler_motion.model.kinematics import inverse_kinematics
from crawler_motion.motion.contact_estimation import FootContact
from crawler_motion.motion.fastpath import FastKinematics, Track, joint_targets
from crawler_motion.motion.foothold import FootholdAdapter, FootholdSettings
from crawler_motion.motion.gait import Slot
from crawler_motion.planner.contacts import ContactMonitor
from crawler_motion.planner.context import JointTarget


class Footholds:
    """Offsets of the feet of the walk in progress: swings registered per slot, contacts read
    from ``monitor`` (the planner's `ContactMonitor`; None or disabled: unknown, the blind
    plan), ``failure`` set when a foot finds no ground (the walk then holds its pose).

    The adapter runs on the walk's own clock: slot time plus the durations of the slots
    before, so a walk frozen mid-slot or held at a boundary resumes its offsets where it left
    them."""

    def __init__(self, robot: RobotConfig, settings: FootholdSettings | None = None) -> None:
        self.robot = robot
        self.adapter = FootholdAdapter(robot.legs, settings)
        self.monitor: ContactMonitor | None = None
        self.failure = ""
        self._end: np.ndarray | None = None  # the joint pose [rad] the last walk ended in
        self._base = 0.0  # walk clock at the current slot's start [s]
        self._previous: float | None = None  # duration of the slot before [s]

    @property
    def settings(self) -> FootholdSettings:
        """The adapter's settings."""
        return self.adapter.settings

    def configure(self, settings: FootholdSettings) -> None:
        """New settings; disabling stops new events (held offsets blend out as they swing)."""
        self.adapter.configure(settings)

    def start(self, hold: JointTarget | None) -> None:
        """A walk starts from ``hold``: the offsets the last walk ended with are kept if it
        is still the pose that walk ended in (its first swings blend them out), else 0."""
        self.failure = ""
        if hold is None or self._end is None or not np.array_equal(hold.positions, self._end):
            self.adapter.reset()
        else:
            self.adapter.reset(self.adapter.held().tolist())
        self._end = None
        self._base, self._previous = 0.0, None

    def begin_slot(self, slot: Slot) -> None:
        """``slot`` starts (it follows the last one on the walk's clock): its swinging legs
        lift from their footholds."""
        if self._previous is not None:
            self._base += self._previous
        self._previous = slot.duration
        if slot.swing_time > 0.0:
            for i in slot.group:
                self.adapter.begin_swing(i, slot.legs[i], self._base, slot.swing_time)

    def _estimate(self) -> tuple[tuple[FootContact, ...] | None, list[float] | None]:
        last = None if self.monitor is None else self.monitor.last
        if last is None or not self.settings.enabled:
            return None, None
        return last.states, last.normal_forces.tolist()

    def targets(self, track: Track, kin: FastKinematics, now: float, t0: float
                ) -> tuple[list[float], list[float]]:
        """Joint angles [rad] and rates [rad/s] at planner time ``now`` [s] of the slot
        ``track`` started at ``t0`` [s], each foot offset along z by its leg's offset."""
        clock = self._base + (now - t0)
        states, forces = self._estimate()
        if states is None and self.adapter.quiet(clock):  # the blind plan, at its cost
            return joint_targets(track, kin, now - t0)
        pos, vel = track.evaluate(now - t0)
        z, zd = pos[2::3], vel[2::3]
        failure = self.adapter.update(clock, z, states, forces)
        if failure is not None and not self.failure:
            self.failure = failure
        delta, rate = self.adapter.offsets(clock, z, zd)
        for i, (d, dd) in enumerate(zip(delta, rate, strict=True)):
            pos[3 * i + 2] += d
            vel[3 * i + 2] += dd
        return kin.solve(pos, vel)

    def end_pose(self, track: Track) -> np.ndarray:
        """The joint pose [rad] at the end of ``track``, the feet at their footholds (kept:
        a walk started from it keeps them)."""
        pos, _ = track.evaluate(track.t_end)
        feet = np.reshape(pos, (-1, 3)).copy()
        feet[:, 2] += self.adapter.held()
        self._end = inverse_kinematics(self.robot, feet)
        return self._end.copy()
