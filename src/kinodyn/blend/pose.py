"""Pose blending: weighted averages of joint rotations and of interpolated clip frames.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, section 3 (the blending module of
their reference [Lba]): local joint rotations are averaged with the actions' weights, either as the
normalized weighted sum of hemisphere-aligned quaternions (``nlerp``, fast) or as Markley's eigenvector
mean. :func:`blend_frames` samples and blends packed clip frames in one pass (numpy);
:func:`blend_frames_fast` is its compiled form, the one the mixer uses every frame. The dynamic response
reuses these to blend a reaction back into motion capture.

Shapes: ``N`` characters, ``S`` action slots, ``J`` joints, ``F`` packed frames.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from kinodyn.math import quat

__all__ = ["Pose", "blend_frames", "blend_frames_fast", "blend_rotations"]


class Pose(NamedTuple):
    """Poses of ``N`` characters: ``root_pos (N, 3)`` and ``local_rot (N, J, 4)``."""

    root_pos: np.ndarray
    local_rot: np.ndarray



def blend_rotations(q, w, ref, wref, method: str = "nlerp") -> np.ndarray:
    """Weighted average of rotations ``q (N, S, J, 4)`` with weights ``w (N, S)`` and a reference pose
    ``ref (J, 4)`` of weight ``wref (N,)`` (the neutral pose); returns ``(N, J, 4)``.

    ``nlerp``: every quaternion is put in the hemisphere of the one with the most weight and the weighted
    sum is normalized (the first-order approximation of the chordal mean; within a fraction of a degree
    of it for rotations less than about 30 degrees apart). ``markley``: the eigenvector mean of
    :func:`kinodyn.math.quat.average`.
    """
    if method == "markley":
        allq = np.concatenate([q, np.broadcast_to(ref, (q.shape[0], 1) + ref.shape)], axis=1)
        allw = np.concatenate([w, wref[:, None]], axis=1)
        return quat.average(allq, np.broadcast_to(allw[:, :, None], allq.shape[:-1]), axis=1)
    # hemisphere of the rotation with the most weight (the neutral pose's or a slot's), per joint
    top = np.argmax(w, axis=1)
    anchor = np.where((wref >= w.max(axis=1))[:, None, None], ref, q[np.arange(len(q)), top])
    sign = np.where(np.einsum("nsjc,njc->nsj", q, anchor) < 0.0, -1.0, 1.0)
    sref = np.where(np.einsum("jc,njc->nj", ref, anchor) < 0.0, -1.0, 1.0)
    acc = np.einsum("nsjc,nsj->njc", q, sign * w[:, :, None]) + (wref[:, None] * sref)[..., None] * ref
    return acc / np.maximum(np.linalg.norm(acc, axis=-1, keepdims=True), 1e-12)



def blend_frames(rot_db, i0, a, w, ref, wref) -> np.ndarray:
    """Weighted blend of clip frames, each interpolated between two database frames (numpy reference).

    Args:
        rot_db: ``(F, J, 4)`` packed frames (consecutive frames of a clip in the same hemisphere).
        i0: ``(N, S)`` first frame of each sample; ``a (N, S)`` the fraction toward ``i0 + 1``.
        w: ``(N, S)`` weights; ``ref (J, 4)`` the neutral pose with weights ``wref (N,)``.

    Returns:
        ``(N, J, 4)``: the normalized sum of ``w * lerp(frame i0, frame i0 + 1)`` and ``wref * ref``,
        every quaternion first put in the hemisphere of the one with the most weight.
    """
    N, S = w.shape
    top = np.argmax(w, axis=1)
    rows_n = np.arange(N)
    anchor = np.where((wref >= w[rows_n, top])[:, None, None], ref, rot_db[i0[rows_n, top]])
    sref = np.where(np.einsum("jc,njc->nj", ref, anchor) < 0.0, -1.0, 1.0)
    q = (wref[:, None] * sref)[..., None] * ref
    for k in range(S):
        live = w[:, k] > 0.0
        if not live.any():
            continue
        rows = None if live.all() else np.nonzero(live)[0]
        ik = i0[:, k] if rows is None else i0[rows, k]
        wk = w[:, k] if rows is None else w[rows, k]
        ak = a[:, k] if rows is None else a[rows, k]
        r0 = rot_db[ik]
        r1 = rot_db[ik + 1]
        sign = np.where(np.einsum("njc,njc->nj", r0, anchor if rows is None else anchor[rows]) < 0.0, -1.0, 1.0)
        c1 = (wk * ak)[:, None] * sign
        c0 = wk[:, None] * sign - c1
        r0 *= c0[..., None]
        r1 *= c1[..., None]
        r0 += r1
        if rows is None:
            q += r0
        else:
            q[rows] += r0
    q /= np.maximum(np.sqrt(np.einsum("njc,njc->nj", q, q)), 1e-12)[..., None]
    return q


@numba.njit(cache=True)
def _blend_kernel(rot_db, i0, a, w, ref, wref, out):  # pragma: no cover - compiled
    n_chars, n_slots = w.shape
    n_joints = ref.shape[0]
    for n in range(n_chars):
        top = -1
        best = wref[n]
        for k in range(n_slots):
            if w[n, k] > best:
                best = w[n, k]
                top = k
        for j in range(n_joints):
            if top < 0:
                x0, x1, x2, x3 = ref[j, 0], ref[j, 1], ref[j, 2], ref[j, 3]
            else:
                f = i0[n, top]
                x0, x1, x2, x3 = rot_db[f, j, 0], rot_db[f, j, 1], rot_db[f, j, 2], rot_db[f, j, 3]
            s = 1.0 if ref[j, 0] * x0 + ref[j, 1] * x1 + ref[j, 2] * x2 + ref[j, 3] * x3 >= 0.0 else -1.0
            c = wref[n] * s
            q0, q1, q2, q3 = c * ref[j, 0], c * ref[j, 1], c * ref[j, 2], c * ref[j, 3]
            for k in range(n_slots):
                wk = w[n, k]
                if wk <= 0.0:
                    continue
                f = i0[n, k]
                r0, r1, r2, r3 = rot_db[f, j, 0], rot_db[f, j, 1], rot_db[f, j, 2], rot_db[f, j, 3]
                s = 1.0 if r0 * x0 + r1 * x1 + r2 * x2 + r3 * x3 >= 0.0 else -1.0
                c1 = wk * a[n, k] * s
                c0 = wk * s - c1
                q0 += c0 * r0 + c1 * rot_db[f + 1, j, 0]
                q1 += c0 * r1 + c1 * rot_db[f + 1, j, 1]
                q2 += c0 * r2 + c1 * rot_db[f + 1, j, 2]
                q3 += c0 * r3 + c1 * rot_db[f + 1, j, 3]
            nrm = max(np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3), 1e-12)
            out[n, j, 0] = q0 / nrm
            out[n, j, 1] = q1 / nrm
            out[n, j, 2] = q2 / nrm
            out[n, j, 3] = q3 / nrm



def blend_frames_fast(rot_db, i0, a, w, ref, wref) -> np.ndarray:
    """Compiled :func:`blend_frames` (same result); one pass per character, no temporaries."""
    out = np.empty((w.shape[0], ref.shape[0], 4))
    _blend_kernel(rot_db, np.ascontiguousarray(i0, dtype=np.int64), np.ascontiguousarray(a, dtype=np.float64),
                  np.ascontiguousarray(w, dtype=np.float64), np.ascontiguousarray(ref, dtype=np.float64),
                  np.ascontiguousarray(wref, dtype=np.float64), out)
    return out
