"""The walk's rough-ground adaptation: the foot contacts and the gait slots in, the planned foot
targets out, each foot offset along z by its leg's touch-down (`motion.foothold`), a swing
that hits an obstacle re-planned once (`motion.stumble`), the body's attitude and height
following the footholds or an IMU (`motion.attitude`); pure: no rclpy."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crawler_motion.errors import GaitError
from crawler_motion.model.config import RobotConfig
from crawler_motion.model.kinematics import inverse_kinematics
from crawler_motion.motion.attitude import (
    AttitudeMode,
    AttitudeProfile,
    AttitudeSettings,
    apply_pose,
    bounded,
    stance_plane,
)
from crawler_motion.motion.contact_estimation import FootContact
from crawler_motion.motion.fastpath import FastKinematics, Track
from crawler_motion.motion.foothold import FootholdAdapter, FootholdSettings, lowering_start
from crawler_motion.motion.gait import Slot, check_trajectories
from crawler_motion.motion.jointtable import JointTable
from crawler_motion.motion.stumble import (
    HitWatch,
    Retry,
    StumbleSettings,
    lift_swing,
    replan_swing,
)
from crawler_motion.motion.trajectory import Piecewise
from crawler_motion.planner.contacts import ContactMonitor
from crawler_motion.planner.context import JointTarget

_NEUTRAL = (0.0, 0.0, 0.0)


class Footholds:
    """Offsets of the feet of the walk in progress: swings registered per slot, contacts read
    from ``monitor`` (the planner's `ContactMonitor`; None or disabled: unknown, the blind
    plan), ``failure`` set when a foot finds no ground or hits an obstacle twice (the walk
    then holds its pose, or ``failure_pose`` where one is given), ``replanned`` the slot's
    track after a stumble's retry (used in place of the walk's from then on), the body pose
    ``(z, roll, pitch)`` planned per slot (`motion.attitude`).

    The adapter runs on the walk's own clock: slot time plus the durations of the slots
    before, so a walk frozen mid-slot or held at a boundary resumes its offsets where it left
    them."""

    def __init__(self, robot: RobotConfig, settings: FootholdSettings | None = None) -> None:
        self.robot = robot
        self.adapter = FootholdAdapter(robot.legs, settings)
        self.monitor: ContactMonitor | None = None
        self.stumble = StumbleSettings()
        self.attitude = AttitudeSettings()
        self.pose = AttitudeProfile()
        self.hits = HitWatch(robot.n_legs)
        self.failure = ""
        self.failure_pose: np.ndarray | None = None  # the pose [rad] a failure holds
        self.replanned: Track | None = None
        self._slot: Slot | None = None
        self._table: JointTable | None = None  # the slot's joints, tabulated (`slot_facts`)
        self._legs: list[Piecewise] = []  # the current slot's leg trajectories
        #: Per leg, its swing's horizontal direction in the current slot (None: not swinging).
        self._swing_dir: list[np.ndarray | None] = [None] * robot.n_legs
        self._slot_time = 0.0  # slot time [s] of the last `targets`
        self._tilt = [0.0, 0.0, 0]  # IMU: sums of measured minus commanded roll, pitch; count
        self._end: np.ndarray | None = None  # the joint pose [rad] the last walk ended in
        self._base = 0.0  # walk clock at the current slot's start [s]
        self._previous: float | None = None  # duration of the slot before [s]

    @property
    def settings(self) -> FootholdSettings:
        """The adapter's settings."""
        return self.adapter.settings

    def configure(self, settings: FootholdSettings, stumble: StumbleSettings | None = None,
                  attitude: AttitudeSettings | None = None) -> None:
        """New settings; disabling stops new events (held offsets blend out as they swing,
        the attitude levels out over the next slot)."""
        self.adapter.configure(settings)
        self.stumble = stumble or self.stumble
        self.attitude = attitude or self.attitude

    def measure_attitude(self, roll: float, pitch: float) -> None:
        """An IMU's roll and pitch of the body [rad] (gravity-referenced, REP-103), taken now
        (averaged over a slot for the ``imu`` attitude mode)."""
        pose = self.pose.evaluate(self._base + self._slot_time)[0] if self._slot else _NEUTRAL
        self._tilt[0] += roll - pose[1]
        self._tilt[1] += pitch - pose[2]
        self._tilt[2] += 1

    def start(self, hold: JointTarget | None) -> None:
        """A walk starts from ``hold``: the offsets and the body pose the last walk ended with
        are kept if it is still the pose that walk ended in (its first swings blend them
        out), else 0."""
        self.failure, self.failure_pose = "", None
        if hold is None or self._end is None or not np.array_equal(hold.positions, self._end):
            self.adapter.reset()
            self.pose.reset()
        else:
            self.adapter.reset(self.adapter.held().tolist())
            self.pose.reset(self.pose.target)
        self._end = None
        self._base, self._previous = 0.0, None
        self._tilt = [0.0, 0.0, 0]

    def begin_slot(self, slot: Slot, facts: SlotFacts | None = None) -> None:
        """``slot`` starts (it follows the last one on the walk's clock): its swinging legs
        lift from their footholds, the body heads for its new pose. ``facts``: its
        `slot_facts`, computed ahead (else now)."""
        if facts is None or facts.slot is not slot:
            facts = slot_facts(slot)  # planned in the tick: no joint table (ms more there)
        if self._previous is not None:
            self._base += self._previous
        self._previous = slot.duration
        self._slot, self._legs, self.replanned = slot, list(slot.legs), None
        self._table = facts.table
        self.hits.clear()
        held = self.adapter.held()  # the footholds, before the swinging legs leave theirs
        self._swing_dir = list(facts.directions)
        for i, t_lower, lift_z, ground_z in facts.swings:
            self.adapter.begin_swing(i, slot.legs[i], self._base, slot.swing_time,
                                     (t_lower, ground_z))
            self.hits.begin(i, t_lower, lift_z)
        self._plan_pose(slot, held, facts.start_xy)

    def _plan_pose(self, slot: Slot, held: np.ndarray, xy: np.ndarray) -> None:
        """The body pose at the end of ``slot`` from the footholds' offsets ``held`` [m] and
        the feet at its start ``xy`` (n_legs, 2) [m] (see `motion.attitude`)."""
        mode = self.attitude.mode
        if mode is AttitudeMode.OFF or not self.settings.enabled:
            self.pose.plan(self._base, slot.duration, _NEUTRAL)
            return
        plane = stance_plane(xy, held)
        target = list(plane if plane is not None else self.pose.target)
        tilt, self._tilt = self._tilt, [0.0, 0.0, 0]
        if mode is AttitudeMode.IMU and tilt[2]:  # cancel the plan frame's mean tilt
            target[1], target[2] = -tilt[0] / tilt[2], -tilt[1] / tilt[2]
        self.pose.plan(self._base, slot.duration, bounded(target, self.attitude))

    def _estimate(self) -> tuple[tuple[FootContact, ...] | None, list[float] | None,
                                 list[float] | None, float]:
        """Contact states, normal forces and the horizontal forces against each swing [N]
        (`against_swing`), or Nones (unknown), and the estimate's stamp [s]."""
        last = None if self.monitor is None else self.monitor.last
        if last is None or not self.settings.enabled or not self.monitor.ground_load:
            return None, None, None, math.nan  # unknown: the blind plan
        return (last.states, last.normal_forces.tolist(),
                against_swing(last.forces, last.normal_forces, self._swing_dir), last.stamp)

    def targets(self, track: Track, kin: FastKinematics, now: float, t0: float
                ) -> tuple[list[float], list[float]]:
        """Joint angles [rad] and rates [rad/s] at planner time ``now`` [s] of the slot
        ``track`` started at ``t0`` [s], each foot offset along z by its leg's offset, the
        body at its planned pose."""
        self._slot_time = t = now - t0
        clock = self._base + t
        if self.replanned is not None:  # a stumble's retry replaced the slot's track
            track = self.replanned
        states, forces, totals, stamp = self._estimate()
        if states is None and self.adapter.quiet(clock) and self.pose.quiet():
            table = self._table if self.replanned is None else None
            joints = None if table is None else table.evaluate(t)  # tabulated ahead
            return kin.solve(*track.evaluate(t)) if joints is None else joints  # blind plan
        pos, vel = track.evaluate(t)
        if states is not None and totals is not None and self.stumble.enabled:
            retried = self._stumbles(track, t, states, totals, pos, stamp)
            if retried is not track:
                track = retried
                pos, vel = track.evaluate(t)
        z, zd = pos[2::3], vel[2::3]
        failure = self.adapter.update(clock, z, states, forces)
        if failure is not None and not self.failure:
            self.failure = failure
        delta, rate = self.adapter.offsets(clock, z, zd)
        for i, (d, dd) in enumerate(zip(delta, rate, strict=True)):
            pos[3 * i + 2] += d
            vel[3 * i + 2] += dd
        pose, pose_rate = self.pose.evaluate(clock)
        if pose != _NEUTRAL or pose_rate != _NEUTRAL:
            apply_pose(pos, vel, pose, pose_rate)
        return kin.solve(pos, vel)

    def _stumbles(self, track: Track, t: float, states: tuple[FootContact, ...],
                  totals: list[float], planned: list[float], stamp: float) -> Track:
        """Hits at slot time ``t`` [s] (``planned`` the feet of ``track`` then [m], ``stamp``
        that of the contact estimate [s]): a first
        one re-plans the swing (``replanned``), a second one (or one that cannot be retried)
        sets ``failure``; the track to use."""
        touching = [s is FootContact.YES for s in states]
        for i in self.hits.update(t, touching, totals, self.stumble.force, planned[2::3],
                                  stamp):
            where = planned[3 * i:3 * i + 3]
            place = (f"at x {where[0]:+.3f}, y {where[1]:+.3f}, z {where[2]:+.3f} m in "
                     f"base_link, {t:.2f} s into its swing")
            leg = self.robot.legs[i].upper()
            if self.hits.retried[i]:
                self._fail(f"leg {leg} hit an obstacle again after lifting "
                           f"{self.stumble.lift * 1e3:.0f} mm higher, {place}")
                continue
            retry, why = self._retry(i, t)
            if retry is None:
                self._fail(f"leg {leg} hit an obstacle {place}; {why}")
                continue
            legs = list(self._legs)
            legs[i] = retry.plan
            self._legs = legs
            track = self.replanned = Track(legs)
            self.adapter.replan_swing(i, retry.plan, retry.t_lower)
            self.hits.retry(i, retry, where[2])
        return track

    def _retry(self, i: int, t: float) -> tuple[Retry | None, str]:
        """Leg ``i``'s swing re-planned from slot time ``t`` [s]: the retry with the stop and
        retreat, else the vertical-only one (`motion.stumble`), the first whose samples keep
        the joint limits; or None and why neither does."""
        assert self._slot is not None
        why = "too late in its swing to lift higher"
        for make in (replan_swing, lift_swing):
            retry = make(self._legs[i], self._slot.swing_time, t, self.stumble)
            if retry is None:
                continue
            legs = list(self._legs)
            legs[i] = retry.plan
            try:
                check_trajectories(self.robot, legs, "its retried swing")
            except GaitError as exc:
                why = str(exc)
                continue
            return retry, ""
        return None, why

    def _fail(self, why: str) -> None:
        """A stumble ends the walk: hold the measured pose (the last target would go on
        pushing what the foot hit), or the last target before a measurement."""
        if not self.failure:
            self.failure = why
            self.failure_pose = None if self.monitor is None else self.monitor.estimator.angles

    def end_pose(self, track: Track) -> np.ndarray:
        """The joint pose [rad] at the end of ``track``, the feet at their footholds, the body
        at its pose (kept: a walk started from it keeps them)."""
        if self.replanned is not None:
            track = self.replanned
        pos, _ = track.evaluate(track.t_end)
        pos = list(pos)
        for i, d in enumerate(self.adapter.held()):
            pos[3 * i + 2] += float(d)
        apply_pose(pos, [0.0] * len(pos), self.pose.target, _NEUTRAL)
        self._end = inverse_kinematics(self.robot, np.reshape(pos, (-1, 3)))
        return self._end.copy()


@dataclass(frozen=True)
class SlotFacts:
    """What `Footholds.begin_slot` needs of a slot's trajectories, computed once per slot
    (`slot_facts`; the walk does it while planning the slot ahead, off the tick)."""

    slot: Slot
    #: per leg, its swing's horizontal direction (`swing_direction`; None: not swinging)
    directions: tuple[np.ndarray | None, ...]
    #: per swinging leg: (leg, lowering start [s], foot z at lift-off [m], at touch-down [m])
    swings: tuple[tuple[int, float, float, float], ...]
    start_xy: np.ndarray  # (n_legs, 2) the feet at the slot's start [m]
    #: the blind plan's joints, tabulated (`JointTable`; None: the tick solves them)
    table: JointTable | None = None


def slot_facts(slot: Slot, robot: RobotConfig | None = None) -> SlotFacts:
    """The `SlotFacts` of ``slot``; with ``robot``, its `JointTable` too (3-5 ms; tens of ms
    for calibrated legs): only where the slot is planned ahead of the tick."""
    n_legs = len(slot.legs)
    directions: list[np.ndarray | None] = [None] * n_legs
    swings = []
    if slot.swing_time > 0.0:
        for i in slot.group:
            leg = slot.legs[i]
            directions[i] = swing_direction(leg, slot.swing_time)
            swings.append((i, lowering_start(leg, slot.swing_time),
                           float(leg.evaluate(0.0)[0][0, 2]),
                           float(leg.evaluate(slot.swing_time)[0][0, 2])))
    xy = np.array([leg.evaluate(0.0)[0][0, :2] for leg in slot.legs])
    table = None if robot is None else JointTable.build(slot.legs, robot)
    return SlotFacts(slot, tuple(directions), tuple(swings), xy, table)


def swing_direction(leg: Piecewise, swing_time: float) -> np.ndarray | None:
    """Unit horizontal direction ``(2,)`` of a swing, lift-off to touch-down (base_link); None
    for a swing that does not move horizontally."""
    start, end = leg.evaluate(0.0)[0][0, :2], leg.evaluate(swing_time)[0][0, :2]
    length = float(np.linalg.norm(end - start))
    return None if length < 1e-6 else (end - start) / length


def against_swing(forces: np.ndarray, normal: np.ndarray,
                  directions: list[np.ndarray | None]) -> list[float]:
    """Per leg, the ground's horizontal force against its swing [N]: the component of the force
    on the foot ``forces`` ``(n, 3)`` [N] opposite the swing's direction (its whole horizontal
    force for a leg without one), 0 where the normal force pulls (``normal`` < 0: the ground
    cannot pull, so that reading is the leg's own dynamics, not a contact)."""
    out = []
    for i, (fx, fy, _) in enumerate(forces.tolist()):
        d = directions[i] if i < len(directions) else None
        if not normal[i] >= 0.0:
            out.append(0.0)
        elif d is None:
            out.append(math.hypot(fx, fy))
        else:
            out.append(max(0.0, -(fx * float(d[0]) + fy * float(d[1]))))
    return out
