"""Support constraints after blending: keep the planted feet where they landed.

Synchronization (:mod:`kinodyn.blend.sync`) leaves every instant with actions that agree on which feet
carry the body; this module makes the blended pose respect that support, the role the paper's engine
gives to kinematic constraints computed after blending (its section 3). A foot is *planted* when the
weights of the actions whose current phase puts it down (``RS``: right, ``LS``: left, ``DS``: both; the
neutral pose: both) add up to at least one half. Each planted foot is held at the position its lowest
point had when it was planted (or when the lowest point moved from heel to toe), and never lower than
the actions' clips keep their planted feet (blending poses of different root heights would push it
through the floor).

The root's horizontal position follows the held feet, each by the share of the body's weight it
carries: all of it on a single support, passed linearly from the old support foot to the new one over a
double support, as the actions' sequences say
(:meth:`~kinodyn.phases.PhaseSequence.left_share`), and faded out as a foot's vote nears one
half. So the root never jumps when a foot lifts or lands. Two-bone inverse kinematics of each leg (hip,
knee, ankle) then puts the feet where they are held, keeping each foot's world orientation; when a held
foot is beyond a straight leg's reach (the back foot at push-off) the pelvis comes down a little, and
beyond that the foot follows the pose.

The two-bone solver is the analytic one of Daniel Holden's Motion-Matching code (``ik_two_bone``),
batch-first and skeleton-agnostic: it works on world positions and rotations from forward kinematics.

Shapes: ``M`` poses, ``J`` joints. Units: metres.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from kinodyn.errors import UnknownNameError
from kinodyn.math import quat

__all__ = ["Leg", "legs", "pin_feet", "pin_feet_fast", "two_bone_ik"]


class Leg(NamedTuple):
    """One leg: ``hip``, ``knee``, ``ankle`` joint indices and the foot's points (joints + end sites)."""

    hip: int
    knee: int
    ankle: int
    joints: np.ndarray
    ends: np.ndarray


def legs(skeleton) -> tuple[Leg, Leg] | None:
    """``(left, right)`` legs of a skeleton found from its foot joints, or ``None`` when it has no feet.

    The ankle is the highest foot joint (closest to the root); the knee and hip are its parent and
    grandparent.
    """
    from kinodyn import contacts

    try:
        feet = contacts.find_feet(skeleton)
    except UnknownNameError:
        return None
    out = []
    par = skeleton.parents
    for side in ("left", "right"):
        joints = np.array(sorted(int(j) for j in feet[side]), dtype=np.int64)
        ankle = int(joints[0])
        knee = int(par[ankle])
        hip = int(par[knee]) if knee >= 0 else -1
        if knee <= 0 or hip < 0:
            return None
        ends = np.nonzero(np.isin(skeleton.end_parents, joints))[0].astype(np.int64)
        out.append(Leg(hip, knee, ankle, joints, ends))
    return out[0], out[1]


def _norm(v, eps=1e-9):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, eps), n[..., 0]


def two_bone_ik(a, b, c, t, a_gr, b_gr, fallback_axis, eps: float = 1e-5):
    """Rotations that bring the end ``c`` of the chain ``a -> b -> c`` to the target ``t``.

    Args:
        a, b, c: ``(M, 3)`` world positions of the upper joint, middle joint and end.
        t: ``(M, 3)`` targets (clamped to the reachable distance).
        a_gr, b_gr: ``(M, 4)`` world rotations of the upper and middle joints.
        fallback_axis: ``(M, 3)`` world bend axis used when the chain is straight.

    Returns:
        ``(da, db)``: ``(M, 4)`` rotations to right-multiply onto the *local* rotations of ``a`` and ``b``.
    """
    lab = np.linalg.norm(b - a, axis=-1)
    lcb = np.linalg.norm(b - c, axis=-1)
    lat = np.clip(np.linalg.norm(t - a, axis=-1), eps, lab + lcb - eps)
    ca, _ = _norm(c - a)
    ba, _ = _norm(b - a)
    ab, _ = _norm(a - b)
    cb, _ = _norm(c - b)
    ta, _ = _norm(t - a)
    ac_ab_0 = np.arccos(np.clip(np.sum(ca * ba, axis=-1), -1.0, 1.0))
    ba_bc_0 = np.arccos(np.clip(np.sum(ab * cb, axis=-1), -1.0, 1.0))
    # the angle between c - a and t - a is often tiny: atan2 keeps it accurate where arccos would not
    ac_at_0 = np.arctan2(np.linalg.norm(np.cross(ca, ta), axis=-1), np.sum(ca * ta, axis=-1))
    ac_ab_1 = np.arccos(np.clip((lcb * lcb - lab * lab - lat * lat) / (-2.0 * lab * lat), -1.0, 1.0))
    ba_bc_1 = np.arccos(np.clip((lat * lat - lab * lab - lcb * lcb) / (-2.0 * lab * lcb), -1.0, 1.0))
    axis0, n0 = _norm(np.cross(c - a, b - a))
    axis0 = np.where((n0 < 1e-6)[:, None], fallback_axis, axis0)
    axis1, n1 = _norm(np.cross(c - a, t - a))
    axis1 = np.where((n1 < 1e-9)[:, None], axis0, axis1)
    r0 = quat.from_axis_angle(quat.inv_mul_vec(a_gr, axis0), ac_ab_1 - ac_ab_0)
    r1 = quat.from_axis_angle(quat.inv_mul_vec(b_gr, axis0), ba_bc_1 - ba_bc_0)
    r2 = quat.from_axis_angle(quat.inv_mul_vec(a_gr, axis1), ac_at_0)
    return quat.mul(r0, r2), r1


def pin_feet(q, gr, gp, leg: Leg, rows, target_xy, lowest_xy, heading, dz=None):
    """Move the ankle of ``leg`` horizontally by ``target_xy - lowest_xy`` (and up by ``dz``) for poses
    ``rows``.

    Args:
        q: ``(N, J, 4)`` local rotations (modified copy returned).
        gr, gp: ``(N, J, 4)``, ``(N, J, 3)`` world rotations and positions of the same poses.
        leg: the leg to move.
        rows: ``(M,)`` indices of the poses to change.
        target_xy, lowest_xy: ``(M, 2)`` where the foot's lowest point must be and where it is.
        heading: ``(M,)`` character headings (their lateral axis bends a straight knee).
        dz: ``(M,)`` metres to raise the ankle (the pelvis was lowered by as much), default 0.

    Returns:
        The new local rotations ``(N, J, 4)``; the foot keeps its world orientation.
    """
    if len(rows) == 0:
        return q
    q = q.copy()
    a, b, c = gp[rows, leg.hip], gp[rows, leg.knee], gp[rows, leg.ankle]
    t = c.copy()
    t[:, :2] += target_xy - lowest_xy
    if dz is not None:
        t[:, 2] += dz
    lateral = np.stack([-np.sin(heading), np.cos(heading), np.zeros_like(heading)], axis=-1)
    da, db = two_bone_ik(a, b, c, t, gr[rows, leg.hip], gr[rows, leg.knee], lateral)
    hip_l = quat.mul(q[rows, leg.hip], da)
    knee_l = quat.mul(q[rows, leg.knee], db)
    hip_parent = quat.mul_inv(gr[rows, leg.hip], q[rows, leg.hip])
    knee_w = quat.mul(quat.mul(hip_parent, hip_l), knee_l)
    q[rows, leg.hip] = hip_l
    q[rows, leg.knee] = knee_l
    q[rows, leg.ankle] = quat.inv_mul(knee_w, gr[rows, leg.ankle])
    return q


# ----------------------------------------------------------------------------------------- compiled
import numba


@numba.njit(cache=True, inline="always")
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):  # pragma: no cover - compiled
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1, a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@numba.njit(cache=True, inline="always")
def _qrot_inv(q0, q1, q2, q3, x, y, z):  # pragma: no cover - compiled
    # R(q)^T v = v + 2w (v x u) + 2 u x (u x v) with u = -(q1, q2, q3)
    u1, u2, u3 = -q1, -q2, -q3
    t1 = 2.0 * (u2 * z - u3 * y)
    t2 = 2.0 * (u3 * x - u1 * z)
    t3 = 2.0 * (u1 * y - u2 * x)
    return (x + q0 * t1 + (u2 * t3 - u3 * t2), y + q0 * t2 + (u3 * t1 - u1 * t3),
            z + q0 * t3 + (u1 * t2 - u2 * t1))


@numba.njit(cache=True, inline="always")
def _axis_angle(x, y, z, ang):  # pragma: no cover - compiled
    n = np.sqrt(x * x + y * y + z * z)
    if n < 1e-12:
        return 1.0, 0.0, 0.0, 0.0
    s = np.sin(0.5 * ang) / n
    return np.cos(0.5 * ang), x * s, y * s, z * s


@numba.njit(cache=True, inline="always")
def _unit(x, y, z):  # pragma: no cover - compiled
    n = np.sqrt(x * x + y * y + z * z)
    if n < 1e-9:
        return x, y, z, n
    return x / n, y / n, z / n, n


@numba.njit(cache=True, inline="always")
def _acos(x):  # pragma: no cover - compiled
    return np.arccos(min(1.0, max(-1.0, x)))


@numba.njit(cache=True)
def _pin_kernel(q, gr, gp, hip, knee, ankle, rows, target_xy, lowest_xy, heading, dz, eps):  # pragma: no cover
    for m in range(rows.shape[0]):
        n = rows[m]
        ax, ay, az = gp[n, hip, 0], gp[n, hip, 1], gp[n, hip, 2]
        bx, by, bz = gp[n, knee, 0], gp[n, knee, 1], gp[n, knee, 2]
        cx, cy, cz = gp[n, ankle, 0], gp[n, ankle, 1], gp[n, ankle, 2]
        tx = cx + target_xy[m, 0] - lowest_xy[m, 0]
        ty = cy + target_xy[m, 1] - lowest_xy[m, 1]
        tz = cz + dz[m]
        lab = np.sqrt((bx - ax) ** 2 + (by - ay) ** 2 + (bz - az) ** 2)
        lcb = np.sqrt((bx - cx) ** 2 + (by - cy) ** 2 + (bz - cz) ** 2)
        lat = np.sqrt((tx - ax) ** 2 + (ty - ay) ** 2 + (tz - az) ** 2)
        lat = min(max(lat, eps), lab + lcb - eps)
        cax, cay, caz, _ = _unit(cx - ax, cy - ay, cz - az)
        bax, bay, baz, _ = _unit(bx - ax, by - ay, bz - az)
        abx, aby, abz, _ = _unit(ax - bx, ay - by, az - bz)
        cbx, cby, cbz, _ = _unit(cx - bx, cy - by, cz - bz)
        tax, tay, taz, _ = _unit(tx - ax, ty - ay, tz - az)
        ac_ab_0 = _acos(cax * bax + cay * bay + caz * baz)
        ba_bc_0 = _acos(abx * cbx + aby * cby + abz * cbz)
        xx, xy_, xz = cay * taz - caz * tay, caz * tax - cax * taz, cax * tay - cay * tax
        ac_at_0 = np.arctan2(np.sqrt(xx * xx + xy_ * xy_ + xz * xz), cax * tax + cay * tay + caz * taz)
        ac_ab_1 = _acos((lcb * lcb - lab * lab - lat * lat) / (-2.0 * lab * lat))
        ba_bc_1 = _acos((lat * lat - lab * lab - lcb * lcb) / (-2.0 * lab * lcb))
        # axis0 = (c - a) x (b - a), axis1 = (c - a) x (t - a)
        ux, uy, uz = cx - ax, cy - ay, cz - az
        vx, vy, vz = bx - ax, by - ay, bz - az
        a0x, a0y, a0z, n0 = _unit(uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx)
        if n0 < 1e-6:
            a0x, a0y, a0z = -np.sin(heading[m]), np.cos(heading[m]), 0.0
        wx, wy, wz = tx - ax, ty - ay, tz - az
        a1x, a1y, a1z, n1 = _unit(uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx)
        if n1 < 1e-9:
            a1x, a1y, a1z = a0x, a0y, a0z
        A0, A1, A2, A3 = gr[n, hip, 0], gr[n, hip, 1], gr[n, hip, 2], gr[n, hip, 3]
        B0, B1, B2, B3 = gr[n, knee, 0], gr[n, knee, 1], gr[n, knee, 2], gr[n, knee, 3]
        lx, ly, lz = _qrot_inv(A0, A1, A2, A3, a0x, a0y, a0z)
        r0 = _axis_angle(lx, ly, lz, ac_ab_1 - ac_ab_0)
        lx, ly, lz = _qrot_inv(B0, B1, B2, B3, a0x, a0y, a0z)
        r1 = _axis_angle(lx, ly, lz, ba_bc_1 - ba_bc_0)
        lx, ly, lz = _qrot_inv(A0, A1, A2, A3, a1x, a1y, a1z)
        r2 = _axis_angle(lx, ly, lz, ac_at_0)
        da = _qmul(r0[0], r0[1], r0[2], r0[3], r2[0], r2[1], r2[2], r2[3])
        hl = _qmul(q[n, hip, 0], q[n, hip, 1], q[n, hip, 2], q[n, hip, 3], da[0], da[1], da[2], da[3])
        kl = _qmul(q[n, knee, 0], q[n, knee, 1], q[n, knee, 2], q[n, knee, 3], r1[0], r1[1], r1[2], r1[3])
        # parent of the hip in world = gr[hip] * inv(q[hip])
        P = _qmul(A0, A1, A2, A3, q[n, hip, 0], -q[n, hip, 1], -q[n, hip, 2], -q[n, hip, 3])
        hw = _qmul(P[0], P[1], P[2], P[3], hl[0], hl[1], hl[2], hl[3])
        kw = _qmul(hw[0], hw[1], hw[2], hw[3], kl[0], kl[1], kl[2], kl[3])
        fl = _qmul(kw[0], -kw[1], -kw[2], -kw[3], gr[n, ankle, 0], gr[n, ankle, 1], gr[n, ankle, 2],
                   gr[n, ankle, 3])
        for c in range(4):
            q[n, hip, c] = hl[c]
            q[n, knee, c] = kl[c]
            q[n, ankle, c] = fl[c]


def pin_feet_fast(q, gr, gp, leg: Leg, rows, target_xy, lowest_xy, heading, eps: float = 1e-5, dz=None):
    """Compiled :func:`pin_feet` (same result); modifies ``q`` in place and returns it."""
    if len(rows):
        dz = np.zeros(len(rows)) if dz is None else np.broadcast_to(np.asarray(dz, dtype=np.float64), (len(rows),))
        _pin_kernel(q, gr, gp, leg.hip, leg.knee, leg.ankle, np.ascontiguousarray(rows, dtype=np.int64),
                    np.ascontiguousarray(target_xy, dtype=np.float64), np.ascontiguousarray(lowest_xy, dtype=np.float64),
                    np.ascontiguousarray(heading, dtype=np.float64), np.ascontiguousarray(dz), eps)
    return q
