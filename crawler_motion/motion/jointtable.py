"""A slot's joint angles and rates tabulated when it is planned ahead; the tick interpolates.

The planner's tick evaluates a slot's foot trajectories and solves the IK of every leg for one
instant (`fastpath`). For the blind plan (no foothold, stumble or attitude change to the
slot's feet) those numbers depend on the time only, so the planning thread can compute them
ahead: `JointTable.build` solves the slot's IK in one vectorised batch (the reference
`kinematics.inverse_kinematics` and `joint_velocities`, calibrated legs included) on a time
grid whose nodes include every segment break of every leg, and stores per cell and joint a
cubic Hermite interpolant of the angle (from the angles and rates at its ends) and one of the
rate (from the rates and accelerations at its ends; the accelerations are
q'' = J^-1 (a - J' q'), with the feet's planned accelerations a and J' q' a central difference
of the leg Jacobians along q'). A tick then costs a cell lookup and two cubics per joint,
whatever the legs' calibration. Only slots planned ahead of the tick get a table (3 ms per
0.5 s slot, 23-35 ms with calibrated legs); a slot planned in the tick is solved per tick.

Every cell is checked when it is built: at its mid-time (where a cubic Hermite's error peaks)
the interpolants are compared with the exact IK, and a cell off by more than `ANGLE_TOL` or
`RATE_TOL` is left to the exact path (`JointTable.evaluate` returns None there). Both are far
below what reaches a motor: the bus carries angles in steps of 1e-4 rad (the DBC's
``AxisN_Target``) and no rate. A slot whose IK fails anywhere on the grid gets no table: the
exact path decides and raises as before. Flat vectors are leg-major, as in `fastpath`.
"""

from __future__ import annotations

import itertools
import math
from bisect import bisect_right
from collections.abc import Sequence

import numpy as np

from crawler_motion.errors import KinematicsError
from crawler_motion.model import kinematics
from crawler_motion.model.config import RobotConfig
from crawler_motion.motion.trajectory import Piecewise

__all__ = ["ANGLE_TOL", "RATE_TOL", "TABLE_STEP", "JointTable"]

#: Longest cell of the grid [s] (a segment of a leg is split into equal cells of at most this).
TABLE_STEP = 0.002
#: Largest interpolation error of a joint angle kept in the table [rad] (at the cell's mid-time).
ANGLE_TOL = 1e-7
#: Largest interpolation error of a joint rate kept in the table [rad/s].
RATE_TOL = 1e-5
#: Step [s] of the central difference of the leg Jacobians along the joint rates that gives
#: the joint accelerations (q'' = J^-1 (a - J' q')).
FD_STEP = 1e-5
#: Segment breaks of different legs closer than this are one node [s].
MERGE_BREAKS = 1e-6


def _grid(legs: Sequence[Piecewise], step: float) -> np.ndarray:
    """Nodes [s]: every leg's breaks (merged within `MERGE_BREAKS`), each interval split into
    equal cells of at most ``step``."""
    breaks = np.unique(np.concatenate([pw.breaks for pw in legs]))
    kept = [float(breaks[0])]
    for b in breaks[1:]:
        if b - kept[-1] > MERGE_BREAKS:
            kept.append(float(b))
    kept[-1] = float(breaks[-1])
    nodes = [np.array(kept[:1])]
    for a, b in itertools.pairwise(kept):
        m = max(1, math.ceil((b - a) / step - 1e-9))
        nodes.append(a + (b - a) * np.arange(1, m + 1) / m)
    grid = np.concatenate(nodes)
    grid[-1] = kept[-1]
    return grid


def _hermite(f0: np.ndarray, f1: np.ndarray, d0: np.ndarray, d1: np.ndarray,
             length: np.ndarray) -> np.ndarray:
    """Coefficients ``(..., 4)`` in u of the cubic with values ``f0``, ``f1`` and time
    derivatives ``d0``, ``d1`` at the ends of cells of ``length`` [s]."""
    d0, d1 = d0 * length, d1 * length
    return np.stack((f0, d0, 3.0 * (f1 - f0) - 2.0 * d0 - d1, 2.0 * (f0 - f1) + d0 + d1), -1)


def _cubic(coeffs: np.ndarray, u: float) -> np.ndarray:
    return ((coeffs[..., 3] * u + coeffs[..., 2]) * u + coeffs[..., 1]) * u + coeffs[..., 0]


class JointTable:
    """Joint angles [rad] and rates [rad/s] of one slot's blind plan, interpolated per tick.

    Built by `build` (the planning thread); `evaluate` is the tick's call. Times are those of
    the slot's `Piecewise` legs; before the start or after the end it holds the end values
    (angles and rates), as `fastpath.Track` does.
    """

    __slots__ = ("_active", "_coeffs", "_exact", "_starts", "exact_cells", "n_cells", "t0",
                 "t_end")

    def __init__(self, starts: list[float], t_end: float, coeffs: np.ndarray,
                 exact: list[bool]) -> None:
        #: ``(cells, joints, 8)``: the 4 coefficients in u = (t - start) / length of the
        #: angle, then the 4 of the rate; one array (a tick converts one cell, and freeing
        #: the table costs nothing, unlike ~25,000 float objects)
        self._coeffs = coeffs
        self._exact = exact  # per cell: True where the exact path serves it
        self._starts = starts
        self.n_cells = len(exact)
        self.t0, self.t_end = starts[0], float(t_end)
        self.exact_cells = sum(exact)  # cells left to the exact path
        self._active = (starts[0], starts[1] if len(starts) > 1 else self.t_end, 0)

    @classmethod
    def build(cls, legs: Sequence[Piecewise], robot: RobotConfig,
              step: float = TABLE_STEP) -> JointTable | None:
        """The table of the feet ``legs`` (one 3-D `Piecewise` per leg, in base_link) for
        ``robot``; None if the IK fails anywhere on the grid (the exact path then decides)."""
        nodes = _grid(legs, step)
        start, end = nodes[:-1], nodes[1:]
        length = end - start
        n = len(start)
        times = np.concatenate((nodes, start + 0.5 * length))
        evaluated = [pw.evaluate(times) for pw in legs]
        feet, velocity, acceleration = (np.stack([e[k] for e in evaluated], axis=-2)
                                        for k in range(3))
        try:  # one IK batch for the nodes and the mid-times, calibrated legs included
            q_all = kinematics.inverse_kinematics(robot, feet)
            qd_all = kinematics.joint_velocities(robot, q_all, velocity)
            q, qd = q_all[:n + 1], qd_all[:n + 1]
            # q'' = J^-1 (a - J' q'), J' q' by a central difference of J along q'
            ahead = kinematics.foot_jacobians(robot, q + FD_STEP * qd)
            back = kinematics.foot_jacobians(robot, q - FD_STEP * qd)
            bend = np.einsum("...ij,...j->...i", (ahead - back) / (2.0 * FD_STEP), qd)
            qdd = kinematics.joint_velocities(robot, q, acceleration[:n + 1] - bend)
        except KinematicsError:
            return None
        flat = (n + 1, -1)
        q, qd, qdd = q.reshape(flat), qd.reshape(flat), qdd.reshape(flat)
        q_mid, qd_mid = q_all[n + 1:].reshape(n, -1), qd_all[n + 1:].reshape(n, -1)
        span = length[:, None]
        angle = _hermite(q[:-1], q[1:], qd[:-1], qd[1:], span)
        rate = _hermite(qd[:-1], qd[1:], qdd[:-1], qdd[1:], span)
        good = ((np.abs(_cubic(angle, 0.5) - q_mid) <= ANGLE_TOL)
                & (np.abs(_cubic(rate, 0.5) - qd_mid) <= RATE_TOL)).all(axis=1)
        coeffs = np.concatenate((angle, rate), axis=-1)  # (cells, joints, 8)
        return cls(start.tolist(), float(nodes[-1]), np.ascontiguousarray(coeffs),
                   (~good).tolist())

    def evaluate(self, t: float) -> tuple[list[float], list[float]] | None:
        """Flat joint angles [rad] and rates [rad/s] at ``t`` [s]; None if the cell of ``t``
        is left to the exact path."""
        lo, hi, k = self._active
        if not (lo <= t < hi):
            k = bisect_right(self._starts, t) - 1
            last = self.n_cells - 1
            k = 0 if k < 0 else (last if k > last else k)
            lo = self._starts[k]
            hi = self._starts[k + 1] if k < last else self.t_end
            self._active = (lo, hi, k)
        if self._exact[k]:
            return None
        u = (t - lo) / (hi - lo)
        if u < 0.0:
            u = 0.0
        elif u > 1.0:
            u = 1.0
        q: list[float] = []
        qd: list[float] = []
        put_q, put_qd = q.append, qd.append
        for a0, a1, a2, a3, b0, b1, b2, b3 in self._coeffs[k].tolist():
            put_q(((a3 * u + a2) * u + a1) * u + a0)
            put_qd(((b3 * u + b2) * u + b1) * u + b0)
        return q, qd
