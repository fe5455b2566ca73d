"""Per-leg geometry with assembly errors: an MDH-style chain of elementary transforms (pure numpy).

Each leg is a chain of 17 elementary transforms in its leg frame (origin at the nominal hip
of ``robot.yaml``, x along the leg's neutral yaw, z up), one parameter each (`PARAMS`, in
chain order). Joint elements rotate by ``sign * (q + offset)``; the others by / along their
parameter. At the nominal values (lengths from ``robot.yaml``, everything else 0) the chain is
exactly the closed-form leg of `crawler_motion.model.kinematics`:

    hip_x hip_y hip_z  -> root axis position error [m]
    root_tilt_x, root_tilt_y -> root axis misalignment [rad] (rotations about x, y)
    root_offset        -> Rot_z(root + offset): root joint zero offset [rad]
    l1, shoulder_dz    -> coxa length along x, shoulder axis height [m]
    shoulder_twist     -> shoulder axis misalignment about the coxa (x) [rad]
    shoulder_offset    -> Rot_y(-(shoulder + offset)): femur up for shoulder > 0 [rad]
    l2                 -> femur length [m]
    knee_twist, knee_yaw -> knee axis misalignment about the femur (x) and about z [rad]
    knee_offset        -> Rot_y(knee + offset): tibia down for knee > 0 [rad]
    l3, foot_y, foot_z -> foot tip in the tibia frame [m]

Completeness: root -> shoulder are perpendicular axes, so the classic MDH parameters (joint
zero, height along the root axis, common normal l1, twist) describe them; the shoulder and
knee axes are nominally parallel, where MDH's common normal is ill-defined, so the Hayati form
is used: the knee axis is placed by l2 and the shoulder's zero, and its direction needs TWO
misalignment angles, ``knee_twist`` (about the femur) and ``knee_yaw`` (about z, the axis
turning within the femur's plane). Any 3R leg near the nominal one is this chain with some
parameter values. 17 parameters, 15 identifiable from foot positions (4 per joint + 6 for
the foot's frame - 3 for its orientation, which a point does not show): ``shoulder_dz`` is
the same motion as ``hip_z`` and ``foot_z`` as ``knee_offset`` with ``l3``
(docs/calibration.md). Files written before ``knee_yaw`` existed read it as 0.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np


class Op(enum.Enum):
    """What an element of the chain does."""

    TRANSLATE = "translate"
    ROTATE = "rotate"


class Unit(enum.Enum):
    """Kind of a parameter, for units, scaling and the plausibility check."""

    LINK = "link length [m]"
    DISPLACEMENT = "displacement [m]"
    ANGLE = "angle [rad]"


@dataclass(frozen=True)
class ParamDef:
    """One element of the leg chain: its parameter, operation, local axis and joint."""

    name: str
    op: Op
    axis: int  # 0 x, 1 y, 2 z (in the frame before the element)
    unit: Unit
    joint: int | None = None  # 0 root, 1 shoulder, 2 knee: a joint element
    sign: float = 1.0  # joint elements: angle = sign * (q + offset)


_T, _R = Op.TRANSLATE, Op.ROTATE
_L, _D, _A = Unit.LINK, Unit.DISPLACEMENT, Unit.ANGLE
#: The chain, in order; the parameter vector of a leg has this order.
PARAMS: tuple[ParamDef, ...] = (
    ParamDef("hip_x", _T, 0, _D), ParamDef("hip_y", _T, 1, _D), ParamDef("hip_z", _T, 2, _D),
    ParamDef("root_tilt_x", _R, 0, _A), ParamDef("root_tilt_y", _R, 1, _A),
    ParamDef("root_offset", _R, 2, _A, joint=0),
    ParamDef("l1", _T, 0, _L), ParamDef("shoulder_dz", _T, 2, _D),
    ParamDef("shoulder_twist", _R, 0, _A),
    ParamDef("shoulder_offset", _R, 1, _A, joint=1, sign=-1.0),
    ParamDef("l2", _T, 0, _L), ParamDef("knee_twist", _R, 0, _A),
    ParamDef("knee_yaw", _R, 2, _A),
    ParamDef("knee_offset", _R, 1, _A, joint=2),
    ParamDef("l3", _T, 0, _L), ParamDef("foot_y", _T, 1, _D), ParamDef("foot_z", _T, 2, _D),
)
NAMES: tuple[str, ...] = tuple(p.name for p in PARAMS)
N_PARAMS = len(PARAMS)
INDEX: dict[str, int] = {name: i for i, name in enumerate(NAMES)}
#: Element index of each joint (root, shoulder, knee).
JOINT_ELEMENTS: tuple[int, ...] = tuple(
    next(i for i, p in enumerate(PARAMS) if p.joint == j) for j in range(3))
#: Plausibility limits of a calibration: a link may differ from robot.yaml by this fraction,
#: an angle by this much [rad], a displacement by this fraction of the nominal l1.
MAX_LINK_FRACTION = 0.10
MAX_ANGLE = math.radians(10.0)
MAX_DISPLACEMENT_FRACTION = 0.10


def nominal_params(l1: float, l2: float, l3: float) -> np.ndarray:
    """The parameter vector ``(N_PARAMS,)`` of the nominal leg with links l1, l2, l3 [m]."""
    params = np.zeros(N_PARAMS)
    params[[INDEX["l1"], INDEX["l2"], INDEX["l3"]]] = (l1, l2, l3)
    return params


def implausible(params: np.ndarray, nominal: np.ndarray) -> list[str]:
    """Reasons (empty when plausible) why ``params`` cannot be a real leg of ``nominal``."""
    reasons = []
    l1 = float(nominal[INDEX["l1"]])
    for k, p in enumerate(PARAMS):
        value, nom = float(params[k]), float(nominal[k])
        if not math.isfinite(value):
            reasons.append(f"{p.name} is not a finite number ({value})")
        elif p.unit is Unit.LINK and abs(value - nom) > MAX_LINK_FRACTION * nom:
            reasons.append(f"{p.name} = {value:.6g} m is more than "
                           f"{MAX_LINK_FRACTION:.0%} from the nominal {nom:.6g} m")
        elif p.unit is Unit.ANGLE and abs(value) > MAX_ANGLE:
            reasons.append(f"{p.name} = {math.degrees(value):.3g} deg is beyond "
                           f"±{math.degrees(MAX_ANGLE):.0f} deg")
        elif p.unit is Unit.DISPLACEMENT and abs(value) > MAX_DISPLACEMENT_FRACTION * l1:
            limit = MAX_DISPLACEMENT_FRACTION * l1
            reasons.append(f"{p.name} = {value:.6g} m is beyond ±{limit:.4g} m "
                           f"({MAX_DISPLACEMENT_FRACTION:.0%} of l1)")
    return reasons


def _rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    """Rotations ``(..., 3, 3)`` about the x / y / z axis by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros((*np.shape(angle), 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i] = c
    out[..., j, j] = c
    out[..., i, j] = -s
    out[..., j, i] = s
    return out


def leg_chain(params: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Foot position in the leg frame and its Jacobian w.r.t. the parameters.

    ``params`` ``(..., N_PARAMS)`` and joint angles ``q`` ``(..., 3)`` [rad] broadcast together
    to the batch shape B. Returns the foot ``(*B, 3)`` [m] and ``d foot / d params``
    ``(*B, 3, N_PARAMS)`` (m per m, m per rad). The joint Jacobian ``d foot / d q`` is the
    columns `JOINT_ELEMENTS` multiplied by the joints' signs (see `joint_jacobian`).
    """
    params = np.asarray(params, dtype=float)
    q = np.asarray(q, dtype=float)
    batch = np.broadcast_shapes(params.shape[:-1], q.shape[:-1])
    rot = np.broadcast_to(np.eye(3), (*batch, 3, 3))
    origin = np.zeros((*batch, 3))
    axes, origins = [], []
    for k, p in enumerate(PARAMS):
        value = params[..., k]
        if p.joint is not None:
            value = p.sign * (q[..., p.joint] + value)
        value = np.broadcast_to(value, batch)
        direction = rot[..., :, p.axis]
        axes.append(direction)
        origins.append(origin)
        if p.op is Op.TRANSLATE:
            origin = origin + direction * value[..., None]
        else:
            rot = rot @ _rotation(p.axis, value)
    foot = origin
    cols = []
    for k, p in enumerate(PARAMS):
        if p.op is Op.TRANSLATE:
            cols.append(axes[k])
        else:
            cols.append(p.sign * np.cross(axes[k], foot - origins[k]))
    return foot, np.stack(cols, axis=-1)


def joint_jacobian(param_jacobian: np.ndarray) -> np.ndarray:
    """``d foot / d q`` ``(..., 3, 3)`` from the parameter Jacobian of `leg_chain`: a joint
    angle enters its element exactly as the element's offset does."""
    return param_jacobian[..., JOINT_ELEMENTS]


def to_base(foot_leg: np.ndarray, hip: np.ndarray, neutral_yaw: float) -> np.ndarray:
    """Leg-frame vectors ``(..., 3)`` [m] to base_link: rotate by the neutral yaw, then add the
    nominal hip ``(3,)`` [m] (pass ``hip = 0`` for directions / Jacobian columns)."""
    c, s = math.cos(neutral_yaw), math.sin(neutral_yaw)
    x, y = foot_leg[..., 0], foot_leg[..., 1]
    return np.stack((c * x - s * y, s * x + c * y, foot_leg[..., 2]), axis=-1) + hip


def to_leg(foot_base: np.ndarray, hip: np.ndarray, neutral_yaw: float) -> np.ndarray:
    """base_link positions ``(..., 3)`` [m] to the leg frame (inverse of `to_base`)."""
    d = np.asarray(foot_base, dtype=float) - hip
    c, s = math.cos(neutral_yaw), math.sin(neutral_yaw)
    return np.stack((c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1], d[..., 2]),
                    axis=-1)


@dataclass(frozen=True)
class JointFrames:
    """A leg's chain as fixed frames between its joints (for the URDF, the simulator's model
    and the scalar fast path).

    foot = o0 + R0 J0(q0) (o1 + R1 J1(q1) (o2 + R2 J2(q2) foot_tip)), where ``Jk(qk)`` is the
    rotation by ``signs[k] * qk`` about local axis ``axes[k]`` and ``(Rk, ok)`` is joint k's
    frame at q = 0 in its parent's (base_link for the root joint; the joint zero offsets are
    part of ``Rk``). Rotations ``(3, 3)``, origins and ``foot_tip`` ``(3,)`` [m].
    """

    rotations: tuple[np.ndarray, np.ndarray, np.ndarray]
    origins: tuple[np.ndarray, np.ndarray, np.ndarray]
    foot_tip: np.ndarray
    axes: tuple[int, int, int]
    signs: tuple[float, float, float]


def joint_frames(params: np.ndarray, hip: np.ndarray, neutral_yaw: float) -> JointFrames:
    """The fixed frames of the chain ``params`` ``(N_PARAMS,)`` whose leg frame sits at the
    nominal ``hip`` ``(3,)`` [m] turned by ``neutral_yaw`` [rad] in base_link."""
    rot = _rotation(2, np.float64(neutral_yaw))
    origin = np.asarray(hip, dtype=float).copy()
    rotations, origins = [], []
    for k, p in enumerate(PARAMS):
        value = float(params[k])
        if p.joint is not None:  # the offset rotates like the joint: fold it into the frame
            rotations.append(rot @ _rotation(p.axis, np.float64(p.sign * value)))
            origins.append(origin)
            rot, origin = np.eye(3), np.zeros(3)
        elif p.op is Op.TRANSLATE:
            origin = origin + rot[:, p.axis] * value
        else:
            rot = rot @ _rotation(p.axis, np.float64(value))
    joints = [PARAMS[k] for k in JOINT_ELEMENTS]
    return JointFrames(tuple(rotations), tuple(origins), origin,  # type: ignore[arg-type]
                       tuple(p.axis for p in joints),  # type: ignore[arg-type]
                       tuple(p.sign for p in joints))  # type: ignore[arg-type]


def frames_forward(frames: JointFrames, q: np.ndarray) -> np.ndarray:
    """Foot ``(3,)`` [m] in base_link through ``frames`` at joint angles ``q`` ``(3,)`` [rad]
    (the composition `JointFrames` documents; tests compare it with `leg_chain`)."""
    point = frames.foot_tip
    for k in (2, 1, 0):
        joint = _rotation(frames.axes[k], np.float64(frames.signs[k] * float(q[k])))
        point = frames.origins[k] + frames.rotations[k] @ (joint @ point)
    return point
