"""Batched interpolation of a multidimensional keyframe set around points of Q (sections 5.1, 5.2).

Mitake et al., section 5.1: the point of the keyframe space a body's state maps to is posed by
interpolating the keyframes around it. The scheme (the paper leaves the interpolant open):

* within one behaviour and plane, keyframes are grouped into levels of equal tilt (:mod:`keyframes`);
  each level is a periodic function of the phase, a Catmull-Rom spline through its keyframes (a level
  with one keyframe is constant), and neighbouring levels are blended linearly in tilt (clamped at
  the outermost levels). It passes through every keyframe exactly and is continuous everywhere;
* the two planes of a behaviour (forward ``(Theta_x, D_z)`` and side ``(Theta_z, D_x)``) are blended
  by how far the point is from each: ``w_side = d_forward / (d_forward + d_side)``, with ``d`` the
  distance in tilt (radians / ``tilt_scale``) and in phase (cyclic, / ``phase_scale``) to the plane;
  the point where the planes meet belongs to the forward plane (a keyframe there is shared by both:
  :mod:`keyframes` adds it to the side plane too, so the blend is continuous there);
  A caller may give its own side weights (the crowd weighs by the direction of travel and tilt, so
  a phase left over from an earlier sidestep does not show while walking forward);
* the behaviours (the values of B) are all adjacent: their poses are blended with the weights given
  (one-hot for a single behaviour; the crowd eases between them when the behaviour changes).

Quaternions are blended as weighted sums aligned to one hemisphere and normalized (exact where one
weight is 1). Shapes: N points, J joints, B behaviours. One compiled kernel runs the whole batch
(numba, parallel over characters: pin ``numba.set_num_threads`` to measure one core).
"""

from __future__ import annotations

from functools import lru_cache

import numba
import numpy as np

from kinodyn.crowd.keyframes import KeyframeSet
from kinodyn.errors import ParameterError

__all__ = ["aligned_keys", "interpolate", "interpolate_prepared", "scratch", "to_world"]

TILT_SCALE = 0.5
PHASE_SCALE = 0.25


#: a caller's side weight under this (or over one minus this) poses one plane only; the weight is
#: stretched in between, so the blend stays continuous.
SIDE_DEAD_ZONE = 0.1
MAX_TERMS = 32  # behaviours (2 blended) x planes (2) x levels (2) x spline keys (4)
#: chunks of points the compiled kernel runs in parallel, each with one row of scratch
SCRATCH_CHUNKS = 64


@numba.njit(cache=True, inline="always")
def _push(k, w, idx, wts, m):
    idx[m] = k
    wts[m] = w
    return m + 1


@numba.njit(cache=True, inline="always")
def _level_terms(lv, phase, w, key_phase, level_start, level_count, idx, wts, m):
    """Add the Catmull-Rom terms of one periodic level at ``phase``; return the new term count."""
    s, c = level_start[lv], level_count[lv]
    if c == 1:
        return _push(s, w, idx, wts, m)
    k = c - 1
    for i in range(c - 1):
        if key_phase[s + i] <= phase < key_phase[s + i + 1]:
            k = i
            break
    p0 = key_phase[s + k]
    p1 = key_phase[s + (k + 1) % c]
    gap = p1 - p0 if k < c - 1 else p1 + 1.0 - p0
    d = phase - p0
    if d < 0.0:
        d += 1.0
    t = d / gap
    t2, t3 = t * t, t * t * t
    w0, w1 = (-t3 + 2 * t2 - t) * 0.5, (3 * t3 - 5 * t2 + 2) * 0.5
    w2, w3 = (-3 * t3 + 4 * t2 + t) * 0.5, (t3 - t2) * 0.5
    if w1 != 0.0:  # first, so an exact keyframe is the reference hemisphere
        m = _push(s + k, w * w1, idx, wts, m)
    if w0 != 0.0:
        m = _push(s + (k - 1 + c) % c, w * w0, idx, wts, m)
    if w2 != 0.0:
        m = _push(s + (k + 1) % c, w * w2, idx, wts, m)
    if w3 != 0.0:
        m = _push(s + (k + 2) % c, w * w3, idx, wts, m)
    return m


@numba.njit(cache=True, inline="always")
def _plane_terms(b, p, tilt, phase, w, plane_start, plane_count, level_tilt, key_phase, level_start,
                 level_count, idx, wts, m):
    """Add the terms of one behaviour's plane: its two levels around ``tilt``, blended linearly."""
    s, c = plane_start[b, p], plane_count[b, p]
    if tilt <= level_tilt[s] or c == 1:
        lo, u = s, 0.0
    elif tilt >= level_tilt[s + c - 1]:
        lo, u = s + c - 1, 0.0
    else:
        lo = s
        while level_tilt[lo + 1] <= tilt:
            lo += 1
        u = (tilt - level_tilt[lo]) / (level_tilt[lo + 1] - level_tilt[lo])
    if u < 1.0:
        m = _level_terms(lo, phase, w * (1.0 - u), key_phase, level_start, level_count, idx, wts, m)
    if u > 0.0:
        m = _level_terms(lo + 1, phase, w * u, key_phase, level_start, level_count, idx, wts, m)
    return m


@numba.njit(cache=True, inline="always")
def _cyc(d):
    return min(d, 1.0 - d)


@numba.njit(cache=True, inline="always")
def _side_weight(tx, tz, dx, dz, given, tilt_scale, phase_scale):
    if given >= 0.0:  # a caller's weight, with dead zones at both ends (one plane only: half the work)
        return min(1.0, max(0.0, (given - SIDE_DEAD_ZONE) / (1.0 - 2.0 * SIDE_DEAD_ZONE)))
    df = np.sqrt((tz / tilt_scale) ** 2 + (_cyc(dx) / phase_scale) ** 2)
    dsd = np.sqrt((tx / tilt_scale) ** 2 + (_cyc(dz) / phase_scale) ** 2)
    return 0.0 if df == 0.0 else df / (df + dsd)


@numba.njit(cache=True, fastmath=True)
def _accumulate(i, m, idx, wts, aligned, ref_sign, key_root, out_rot, out_root):
    """Weighted sum of the terms' poses (quaternions on the first term's hemisphere), normalized.

    ``aligned[r, k]`` is keyframe ``k``'s rotations ``(J * 4,)`` each turned onto the hemisphere of
    keyframe ``r``'s, times ``ref_sign[r]`` (:func:`aligned_keys`; one row ``aligned[0]`` serves every
    ``r`` when the set allows), so the sum is a plain weighted sum of rows.
    """
    nj4 = aligned.shape[2]
    r = idx[0]
    a = aligned[0] if aligned.shape[0] == 1 else aligned[r]
    o = out_rot[i]
    w = wts[0]
    row = a[r]
    for c in range(nj4):
        o[c] = w * row[c]
    rx, ry, rz = w * key_root[r, 0], w * key_root[r, 1], w * key_root[r, 2]
    for t in range(1, m):
        k, w = idx[t], wts[t]
        row = a[k]
        for c in range(nj4):
            o[c] += w * row[c]
        rx += w * key_root[k, 0]
        ry += w * key_root[k, 1]
        rz += w * key_root[k, 2]
    out_root[i, 0], out_root[i, 1], out_root[i, 2] = rx, ry, rz
    for j in range(0, nj4, 4):
        q0, q1, q2, q3 = o[j], o[j + 1], o[j + 2], o[j + 3]
        nrm = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        if nrm < 1e-12:
            o[j], o[j + 1], o[j + 2], o[j + 3] = 1.0, 0.0, 0.0, 0.0
        else:
            inv = ref_sign[r, j // 4] / nrm
            for c in range(4):
                o[j + c] *= inv


@lru_cache(maxsize=8)
def aligned_keys(ks: KeyframeSet, dtype=np.float64) -> tuple[np.ndarray, np.ndarray]:
    """The keyframes' rotations on the hemispheres the interpolation sums them on.

    With ``s[r, k, j] = +-1`` the sign of the dot product of keyframes ``r`` and ``k``'s rotations of
    joint ``j``, the sum around reference keyframe ``r`` adds ``s[r, k, j] * key_rot[k, j]``. When
    each joint's rotations, once turned onto the hemisphere of keyframe 0's (``c[k, j] = s[0, k, j]
    key_rot[k, j]``), have positive dot products with each other, ``s[r, k, j] = s[0, r, j] s[0, k, j]``
    and one table serves every reference: ``c``, with the sum's sign restored by ``s[0, r, j]``. Any
    other set keeps a row per reference.

    Returns:
        ``(aligned (R, K, J * 4), ref_sign (K, J))`` of ``dtype``: ``R = 1`` with ``aligned[0] = c``
        and ``ref_sign = s[0]``, or ``R = K`` with ``aligned[r, k] = s[r, k] key_rot[k]`` and
        ``ref_sign = 1``; read-only.
    """
    rot = np.asarray(ks.key_rot, np.float64)
    k, j = rot.shape[:2]
    canon = np.where(np.einsum("jc,kjc->kj", rot[0], rot) >= 0.0, 1.0, -1.0)
    c = canon[..., None] * rot
    if np.all(np.einsum("rjc,kjc->rkj", c, c) > 0.0):
        out, ref = c.reshape(1, k, j * 4), canon
    else:
        sign = np.where(np.einsum("rjc,kjc->rkj", rot, rot) >= 0.0, 1.0, -1.0)
        out, ref = (sign[..., None] * rot[None]).reshape(k, k, j * 4), np.ones((k, j))
    out, ref = out.astype(dtype), ref.astype(dtype)
    out.setflags(write=False)
    ref.setflags(write=False)
    return out, ref


@numba.njit(cache=True, inline="always")
def _to_frame(i, pos, q, out_rot, out_root):
    """Show pose ``i`` in the frame (``pos (N, 3)``, ``q (N, 4)``): root rotation and position."""
    w, x, y, z = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    a0, a1, a2, a3 = out_rot[i, 0], out_rot[i, 1], out_rot[i, 2], out_rot[i, 3]
    out_rot[i, 0] = w * a0 - x * a1 - y * a2 - z * a3
    out_rot[i, 1] = w * a1 + x * a0 + y * a3 - z * a2
    out_rot[i, 2] = w * a2 - x * a3 + y * a0 + z * a1
    out_rot[i, 3] = w * a3 + x * a2 - y * a1 + z * a0
    vx, vy, vz = out_root[i, 0], out_root[i, 1], out_root[i, 2]
    tx, ty, tz = 2 * (y * vz - z * vy), 2 * (z * vx - x * vz), 2 * (x * vy - y * vx)
    out_root[i, 0] = pos[i, 0] + vx + w * tx + (y * tz - z * ty)
    out_root[i, 1] = pos[i, 1] + vy + w * ty + (z * tx - x * tz)
    out_root[i, 2] = pos[i, 2] + vz + w * tz + (x * ty - y * tx)


@numba.njit(cache=True, parallel=True)
def _interp_kernel(points, bweights, side_w, tilt_scale, phase_scale, key_root, aligned, ref_sign, key_phase,
                   level_tilt, level_start, level_count, plane_start, plane_count, idx, wts, out_rot, out_root,
                   frame_pos, frame_quat, in_frame):
    nb = bweights.shape[1]
    n, chunks = points.shape[0], idx.shape[0]
    for ch in numba.prange(chunks):  # one scratch row per chunk of characters
        ti, tw = idx[ch], wts[ch]
        for i in range(ch * n // chunks, (ch + 1) * n // chunks):
            tx, tz, dx, dz = points[i, 0], points[i, 1], points[i, 2], points[i, 3]
            m = 0
            for b in range(nb):
                wb = bweights[i, b]
                if wb == 0.0:
                    continue
                hf, hs = plane_count[b, 0] > 0, plane_count[b, 1] > 0
                ws = _side_weight(tx, tz, dx, dz, side_w[i], tilt_scale, phase_scale) if hf and hs else (
                    0.0 if hf else 1.0)
                if ws < 1.0:
                    m = _plane_terms(b, 0, tx, dz, wb * (1.0 - ws), plane_start, plane_count, level_tilt,
                                     key_phase, level_start, level_count, ti, tw, m)
                if ws > 0.0:
                    m = _plane_terms(b, 1, tz, dx, wb * ws, plane_start, plane_count, level_tilt, key_phase,
                                     level_start, level_count, ti, tw, m)
            _accumulate(i, m, ti, tw, aligned, ref_sign, key_root, out_rot, out_root)
            if in_frame:
                _to_frame(i, frame_pos, frame_quat, out_rot, out_root)


def interpolate(ks: KeyframeSet, points, behaviour, side_weight=None, out=None,
                tilt_scale: float = TILT_SCALE, phase_scale: float = PHASE_SCALE, frame=None):
    """Poses in the body frame Sr at points of the keyframe space.

    Args:
        ks: the keyframe set.
        points: ``(N, 4)`` coordinates ``(Theta_x, Theta_z, D_x, D_z)``: tilts in radians, phases in
            ``[0, 1)`` (other values are wrapped with :func:`~kinodyn.crowd.keyframes.periodic`).
        behaviour: an int or ``(N,)`` ints (indices into ``ks.behaviours``), or ``(N, B)`` weights
            (rows summing to 1).
        side_weight: ``(N,)`` weights of the side plane in ``[0, 1]`` (mapped continuously so that
            weights within :data:`SIDE_DEAD_ZONE` of 0 or 1 pose one plane only); None: from the point
            (module docstring).
        out: optional ``(rot (N, J, 4), root (N, 3))`` arrays to fill.
        tilt_scale, phase_scale: the distance scales of the plane weights.
        frame: optional ``(body_pos (N, 3), body_quat (N, 4))``: show the poses in these frames Sr
            (the same as :func:`to_world` afterwards, in the same compiled pass).

    Returns:
        ``(local_rot (N, J, 4), root (N, 3))``: local rotations (the root's relative to Sr) and the
        root position in Sr relative to the centre of mass (or in the world, with ``frame``).
    """
    pts = np.array(points, dtype=np.float64, ndmin=2)
    if pts.ndim != 2 or pts.shape[1] != 4:
        raise ParameterError(f"points must have shape (N, 4), got {np.shape(points)}")
    if not np.all(np.isfinite(pts)):
        raise ParameterError("points must be finite")
    n, nb = pts.shape[0], len(ks.behaviours)
    pts[:, 2:] = pts[:, 2:] - np.floor(pts[:, 2:])
    pts[:, 2:][pts[:, 2:] >= 1.0] = 0.0
    bw = _behaviour_weights(behaviour, n, nb)
    if side_weight is None:
        sw = np.full(n, -1.0)
    else:
        sw = np.clip(np.broadcast_to(np.asarray(side_weight, np.float64), (n,)), 0.0, 1.0)
    rot, root = out if out is not None else (np.empty((n, ks.key_rot.shape[1], 4)), np.empty((n, 3)))
    idx, wts = scratch(n)
    if frame is None:
        fpos, fquat, in_frame = np.zeros((1, 3)), np.zeros((1, 4)), False
    else:
        fpos, fquat, in_frame = np.ascontiguousarray(frame[0], np.float64), np.ascontiguousarray(frame[1], np.float64), True
        if fpos.shape != (n, 3) or fquat.shape != (n, 4):
            raise ParameterError(f"frame must be ((N, 3), (N, 4)) arrays for N = {n}, got {fpos.shape}, {fquat.shape}")
    _interp_kernel(pts, bw, np.ascontiguousarray(sw), float(tilt_scale), float(phase_scale), ks.key_root,
                   *aligned_keys(ks), ks.key_phase, ks.level_tilt, ks.level_start, ks.level_count,
                   ks.plane_start, ks.plane_count, idx, wts, rot.reshape(n, -1), root, fpos, fquat, in_frame)
    return rot, root


def scratch(n: int, dtype=np.float64) -> tuple[np.ndarray, np.ndarray]:
    """Working arrays of the compiled interpolation for ``n`` points: term indices ``(C, MAX_TERMS)``
    and weights of ``dtype``, the precision of the rotations it sums, one row per chunk of points
    (``C = min(n, SCRATCH_CHUNKS)``; a caller posing every frame keeps them)."""
    c = max(1, min(int(n), SCRATCH_CHUNKS))
    return np.empty((c, MAX_TERMS), np.int64), np.empty((c, MAX_TERMS), dtype)


def interpolate_prepared(ks: KeyframeSet, points, bweights, side_weight, work, out, frame) -> None:
    """:func:`interpolate` without checks or copies, for a caller that owns valid arrays.

    Args:
        points: ``(N, 4)`` float64, phases already in ``[0, 1)``.
        bweights: ``(N, B)`` float64 rows summing to 1.
        side_weight: ``(N,)`` float64 in ``[0, 1]``.
        work: :func:`scratch` arrays for N; the dtype of their weights (float64 or float32) is the
            precision of the rotations summed.
        out: ``(rot (N, J, 4), root (N, 3))`` C-contiguous, filled: ``rot`` of the weights' dtype
            (float32 poses agree with :func:`interpolate` to about 1e-7), ``root`` float64.
        frame: ``(body_pos (N, 3), body_quat (N, 4))`` C-contiguous float64.
    """
    rot, root = out
    aligned, ref_sign = aligned_keys(ks, work[1].dtype.type)
    _interp_kernel(points, bweights, side_weight, TILT_SCALE, PHASE_SCALE, ks.key_root, aligned, ref_sign,
                   ks.key_phase, ks.level_tilt, ks.level_start, ks.level_count, ks.plane_start,
                   ks.plane_count, work[0], work[1], rot.reshape(rot.shape[0], -1), root, frame[0], frame[1],
                   True)


def _behaviour_weights(behaviour, n: int, nb: int) -> np.ndarray:
    b = np.asarray(behaviour)
    if b.ndim == 2:
        if b.shape != (n, nb):
            raise ParameterError(f"behaviour weights must have shape ({n}, {nb}), got {b.shape}")
        return np.ascontiguousarray(b, dtype=np.float64)
    idx = np.broadcast_to(b.astype(np.int64), (n,))
    if np.any((idx < 0) | (idx >= nb)):
        raise ParameterError(f"behaviour indices must lie in [0, {nb}), got {np.unique(idx).tolist()}")
    bw = np.zeros((n, nb))
    bw[np.arange(n), idx] = 1.0
    return bw


def to_world(rot: np.ndarray, root: np.ndarray, body_pos: np.ndarray, body_quat: np.ndarray) -> None:
    """Show poses in the bodies' frames Sr (section 5.1), in place.

    Args:
        rot: ``(N, J, 4)`` local rotations; the root's becomes its world rotation.
        root: ``(N, 3)`` root positions in Sr; become world positions.
        body_pos: ``(N, 3)`` centres of mass.
        body_quat: ``(N, 4)`` body rotations.
    """
    from kinodyn.math import quat

    rot[:, 0] = quat.mul(body_quat, rot[:, 0])
    root[:] = body_pos + quat.mul_vec(body_quat, root)
