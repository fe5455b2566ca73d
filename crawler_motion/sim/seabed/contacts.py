"""Contact forces between the robot and the world, read from a MuJoCo state."""

from __future__ import annotations

import mujoco
import numpy as np

from crawler_motion.sim.seabed.model import SeabedModel


def normal_forces(sm: SeabedModel, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """Geom pairs ``(ncon, 2)`` of the active contacts and their normal forces [N]."""
    n = data.ncon
    forces = np.zeros(n)
    if n == 0:
        return np.zeros((0, 2), dtype=int), forces
    if sm.model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC:
        forces[:] = data.efc_force[data.contact.efc_address[:n]]  # first row: the normal
    else:
        wrench = np.zeros(6)
        for i in range(n):
            mujoco.mj_contactForce(sm.model, data, i, wrench)
            forces[i] = wrench[0]
    return np.array(data.contact.geom[:n]), forces


def foot_loads(sm: SeabedModel, data: mujoco.MjData) -> np.ndarray:
    """Normal force on each foot sphere ``(n_legs,)`` [N] (sum over its contacts)."""
    geoms, forces = normal_forces(sm, data)
    hit = geoms[:, :, None] == sm.foot_geoms[None, None, :]  # (ncon, 2, n_legs)
    return (hit.any(axis=1) * forces[:, None]).sum(axis=0)


def body_touches(sm: SeabedModel, data: mujoco.MjData) -> np.ndarray:
    """The ``(body geom, world geom)`` pairs ``(k, 2)`` of the active contacts where the hull
    or a leg link (anything but a foot) touches the world (the seabed, a box, a rock)."""
    geoms = np.asarray(data.contact.geom[:data.ncon]).reshape(-1, 2)
    body = np.isin(geoms, sm.body_geoms)
    one = body[:, 0] != body[:, 1]  # one side the robot's body, the other the world
    return np.where(body[one, :1], geoms[one], geoms[one, ::-1])


def body_contact(sm: SeabedModel, data: mujoco.MjData) -> bool:
    """True when the hull or a leg link (anything but a foot) touches the world."""
    return len(body_touches(sm, data)) > 0


def robot_load(sm: SeabedModel, data: mujoco.MjData) -> float:
    """Total normal force of the world on the robot [N]."""
    geoms, forces = normal_forces(sm, data)
    return float(forces[np.isin(geoms, sm.robot_geoms).any(axis=1)].sum())
