"""Forward kinematics and derived kinematic quantities of motions.

Forward kinematics walks the parents array once per frame (``parents[j] < j``), composing local
rotations and offsets; it is compiled with numba and parallel over frames, and agrees with the pure
numpy reference :func:`kinodyn.math.quat.fk` to 1e-12. Velocities are finite differences (central
inside, one-sided at the ends) in world units per second.

Shapes: ``F`` frames, ``J`` joints, ``E`` end sites.
"""

from __future__ import annotations

import numpy as np

from kinodyn.math import quat

__all__ = [
    "SMALL_JOINT_FRAMES",
    "angular_velocity",
    "end_site_positions",
    "fk_arrays",
    "fk_link",
    "forward_kinematics",
    "joint_velocities",
    "linear_velocity",
]

#: at most this many frames x joints go through the numpy path (no numba import, which costs 0.25-0.5 s
#: and more than numpy takes on such sizes); larger motions use the compiled kernel, parallel over frames
SMALL_JOINT_FRAMES = 200_000


def _fk_kernel(root_pos, local_rot, trans, parents, gr, gp):  # pragma: no cover - compiled
    """trans is (1, J, 3) (rest offsets for every frame) or (F, J, 3) (animated translations)."""
    n_frames, n_joints = local_rot.shape[0], local_rot.shape[1]
    per_frame = 1 if trans.shape[0] > 1 else 0
    for f in numba.prange(n_frames):
        ft = f * per_frame
        for c in range(4):
            gr[f, 0, c] = local_rot[f, 0, c]
        for c in range(3):
            gp[f, 0, c] = root_pos[f, c]
        for j in range(1, n_joints):
            fk_link(gr[f], gp[f], parents[j], j, local_rot[f, j], trans[ft, j])


def _fk_link(gr, gp, p, j, q, v):  # pragma: no cover - compiled
    """One forward-kinematics link, in place: ``gr[j] = gr[p] * q`` and ``gp[j] = gp[p] + R(gr[p]) v``.

    For compiled kernels (as :data:`fk_link`): ``gr (J, 4)`` and ``gp (J, 3)`` of one pose, ``q (4,)``
    local rotation and ``v (3,)`` local offset of joint ``j`` whose parent is ``p``. The same code runs
    vectorized over frames in the numpy path (``gr (F, J, 4)`` then indexed by ``[..., j, c]``).
    """
    aw, ax, ay, az = gr[..., p, 0], gr[..., p, 1], gr[..., p, 2], gr[..., p, 3]
    bw, bx, by, bz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    gr[..., j, 0] = aw * bw - ax * bx - ay * by - az * bz
    gr[..., j, 1] = aw * bx + ax * bw + ay * bz - az * by
    gr[..., j, 2] = aw * by - ax * bz + ay * bw + az * bx
    gr[..., j, 3] = aw * bz + ax * by - ay * bx + az * bw
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    # R(a) v = v + 2w (u x v) + 2 u x (u x v), with t = 2 (u x v)
    tx = 2.0 * (ay * vz - az * vy)
    ty = 2.0 * (az * vx - ax * vz)
    tz = 2.0 * (ax * vy - ay * vx)
    gp[..., j, 0] = gp[..., p, 0] + vx + aw * tx + (ay * tz - az * ty)
    gp[..., j, 1] = gp[..., p, 1] + vy + aw * ty + (az * tx - ax * tz)
    gp[..., j, 2] = gp[..., p, 2] + vz + aw * tz + (ax * ty - ay * tx)


_COMPILED: dict = {}


def _compiled() -> dict:
    """The numba kernels, compiled (or loaded from numba's cache) on first use, so that importing this
    module, and reading or inspecting small files, never imports numba."""
    if not _COMPILED:
        global numba, fk_link  # the kernels find numba.prange and each other by their global names
        import numba

        fk_link = numba.njit(cache=True, inline="always")(_fk_link)
        _COMPILED.update(fk_link=fk_link, fk_kernel=numba.njit(cache=True, parallel=True)(_fk_kernel))
    return _COMPILED


def __getattr__(name: str):
    if name == "fk_link":  # the compiled link for other modules' kernels (``from ... import fk_link``)
        return _compiled()["fk_link"]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def fk_arrays(root_pos, local_rot, offsets, parents, translations=None) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics on plain arrays.

    Motions of up to :data:`SMALL_JOINT_FRAMES` frames x joints run in numpy, larger ones in a compiled
    kernel parallel over frames; both evaluate the same expressions (:func:`_fk_link`) and agree to
    1e-12.

    Args:
        root_pos: ``(F, 3)`` root positions.
        local_rot: ``(F, J, 4)`` local rotations.
        offsets: ``(J, 3)`` rest offsets (ignored when ``translations`` is given).
        parents: ``(J,)`` parents with ``parents[j] < j``.
        translations: optional ``(F, J, 3)`` per-frame local translations.

    Returns:
        Global rotations ``(F, J, 4)`` and positions ``(F, J, 3)``.
    """
    local_rot = np.ascontiguousarray(local_rot, dtype=np.float64)
    f, j = local_rot.shape[:2]
    parents = np.ascontiguousarray(parents, dtype=np.int64)
    gr = np.empty((f, j, 4))
    gp = np.empty((f, j, 3))
    trans = np.ascontiguousarray(offsets[None] if translations is None else translations, dtype=np.float64)
    root_pos = np.ascontiguousarray(root_pos, dtype=np.float64)
    if f * j <= SMALL_JOINT_FRAMES:
        gr[:, 0] = local_rot[:, 0]
        gp[:, 0] = root_pos
        for k in range(1, j):
            _fk_link(gr, gp, parents[k], k, local_rot[:, k], trans[:, k])
    else:
        _compiled()["fk_kernel"](root_pos, local_rot, trans, parents, gr, gp)
    return gr, gp


def forward_kinematics(motion) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations ``(F, J, 4)`` and positions ``(F, J, 3)`` of a :class:`~kinodyn.motion.Motion`."""
    sk = motion.skeleton
    return fk_arrays(motion.root_pos, motion.local_rot, sk.offsets, sk.parents, motion.translations)


def end_site_positions(motion, global_rot=None, global_pos=None) -> np.ndarray:
    """``(F, E, 3)`` world positions of the skeleton's end sites (bone tips)."""
    sk = motion.skeleton
    if global_rot is None or global_pos is None:
        global_rot, global_pos = forward_kinematics(motion)
    ep = sk.end_parents
    return global_pos[:, ep] + quat.mul_vec(global_rot[:, ep], sk.end_offsets)


def linear_velocity(x, fps: float) -> np.ndarray:
    """Finite-difference velocity of ``x (F, ...)`` sampled at ``fps``; same shape, units per second."""
    x = np.asarray(x, dtype=np.float64)
    if len(x) < 2:
        return np.zeros_like(x)
    return np.gradient(x, 1.0 / fps, axis=0)


def angular_velocity(q, fps: float) -> np.ndarray:
    """World-frame angular velocity ``(F, ..., 3)`` rad/s of rotations ``q (F, ..., 4)``.

    Uses ``2 log(q[t+1] q[t]^-1) fps`` on each interval and averages the two intervals around a frame.
    """
    q = np.asarray(q, dtype=np.float64)
    if len(q) < 2:
        return np.zeros(q.shape[:-1] + (3,))
    d = 2.0 * quat.log(quat.mul_inv(q[1:], q[:-1])) * fps
    out = np.empty(q.shape[:-1] + (3,))
    out[0] = d[0]
    out[-1] = d[-1]
    out[1:-1] = 0.5 * (d[1:] + d[:-1])
    return out


def joint_velocities(motion) -> tuple[np.ndarray, np.ndarray]:
    """World linear ``(F, J, 3)`` m/s and angular ``(F, J, 3)`` rad/s velocities of every joint."""
    gr, gp = forward_kinematics(motion)
    return linear_velocity(gp, motion.fps), angular_velocity(gr, motion.fps)
