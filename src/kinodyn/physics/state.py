"""Character state as arrays for learning: bodies, centre of mass, foot contacts.

The fast dynamic-response paper (section 4.2) classifies reactions from "the 6 degree-of-freedom state
(with state derivative) for the bodies of the simulation along the spine (pelvis, stomach, chest, head)",
"the state of the feet and the position and velocity of the center of mass" sampled at 0, 0.1, 0.2 and
0.3 s after the collision. :class:`CharacterState` holds all of it for every segment; :meth:`vector`
flattens a chosen subset into a feature vector, and :func:`states_from_qpos` does the same for a whole
batch of rollout states at once.

Shapes: ``B`` segments, ``(..., B, 3)`` positions and velocities (m, m/s, rad/s, world frame),
``(..., B, 4)`` orientations ``(w, x, y, z)``, ``(..., 2)`` foot contacts (left, right).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from kinodyn.errors import ParameterError

__all__ = ["FEATURE_PARTS", "CharacterState", "character_state", "states_from_qpos"]

#: Parts of a feature vector, in order, and their widths per body (or in total for com/feet).
FEATURE_PARTS = ("pos", "quat", "linvel", "angvel", "com", "com_vel", "feet")


@dataclass(frozen=True)
class CharacterState:
    """State of one character at one instant (world frame).

    Attributes:
        time: world time (s).
        names: ``B`` segment names.
        pos: ``(B, 3)`` body origins (the joints).
        quat: ``(B, 4)`` body orientations.
        linvel: ``(B, 3)`` linear velocity of each body origin.
        angvel: ``(B, 3)`` angular velocity of each body.
        com: ``(3,)`` centre of mass; com_vel: ``(3,)`` its velocity.
        feet: ``(2,)`` bool, left and right foot touching something other than the character itself.
    """

    time: float
    names: tuple[str, ...]
    pos: np.ndarray
    quat: np.ndarray
    linvel: np.ndarray
    angvel: np.ndarray
    com: np.ndarray
    com_vel: np.ndarray
    feet: np.ndarray

    def vector(self, bodies=None, parts=FEATURE_PARTS, relative: bool = True) -> np.ndarray:
        """A flat float feature vector.

        Args:
            bodies: segment indices or names to include (default all).
            parts: which of :data:`FEATURE_PARTS` to include, in that order.
            relative: express positions relative to the centre of mass's floor point (x, y of the com,
                z = 0), so features do not depend on where the character stands.
        """
        idx = _body_index(self.names, bodies)
        origin = np.array([self.com[0], self.com[1], 0.0]) if relative else np.zeros(3)
        out = []
        for part in parts:
            if part == "pos":
                out.append((self.pos[idx] - origin).ravel())
            elif part == "quat":
                q = self.quat[idx]
                out.append(np.where(q[:, :1] < 0, -q, q).ravel())
            elif part == "linvel":
                out.append(self.linvel[idx].ravel())
            elif part == "angvel":
                out.append(self.angvel[idx].ravel())
            elif part == "com":
                out.append(self.com - origin)
            elif part == "com_vel":
                out.append(self.com_vel)
            elif part == "feet":
                out.append(self.feet.astype(np.float64))
            else:
                raise ParameterError(f"unknown feature part {part!r}; parts: {', '.join(FEATURE_PARTS)}")
        return np.concatenate(out) if out else np.zeros(0)


def _body_index(names, bodies) -> np.ndarray:
    if bodies is None:
        return np.arange(len(names))
    out = []
    for b in bodies:
        if isinstance(b, (int, np.integer)):
            out.append(int(b))
        elif b in names:
            out.append(names.index(b))
        else:
            raise ParameterError(f"no segment {b!r}; segments: {', '.join(names)}")
    return np.array(out, dtype=np.int64)


def _velocities(model, data, ids):
    """Linear velocity of each body origin and angular velocity (world), from ``cvel``."""
    cvel = data.cvel[ids]
    root_com = data.subtree_com[model.body_rootid[ids]]
    ang = cvel[:, :3]
    lin = cvel[:, 3:] + np.cross(ang, data.xpos[ids] - root_com)
    return lin, ang


def _feet(model, data, char) -> np.ndarray:
    out = np.zeros(2, dtype=bool)
    feet = char.map.feet
    n = data.ncon
    if n == 0 or not feet:
        return out
    g1 = data.contact.geom1[:n]
    g2 = data.contact.geom2[:n]
    b1 = model.geom_bodyid[g1]
    b2 = model.geom_bodyid[g2]
    mine = {int(b) for b in char.body_ids}
    for k, side in enumerate(("left", "right")):
        if side not in feet:
            continue
        fb = int(char.body_ids[feet[side]])
        hit = ((b1 == fb) & ~np.isin(b2, list(mine))) | ((b2 == fb) & ~np.isin(b1, list(mine)))
        out[k] = bool(np.any(hit & (data.contact.dist[:n] < 1e-3)))
    return out


def character_state(world, char) -> CharacterState:
    """The current :class:`CharacterState` of ``char`` in ``world``.

    Recomputes positions and velocities from ``qpos``/``qvel`` (cheap: kinematics, com and com
    velocity only); foot contacts come from the contacts of the last step.
    """
    m, d = world.model, world.data
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    mujoco.mj_comVel(m, d)
    ids = char.body_ids
    lin, ang = _velocities(m, d, ids)
    mass = m.body_mass[ids]
    com = (d.xipos[ids] * mass[:, None]).sum(axis=0) / mass.sum()
    cv_lin = d.cvel[ids, 3:] + np.cross(d.cvel[ids, :3], d.xipos[ids] - d.subtree_com[m.body_rootid[ids]])
    com_vel = (cv_lin * mass[:, None]).sum(axis=0) / mass.sum()
    return CharacterState(time=world.time, names=char.map.names, pos=d.xpos[ids].copy(), quat=d.xquat[ids].copy(),
                          linvel=lin, angvel=ang.copy(), com=com, com_vel=com_vel, feet=_feet(m, d, char))


def states_from_qpos(world, char, qpos: np.ndarray, qvel: np.ndarray, mocap=None, contacts: bool = True) -> dict:
    """Batched states of ``char`` for world-sized ``qpos (..., nq)`` and ``qvel (..., nv)`` (for instance
    rollout output). Returns a dict of arrays: ``pos (..., B, 3)``, ``quat (..., B, 4)``,
    ``linvel``, ``angvel (..., B, 3)``, ``com``, ``com_vel (..., 3)``, ``feet (..., 2)`` (from collision
    detection when ``contacts``)."""
    m = world.model
    qpos = np.asarray(qpos, dtype=np.float64)
    qvel = np.asarray(qvel, dtype=np.float64)
    lead = qpos.shape[:-1]
    if qpos.shape[-1] != m.nq or qvel.shape[-1] != m.nv or qvel.shape[:-1] != lead:
        raise ParameterError(f"qpos/qvel must be (..., {m.nq}) and (..., {m.nv}) with the same leading shape, "
                             f"got {qpos.shape} and {qvel.shape}")
    qp = qpos.reshape(-1, m.nq)
    qv = qvel.reshape(-1, m.nv)
    d = mujoco.MjData(m)
    d.mocap_pos[:] = world.data.mocap_pos
    d.mocap_quat[:] = world.data.mocap_quat
    ids = char.body_ids
    nb = len(ids)
    n = len(qp)
    out = {k: np.zeros((n, nb, w)) for k, w in (("pos", 3), ("quat", 4), ("linvel", 3), ("angvel", 3))}
    out["com"] = np.zeros((n, 3))
    out["com_vel"] = np.zeros((n, 3))
    out["feet"] = np.zeros((n, 2), dtype=bool)
    mass = m.body_mass[ids]
    for i in range(n):
        d.qpos[:] = qp[i]
        d.qvel[:] = qv[i]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        lin, ang = _velocities(m, d, ids)
        out["pos"][i] = d.xpos[ids]
        out["quat"][i] = d.xquat[ids]
        out["linvel"][i] = lin
        out["angvel"][i] = ang
        out["com"][i] = (d.xipos[ids] * mass[:, None]).sum(axis=0) / mass.sum()
        cv = d.cvel[ids, 3:] + np.cross(d.cvel[ids, :3], d.xipos[ids] - d.subtree_com[m.body_rootid[ids]])
        out["com_vel"][i] = (cv * mass[:, None]).sum(axis=0) / mass.sum()
        if contacts:
            mujoco.mj_collision(m, d)
            out["feet"][i] = _feet(m, d, char)
    return {k: v.reshape(lead + v.shape[1:]) for k, v in out.items()}
