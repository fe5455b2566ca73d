"""Calibrated legs in plain floats: forward kinematics, joint Jacobian, Newton refinement of the
IK and joint rates of one leg at one instant, for the per-tick fast path.

Evaluates the fixed frames of `crawler_motion.model.leg_geometry.joint_frames` (the same
frames the URDF and the simulator's model are built from) with `math` on Python floats; the
numpy reference is `crawler_motion.model.calibrated` (through `leg_geometry.leg_chain`), and
`test/motion/test_fastchain.py` compares the two. Newton settings are the reference's
(`calibrated.IK_MAX_STEPS`, `START_KNEE`, `MAX_STEP`); a leg this module cannot solve returns
None and the caller asks the reference, which raises its own error.

Stopping rule (the reference instead evaluates the foot error after every step): a Newton
step t = J(q)^-1 e from angles q (e the foot error there) ends at most
``reach / 2 * (|t0| + |t1| + |t2|)^2 <= 3 / 2 * reach * |t|^2`` from the target (Taylor's
remainder: each second derivative of the foot w.r.t. two joint angles is a double cross
product with unit axes and a lever no longer than ``reach``, the sum of the lengths of the
link vectors after the root joint; rounding adds ~1e-17 m). The refinement ends with the
first step whose bound is within `STEP_BOUND`, without evaluating the chain again; that last
evaluation's Jacobian, at most |t| <= ~2e-4 rad from the returned angles, also gives the
joint rates.

Per tick one chain evaluation per leg is then usually all: `ScalarLeg.warm` starts from the
last solution plus the last Jacobian's step to the new target plus the part of the last such
prediction its Newton step corrected (which changes little from tick to tick). Walking at
100 Hz that start misses by ~1e-6 m (median; the nominal closed form: by millimetres). The
chain is evaluated in the frame of the root joint's child (`_chain`), with the constants of
each leg folded in once; the target is turned into that frame instead of the Jacobian into
base_link. Numpy across the four legs would not pay: each of the ~60 operations of a chain
evaluation would be a ufunc call on 4 values (~0.25 us; ~15 us per evaluation of all legs)
where four float evaluations take ~3.2 us.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from crawler_motion.errors import KinematicsError
from crawler_motion.model import calibrated
from crawler_motion.model.leg_geometry import JointFrames

__all__ = ["STEP_BOUND", "WARM_START_MISS", "ScalarLeg"]

_Vec = tuple[float, float, float]
#: `_chain`'s result: cos, sin of the root angle (times its sign); foot u [m] and the Jacobian
#: columns d u / d q_k [m/rad] (k = root, shoulder, knee), all in the root joint's child frame.
_Local = tuple[float, ...]

#: The refinement ends with a Newton step that provably ends this close to the target [m]
#: (the reference accepts `calibrated.IK_ACCEPT`, 1e-7 m; the issue asks < 1e-6 m).
STEP_BOUND = 1e-8
#: A warm start is used only when it places the foot this close to the target [m]; otherwise
#: the cold start (from the nominal closed form) runs.
WARM_START_MISS = 1e-4

_WARM2 = WARM_START_MISS ** 2
_MAX_STEP = calibrated.MAX_STEP
_SINGULAR = calibrated.SINGULAR_DET
_STEPS = range(calibrated.IK_MAX_STEPS)
_ZERO = (0.0, 0.0, 0.0)


def _mat(rotation: object) -> tuple[float, ...]:
    return tuple(float(x) for x in rotation.reshape(-1))  # type: ignore[attr-defined]


def _norm(v: object) -> float:
    return math.sqrt(sum(float(x) ** 2 for x in v))  # type: ignore[attr-defined]


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

    Keeps its last solution between calls (angles, target, the inverse Jacobian of the last
    evaluation, the correction of the last prediction), from which `warm` predicts the next
    one; a result therefore depends on the previous call, within `STEP_BOUND` of the target.
    A prediction missing the target by more than `WARM_START_MISS` is dropped (the caller runs
    `cold`); a failed solve forgets the state.
    """

    __slots__ = ("_bound", "_frame", "_local", "_origin", "_r0", "_state")

    def __init__(self, frames: JointFrames) -> None:
        if frames.axes != (2, 1, 1):
            raise KinematicsError(f"the scalar leg chain needs joint axes z, y, y; the leg "
                                  f"geometry has axes {frames.axes}")
        self._local = _chain(frames)
        self._r0 = _mat(frames.rotations[0])
        self._origin = tuple(float(x) for x in frames.origins[0])
        self._frame = (*self._origin, *self._r0)
        reach = _norm(frames.origins[1]) + _norm(frames.origins[2]) + _norm(frames.foot_tip)
        #: largest t0^2 + t1^2 + t2^2 [rad^2] of a last step: then (|t0| + |t1| + |t2|)^2 <=
        #: 2 STEP_BOUND / reach (see the module docstring)
        self._bound = 2.0 * STEP_BOUND / reach / 3.0
        #: q (3) [rad], target in the root frame (3) [m], correction of the linear prediction
        #: (3) [rad]; cos / sin of the root angle, the inverse Jacobian's rows (9) [rad/m] and
        #: determinant [m^3] of the last evaluation (root joint's child frame); None: no state
        self._state: tuple[float, ...] | None = None

    def _to_base(self, c: float, s: float, x: float, y: float, z: float) -> _Vec:
        m = self._r0
        x, y = c * x - s * y, s * x + c * y
        return (m[0] * x + m[1] * y + m[2] * z, m[3] * x + m[4] * y + m[5] * z,
                m[6] * x + m[7] * y + m[8] * z)

    def _root_frame(self, x: float, y: float, z: float) -> _Vec:
        """base_link position [m] in the root joint's frame (before its rotation)."""
        ox, oy, oz, m0, m1, m2, m3, m4, m5, m6, m7, m8 = self._frame
        x, y, z = x - ox, y - oy, z - oz
        return m0 * x + m3 * y + m6 * z, m1 * x + m4 * y + m7 * z, m2 * x + m5 * y + m8 * z

    def forward(self, q0: float, q1: float, q2: float) -> tuple[_Vec, tuple[_Vec, _Vec, _Vec]]:
        """Foot [m] in base_link and the columns d foot / d q_k [m/rad] of the joint Jacobian."""
        c, s, ux, uy, uz, a0, a1, b0, b1, b2, d0, d1, d2 = self._local(q0, q1, q2)
        foot = self._to_base(c, s, ux, uy, uz)
        o = self._origin
        return ((foot[0] + o[0], foot[1] + o[1], foot[2] + o[2]),
                (self._to_base(c, s, a0, a1, 0.0), self._to_base(c, s, b0, b1, b2),
                 self._to_base(c, s, d0, d1, d2)))

    def warm(self, x: float, y: float, z: float) -> _Vec | None:
        """Joint angles [rad] placing the foot within `STEP_BOUND` of (x, y, z) [m, base_link],
        started from the last solution (see the class); None without one, when the start
        misses by more than `WARM_START_MISS` or the refinement fails.

        Inlines `_inverse` and `_newton`'s first iteration: all a tick usually needs."""
        state = self._state
        if state is None:
            return None
        (q0, q1, q2, lx, ly, lz, k0, k1, k2, c, s, i0, i1, i2, i3, i4, i5, i6, i7, i8,
         _) = state
        ox, oy, oz, m0, m1, m2, m3, m4, m5, m6, m7, m8 = self._frame
        x, y, z = x - ox, y - oy, z - oz
        px, py, pz = m0 * x + m3 * y + m6 * z, m1 * x + m4 * y + m7 * z, m2 * x + m5 * y + m8 * z
        dx, dy, dz = px - lx, py - ly, pz - lz
        dx, dy = c * dx + s * dy, c * dy - s * dx
        q0 += i0 * dx + i1 * dy + i2 * dz  # the last Jacobian's step to the new target ...
        q1 += i3 * dx + i4 * dy + i5 * dz
        q2 += i6 * dx + i7 * dy + i8 * dz
        s0, s1, s2 = q0 + k0, q1 + k1, q2 + k2  # ... plus what it missed last time
        c, s, ux, uy, uz, a0, a1, b0, b1, b2, d0, d1, d2 = self._local(s0, s1, s2)
        ex, ey, ez = c * px + s * py - ux, c * py - s * px - uy, pz - uz
        if not ex * ex + ey * ey + ez * ez <= _WARM2:
            self._state = None
            return None
        c0 = b1 * d2 - b2 * d1  # as `_inverse`
        c1 = b2 * d0 - b0 * d2
        det = a0 * c0 + a1 * c1
        if abs(det) > 0.0:
            inv = 1.0 / det
            i0, i1, i2 = c0 * inv, c1 * inv, (b0 * d1 - b1 * d0) * inv
            i3, i4, i5 = -a1 * d2 * inv, a0 * d2 * inv, (a1 * d0 - a0 * d1) * inv
            i6, i7, i8 = a1 * b2 * inv, -a0 * b2 * inv, (a0 * b1 - a1 * b0) * inv
            t0 = i0 * ex + i1 * ey + i2 * ez
            t1 = i3 * ex + i4 * ey + i5 * ez
            t2 = i6 * ex + i7 * ey + i8 * ez
            if t0 * t0 + t1 * t1 + t2 * t2 <= self._bound:  # also false for NaN
                s0, s1, s2 = s0 + t0, s1 + t1, s2 + t2
                self._state = (s0, s1, s2, px, py, pz, s0 - q0, s1 - q1, s2 - q2,
                               c, s, i0, i1, i2, i3, i4, i5, i6, i7, i8, det)
                return s0, s1, s2
            largest = max(abs(t0), abs(t1), abs(t2))
            if largest > _MAX_STEP:
                scale = _MAX_STEP / largest
                t0, t1, t2 = t0 * scale, t1 * scale, t2 * scale
            return self._newton(px, py, pz, s0 + t0, s1 + t1, s2 + t2, math.inf, (q0, q1, q2))
        self._state = None
        return None

    def cold(self, x: float, y: float, z: float, closed: _Vec, knee_sign: float
             ) -> _Vec | None:
        """Joint angles [rad] placing the foot within `STEP_BOUND` of (x, y, z) [m, base_link]
        by Newton steps from the closed form ``closed`` of the nominal leg, its knee kept
        `calibrated.START_KNEE` from straight / folded as `calibrated.refine` starts; None
        when they fail (the reference then raises)."""
        c0, c1, c2 = closed
        bend = abs(c2)
        if not calibrated.START_KNEE <= bend <= math.pi - calibrated.START_KNEE:
            c2 = knee_sign * min(max(bend, calibrated.START_KNEE),
                                 math.pi - calibrated.START_KNEE)
        px, py, pz = self._root_frame(x, y, z)
        return self._newton(px, py, pz, c0, c1, c2, math.inf, None)

    def _newton(self, px: float, py: float, pz: float, q0: float, q1: float, q2: float,
                first: float, linear: _Vec | None) -> _Vec | None:
        """Newton steps to the target (px, py, pz) [m] in the root frame from q [rad], ending
        with the first step whose bound is within `STEP_BOUND` (module docstring); None when
        the start misses by more than sqrt(first) [m], a Jacobian is singular or the steps
        run out. Keeps the state `warm` needs (cleared on failure), with the correction of
        the ``linear`` prediction (zero for a cold start)."""
        local, bound = self._local, self._bound
        self._state = None
        c, s, ux, uy, uz, a0, a1, b0, b1, b2, d0, d1, d2 = local(q0, q1, q2)
        ex, ey, ez = c * px + s * py - ux, c * py - s * px - uy, pz - uz
        if not ex * ex + ey * ey + ez * ez <= first:
            return None
        for _ in _STEPS:
            inv = _inverse(a0, a1, b0, b1, b2, d0, d1, d2)
            if inv is None:
                return None
            i0, i1, i2, i3, i4, i5, i6, i7, i8, _ = inv
            t0 = i0 * ex + i1 * ey + i2 * ez
            t1 = i3 * ex + i4 * ey + i5 * ez
            t2 = i6 * ex + i7 * ey + i8 * ez
            if t0 * t0 + t1 * t1 + t2 * t2 <= bound:  # also false for NaN
                q0, q1, q2 = q0 + t0, q1 + t1, q2 + t2
                k0, k1, k2 = _ZERO if linear is None else (
                    q0 - linear[0], q1 - linear[1], q2 - linear[2])
                self._state = (q0, q1, q2, px, py, pz, k0, k1, k2, c, s, *inv)
                return q0, q1, q2
            largest = max(abs(t0), abs(t1), abs(t2))
            if largest > _MAX_STEP:
                scale = _MAX_STEP / largest
                t0, t1, t2 = t0 * scale, t1 * scale, t2 * scale
            q0, q1, q2 = q0 + t0, q1 + t1, q2 + t2
            c, s, ux, uy, uz, a0, a1, b0, b1, b2, d0, d1, d2 = local(q0, q1, q2)
            ex, ey, ez = c * px + s * py - ux, c * py - s * px - uy, pz - uz
        return None

    def rates_last(self, vx: float, vy: float, vz: float) -> _Vec | None:
        """Joint rates [rad/s] for the foot velocity (vx, vy, vz) [m/s] (base_link) through the
        Jacobian of the last solve's last evaluation (within a `STEP_BOUND` step of the angles
        it returned); None without a solution or where the reference calls it singular.
        Inlines `_apply` on purpose: the call with 15 arguments costs 1.5 us of the 20 us tick
        (measured with `crawler-motion bench`); `test_fastchain` holds both to the reference."""
        state = self._state
        if state is None:
            return None
        (_, _, _, _, _, _, _, _, _, c, s, i0, i1, i2, i3, i4, i5, i6, i7, i8, det) = state
        if not abs(det) > _SINGULAR:
            return None
        _, _, _, m0, m1, m2, m3, m4, m5, m6, m7, m8 = self._frame
        x, y, z = m0 * vx + m3 * vy + m6 * vz, m1 * vx + m4 * vy + m7 * vz, \
            m2 * vx + m5 * vy + m8 * vz
        x, y = c * x + s * y, c * y - s * x
        return i0 * x + i1 * y + i2 * z, i3 * x + i4 * y + i5 * z, i6 * x + i7 * y + i8 * z

    def rates(self, q: _Vec, v: _Vec) -> _Vec | None:
        """Joint rates [rad/s] for the foot velocity ``v`` [m/s] at ``q`` [rad]; None where the
        reference calls the Jacobian singular."""
        c, s, _, _, _, a0, a1, b0, b1, b2, d0, d1, d2 = self._local(*q)
        inv = _inverse(a0, a1, b0, b1, b2, d0, d1, d2)
        return None if inv is None else self._apply(c, s, *inv, *v)

    def _apply(self, c: float, s: float, i0: float, i1: float, i2: float, i3: float,
               i4: float, i5: float, i6: float, i7: float, i8: float, det: float, vx: float,
               vy: float, vz: float) -> _Vec | None:
        """Rates [rad/s] for (vx, vy, vz) [m/s] through an inverse Jacobian (see `_state`)."""
        if not abs(det) > _SINGULAR:
            return None
        _, _, _, m0, m1, m2, m3, m4, m5, m6, m7, m8 = self._frame
        x, y, z = m0 * vx + m3 * vy + m6 * vz, m1 * vx + m4 * vy + m7 * vz, \
            m2 * vx + m5 * vy + m8 * vz
        x, y = c * x + s * y, c * y - s * x
        return i0 * x + i1 * y + i2 * z, i3 * x + i4 * y + i5 * z, i6 * x + i7 * y + i8 * z
