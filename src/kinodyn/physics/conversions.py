"""Conversions between skeleton poses and a character body's MuJoCo blocks, through its BodyMap.

Skeleton local rotations ``(..., J, 4)`` become per-segment joint rotations (merged joints folded into the
next kept joint below them), the character's ``qpos`` block (free root position and quaternion, a
quaternion per ball joint, the swing-twist angle of a hinge about its axis) and the servo targets
(:mod:`kinodyn.physics.tracking`); :func:`qpos_to_local_rot` goes back. The map is a
:class:`kinodyn.physics.body.BodyMap`.

Shapes: ``J`` skeleton joints, ``B`` segments; ``nq``/``nu`` the character's blocks. Rotations are
``(w, x, y, z)``.
"""

from __future__ import annotations

import numpy as np

from kinodyn.errors import MotionError
from kinodyn.math import quat
from kinodyn.skeleton import Skeleton

__all__ = ["body_rotations", "check_skeleton", "motion_to_qpos", "pose_to_ctrl", "qpos_to_local_rot"]


def check_skeleton(bmap, skeleton: Skeleton, what: str = "motion") -> None:
    """Raise :class:`MotionError` when ``skeleton`` is not the one the body was built for."""
    if skeleton is bmap.skeleton:
        return
    if not bmap.skeleton.same_topology(skeleton):
        raise MotionError(
            f"the {what} is for another skeleton ({skeleton.num_joints} joints, root {skeleton.names[0]!r}) "
            f"than the character's ({bmap.skeleton.num_joints} joints, root {bmap.skeleton.names[0]!r}); "
            "retarget it first")


def body_rotations(bmap, local_rot: np.ndarray) -> np.ndarray:
    """``(..., B, 4)`` joint rotation of each segment from skeleton local rotations ``(..., J, 4)``
    (merged joints folded into the next kept joint below them)."""
    lr = np.asarray(local_rot, dtype=np.float64)
    out = np.empty(lr.shape[:-2] + (bmap.num_bodies, 4))
    for b, chain in enumerate(bmap.chains):
        q = lr[..., chain[0], :]
        for k in chain[1:]:
            q = quat.mul(q, lr[..., k, :])
        out[..., b, :] = q
    return out


def _hinge_angle(q: np.ndarray, axis: np.ndarray) -> np.ndarray:
    q = quat.abs(q)
    _, twist = quat.swing_twist(q, axis)
    return 2.0 * np.arctan2(twist[..., 1:] @ axis, twist[..., 0])


def motion_to_qpos(bmap, root_pos: np.ndarray, local_rot: np.ndarray) -> np.ndarray:
    """The character's ``qpos`` block ``(..., nq)`` for root positions ``(..., 3)`` and skeleton local
    rotations ``(..., J, 4)``. Hinges keep the rotation about their axis (swing-twist)."""
    rp = np.asarray(root_pos, dtype=np.float64)
    brot = body_rotations(bmap, local_rot)
    out = np.zeros(rp.shape[:-1] + (bmap.nq,))
    for b, s in enumerate(bmap.segments):
        a = bmap.qpos_adr[b]
        if s.kind == "free":
            out[..., a:a + 3] = rp
            out[..., a + 3:a + 7] = quat.normalize(brot[..., b, :])
        elif s.kind == "ball":
            out[..., a:a + 4] = quat.normalize(brot[..., b, :])
        elif s.kind == "hinge":
            out[..., a] = _hinge_angle(brot[..., b, :], np.asarray(s.axis))
    return out


def pose_to_ctrl(bmap, local_rot: np.ndarray) -> np.ndarray:
    """PD targets ``(..., nu)``: a quaternion per ball joint and an angle per hinge, from skeleton local
    rotations ``(..., J, 4)``."""
    brot = body_rotations(bmap, local_rot)
    out = np.zeros(brot.shape[:-2] + (bmap.nu,))
    for b in bmap.actuated:
        s = bmap.segments[b]
        a = bmap.ctrl_adr[b]
        if s.kind == "ball":
            out[..., a:a + 4] = quat.normalize(brot[..., b, :])
        else:
            out[..., a] = _hinge_angle(brot[..., b, :], np.asarray(s.axis))
    return out


def qpos_to_local_rot(bmap, qpos: np.ndarray, root_quat: np.ndarray | None = None) -> np.ndarray:
    """Skeleton local rotations ``(..., J, 4)`` from the character's ``qpos`` block ``(..., nq)``; merged
    joints get the identity (they are rigid at rest). ``root_quat (..., 4)`` gives the root rotation
    of a fixed-root character."""
    q = np.asarray(qpos, dtype=np.float64)
    out = quat.identity(q.shape[:-1] + (bmap.skeleton.num_joints,))
    for b, s in enumerate(bmap.segments):
        a = bmap.qpos_adr[b]
        j = s.joint
        if s.kind == "free":
            out[..., j, :] = quat.normalize(q[..., a + 3:a + 7])
        elif s.kind == "fixed":
            if root_quat is not None:
                out[..., j, :] = root_quat
        elif s.kind == "ball":
            out[..., j, :] = quat.normalize(q[..., a:a + 4])
        else:
            out[..., j, :] = quat.from_axis_angle(np.asarray(s.axis), q[..., a])
    return out
