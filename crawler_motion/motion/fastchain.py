"""Calibrated legs in plain floats: forward kinematics, joint Jacobian, Newton refinement of the
IK and joint rates of one leg at one instant, for the per-tick fast path.

Evaluates the fixed frames of `crawler_motion.model.leg_geometry.joint_frames` (the same
frames the URDF and the simulator's model are built from) with `math` on Python floats; the
numpy reference is `crawler_motion.model.calibrated` (through `leg_geometry.leg_chain`), and
`test/motion/test_fastchain.py` compares the two. Newton settings are the reference's
(`calibrated.IK_FINAL`, `IK_MAX_STEPS`, `IK_ACCEPT`, `START_KNEE`, `MAX_STEP`); a leg this
module cannot solve returns None and the caller asks the reference, which raises its own error.

Speed: the chain is evaluated in the frame of the root joint's child (`_chain`), with the
constants of each leg folded in once; the target is turned into that frame instead of the
Jacobian into base_link (the Newton step is the same vector). The evaluation that checks the
final foot error also gives the Jacobian whose inverse `ScalarLeg.rates_at` reuses.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from crawler_motion.errors import KinematicsError
from crawler_motion.model import calibrated
from crawler_motion.model.leg_geometry import JointFrames

__all__ = ["WARM_START_MISS", "ScalarLeg", "Solution"]

_Vec = tuple[float, float, float]
#: `_chain`'s result: cos, sin of the root angle (times its sign); foot u [m] and the Jacobian
#: columns d u / d q_k [m/rad] (k = root, shoulder, knee), all in the root joint's child frame.
_Local = tuple[float, ...]
#: A solved leg: q (3) [rad], cos / sin of the root angle, the inverse Jacobian's rows (9) in the
#: root joint's child frame [rad/m], its determinant [m^3] (see `ScalarLeg.solve`).
Solution = tuple[float, ...]

#: A warm start (the last solution's Newton correction on the new closed form) is used only
#: when it places the foot this close to the target [m]; otherwise the cold start runs. Walking
#: at 100 Hz the warm start misses by < 3e-5 m, the cold start by millimetres.
WARM_START_MISS = 1e-4

_FINAL2 = calibrated.IK_FINAL ** 2
_ACCEPT2 = calibrated.IK_ACCEPT ** 2
_MAX_STEP = calibrated.MAX_STEP
_STEPS = range(calibrated.IK_MAX_STEPS)


def _mat(rotation: object) -> tuple[float, ...]:
    return tuple(float(x) for x in rotation.reshape(-1))  # type: ignore[attr-defined]


def _chain(frames: JointFrames) -> Callable[[float, float, float], _Local]:
    """The chain root yaw (z), shoulder (y), knee (y) of ``frames`` as one function of the
    joint angles [rad], its constants bound once."""
    r1 = _mat(frames.rotations[1])
    r2 = _mat(frames.rotations[2])
    tx, ty, tz = (float(x) for x in frames.foot_tip)
    o1x, o1y, o1z = (float(x) for x in frames.origins[1])
    o2 = [float(x) for x in frames.origins[2]]
    s0, s1, s2 = (float(s) for s in frames.signs)
    # knee: R2 Ry(s2 q2) tip + o2 = c a + s b + m (c, s of s2 q2); d/dq2 = s2 (c b - s a)
    ax, ay, az = (r2[3 * i] * tx + r2[3 * i + 2] * tz for i in range(3))
    bx, by, bz = (r2[3 * i] * tz - r2[3 * i + 2] * tx for i in range(3))
    mx, my, mz = (r2[3 * i + 1] * ty + o2[i] for i in range(3))
    sax, say, saz, sbx, sby, sbz = (s2 * x for x in (ax, ay, az, bx, by, bz))
    e00, e01, e02, e10, e11, e12, e20, e21, e22 = r1
    # shoulder: d/dq1 of R1 Ry(s1 q1) v = s1 R1 (y x Ry v) = s1 R1 (w_z, 0, -w_x)
    f00, f02, f10, f12, f20, f22 = (s1 * x for x in (e00, e02, e10, e12, e20, e22))
    cos, sin = math.cos, math.sin

    def local(q0: float, q1: float, q2: float) -> _Local:
        c, s = cos(s2 * q2), sin(s2 * q2)
        vx, vy, vz = c * ax + s * bx + mx, c * ay + s * by + my, c * az + s * bz + mz
        kx, ky, kz = c * sbx - s * sax, c * sby - s * say, c * sbz - s * saz
        c, s = cos(s1 * q1), sin(s1 * q1)
        wx, wz = c * vx + s * vz, c * vz - s * vx
        gx, gz = c * kx + s * kz, c * kz - s * kx
        ux = e00 * wx + e01 * vy + e02 * wz + o1x
        uy = e10 * wx + e11 * vy + e12 * wz + o1y
        return (cos(s0 * q0), sin(s0 * q0), ux, uy, e20 * wx + e21 * vy + e22 * wz + o1z,
                -s0 * uy, s0 * ux,  # root: s0 z x u (its z component is 0)
                f00 * wz - f02 * wx, f10 * wz - f12 * wx, f20 * wz - f22 * wx,
                e00 * gx + e01 * ky + e02 * gz, e10 * gx + e11 * ky + e12 * gz,
                e20 * gx + e21 * ky + e22 * gz)

    return local


def _inverse(a0: float, a1: float, b0: float, b1: float, b2: float, d0: float, d1: float,
             d2: float) -> tuple[float, ...] | None:
    """Rows of the inverse [rad/m] and the determinant [m^3] of the matrix of columns
    (a0, a1, 0), b, d; None when it is singular (or not a number)."""
    c0 = b1 * d2 - b2 * d1
    c1 = b2 * d0 - b0 * d2
    det = a0 * c0 + a1 * c1
    if not abs(det) > 0.0:
        return None
    inv = 1.0 / det
    return (c0 * inv, c1 * inv, (b0 * d1 - b1 * d0) * inv,
            -a1 * d2 * inv, a0 * d2 * inv, (a1 * d0 - a0 * d1) * inv,
            a1 * b2 * inv, -a0 * b2 * inv, (a0 * b1 - a1 * b0) * inv, det)


class ScalarLeg:
    """One calibrated leg: the chain root yaw (z), shoulder (y), knee (y) of its `JointFrames`.

    `solve` keeps the Newton correction of its last solution (joint angles minus the closed
    form they started from) and starts the next call from the new closed form plus that
    correction (a warm start), since the correction changes little between ticks; the result
    then depends on the previous call at the rounding level only (both starts converge to the
    same solution, ~1e-15 rad apart). A warm start that misses the target by more than
    `WARM_START_MISS` or does not converge is dropped and the cold start runs.
    """

    __slots__ = ("_local", "_origin", "_r0", "_warm")

    def __init__(self, frames: JointFrames) -> None:
        if frames.axes != (2, 1, 1):
            raise KinematicsError(f"the scalar leg chain needs joint axes z, y, y; the leg "
                                  f"geometry has axes {frames.axes}")
        self._local = _chain(frames)
        self._r0 = _mat(frames.rotations[0])
        self._origin = tuple(float(x) for x in frames.origins[0])
        self._warm: _Vec | None = None

    def _to_base(self, c: float, s: float, x: float, y: float, z: float) -> _Vec:
        m = self._r0
        x, y = c * x - s * y, s * x + c * y
        return (m[0] * x + m[1] * y + m[2] * z, m[3] * x + m[4] * y + m[5] * z,
                m[6] * x + m[7] * y + m[8] * z)

    def _from_base(self, c: float, s: float, x: float, y: float, z: float) -> _Vec:
        m = self._r0
        x, y, z = (m[0] * x + m[3] * y + m[6] * z, m[1] * x + m[4] * y + m[7] * z,
                   m[2] * x + m[5] * y + m[8] * z)
        return c * x + s * y, c * y - s * x, z

    def forward(self, q0: float, q1: float, q2: float) -> tuple[_Vec, tuple[_Vec, _Vec, _Vec]]:
        """Foot [m] in base_link and the columns d foot / d q_k [m/rad] of the joint Jacobian."""
        c, s, ux, uy, uz, a0, a1, b0, b1, b2, d0, d1, d2 = self._local(q0, q1, q2)
        foot = self._to_base(c, s, ux, uy, uz)
        o = self._origin
        return ((foot[0] + o[0], foot[1] + o[1], foot[2] + o[2]),
                (self._to_base(c, s, a0, a1, 0.0), self._to_base(c, s, b0, b1, b2),
                 self._to_base(c, s, d0, d1, d2)))

    def solve(self, target: _Vec, closed: _Vec, knee_sign: float) -> Solution | None:
        """Joint angles [rad] placing the foot at ``target`` [m] by Newton steps, warm-started
        (see the class) or from the closed-form ``closed`` as `calibrated.refine` starts;
        None when they do not end within `calibrated.IK_ACCEPT` (the reference then raises).

        The foot error at the returned angles is evaluated, not assumed; that evaluation's
        inverse Jacobian is part of the `Solution` (for `rates_at`)."""
        m, o = self._r0, self._origin
        x, y, z = target[0] - o[0], target[1] - o[1], target[2] - o[2]
        px, py, pz = (m[0] * x + m[3] * y + m[6] * z, m[1] * x + m[4] * y + m[7] * z,
                      m[2] * x + m[5] * y + m[8] * z)
        c0, c1, c2 = closed
        warm = self._warm
        solution = None
        if warm is not None:
            solution = self._newton(px, py, pz, c0 + warm[0], c1 + warm[1], c2 + warm[2],
                                    WARM_START_MISS * WARM_START_MISS)
        if solution is None:
            bend = abs(c2)
            if calibrated.START_KNEE <= bend <= math.pi - calibrated.START_KNEE:
                start = c2
            else:
                start = knee_sign * min(max(bend, calibrated.START_KNEE),
                                        math.pi - calibrated.START_KNEE)
            solution = self._newton(px, py, pz, c0, c1, start, math.inf)
        self._warm = None if solution is None else (
            solution[0] - c0, solution[1] - c1, solution[2] - c2)
        return solution

    def _newton(self, px: float, py: float, pz: float, q0: float, q1: float, q2: float,
                first: float) -> Solution | None:
        """`calibrated.refine`'s steps for the target (px, py, pz) [m] in the root frame (before
        the root joint) from q [rad]; None when the start misses by more than sqrt(first) [m],
        a Jacobian is singular or the end misses by more than `calibrated.IK_ACCEPT`. Stops
        once the error before a step is below `calibrated.IK_FINAL` in the Euclidean norm
        (never earlier than the reference's largest-component test)."""
        local = self._local
        c, s, ux, uy, uz, a0, a1, b0, b1, b2, d0, d1, d2 = local(q0, q1, q2)
        ex, ey, ez = c * px + s * py - ux, c * py - s * px - uy, pz - uz
        miss = ex * ex + ey * ey + ez * ez
        if miss > first:
            return None
        final = False
        for _ in _STEPS:
            inv = _inverse(a0, a1, b0, b1, b2, d0, d1, d2)
            if inv is None:
                return None
            i0, i1, i2, i3, i4, i5, i6, i7, i8, _ = inv
            t0 = i0 * ex + i1 * ey + i2 * ez
            t1 = i3 * ex + i4 * ey + i5 * ez
            t2 = i6 * ex + i7 * ey + i8 * ez
            if not (-_MAX_STEP <= t0 <= _MAX_STEP and -_MAX_STEP <= t1 <= _MAX_STEP
                    and -_MAX_STEP <= t2 <= _MAX_STEP):
                scale = _MAX_STEP / max(abs(t0), abs(t1), abs(t2))
                t0, t1, t2 = t0 * scale, t1 * scale, t2 * scale
            q0, q1, q2 = q0 + t0, q1 + t1, q2 + t2
            final = miss < _FINAL2
            c, s, ux, uy, uz, a0, a1, b0, b1, b2, d0, d1, d2 = local(q0, q1, q2)
            ex, ey, ez = c * px + s * py - ux, c * py - s * px - uy, pz - uz
            miss = ex * ex + ey * ey + ez * ez
            if final:
                break
        if not miss <= _ACCEPT2:
            return None
        inv = _inverse(a0, a1, b0, b1, b2, d0, d1, d2) or (math.nan,) * 10
        return (q0, q1, q2, c, s, *inv)

    def rates_at(self, solution: Solution, v: _Vec) -> _Vec | None:
        """Joint rates [rad/s] for the foot velocity ``v`` [m/s] (base_link) at the angles of
        ``solution``; None where the reference calls the Jacobian singular."""
        (_, _, _, c, s, i0, i1, i2, i3, i4, i5, i6, i7, i8, det) = solution
        if not abs(det) > calibrated.SINGULAR_DET:
            return None
        x, y, z = self._from_base(c, s, v[0], v[1], v[2])
        return i0 * x + i1 * y + i2 * z, i3 * x + i4 * y + i5 * z, i6 * x + i7 * y + i8 * z

    def rates(self, q: _Vec, v: _Vec) -> _Vec | None:
        """Joint rates [rad/s] for the foot velocity ``v`` [m/s] at ``q`` [rad]; None where the
        reference calls the Jacobian singular."""
        c, s, _, _, _, a0, a1, b0, b1, b2, d0, d1, d2 = self._local(*q)
        inv = _inverse(a0, a1, b0, b1, b2, d0, d1, d2)
        return None if inv is None else self.rates_at((*q, c, s, *inv), v)
