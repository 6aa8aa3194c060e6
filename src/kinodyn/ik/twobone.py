"""Two-bone inverse kinematics for the clips and the foot lock.

Two analytic two-bone solvers, the closed-form solution of a two-link chain (the law of cosines gives
the middle joint's bend), in the two forms kinodyn needs:

- :func:`two_bone_ik` builds a chain from scratch toward a *pole* (the built-in clips' legs and arms,
  :mod:`kinodyn.data.procedural`): the ``ik_two_bone`` of most game engines, on the conventions of
  :mod:`kinodyn.data.skeleton` (in the rest pose both bones are collinear along the upper joint's local
  ``bone`` axis, ``-Z``, and the middle joint is a hinge about a local ``hinge`` axis perpendicular to
  it, positive angle = flexion; a flexed middle joint points, in the upper bone's frame, along
  :func:`bend_direction` ``= bone x hinge``).
- :func:`two_bone_delta` corrects a posed chain (the foot lock of :mod:`kinodyn.blend.footlock`): the
  analytic solver of Daniel Holden's Motion-Matching code, skeleton-agnostic, on world positions and
  rotations from forward kinematics; :func:`two_bone_delta_kernel` is its compiled scalar form.

The iterative solver for longer chains is :mod:`kinodyn.ik.ccd`.

Shapes: ``(..., 3)`` points and directions, ``(..., 4)`` quaternions ``(w, x, y, z)``; every function
broadcasts over the leading axes (frames, poses). Lengths in metres, angles in radians.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.math import quat
from kinodyn.math.kernels import acos_clipped, axis_angle, qmul, qrot_inv, unit

__all__ = ["TwoBoneSolution", "bend_direction", "knee_angle", "two_bone_delta", "two_bone_delta_kernel",
           "two_bone_fk", "two_bone_ik"]

_EPS = 1e-12


class TwoBoneSolution(NamedTuple):
    """Result of :func:`two_bone_ik`.

    Attributes:
        upper_local: ``(..., 4)`` local rotation of the upper joint (hip, shoulder) in its parent's frame.
        lower_local: ``(..., 4)`` local rotation of the middle joint (knee, elbow): a pure hinge.
        upper_world: ``(..., 4)`` world rotation of the upper joint.
        lower_world: ``(..., 4)`` world rotation of the middle joint.
        angle: ``(...)`` hinge angle (flexion, rad).
        reached: ``(...)`` bool, False where the target was out of reach (the limb points at it,
            fully stretched or fully folded).
    """

    upper_local: np.ndarray
    lower_local: np.ndarray
    upper_world: np.ndarray
    lower_world: np.ndarray
    angle: np.ndarray
    reached: np.ndarray


def bend_direction(bone, hinge) -> np.ndarray:
    """Direction ``(3,)`` the middle joint points to when flexed, in the upper bone's frame.

    A positive hinge rotation about ``hinge`` swings the lower bone toward ``hinge x bone``; the joint
    itself sticks out the opposite way, ``bone x hinge``.
    """
    bone = np.asarray(bone, dtype=np.float64)
    hinge = np.asarray(hinge, dtype=np.float64)
    b = np.cross(bone, hinge)
    return b / np.linalg.norm(b)


def knee_angle(l1: float, l2: float, d) -> np.ndarray:
    """Flexion angle ``(...)`` of the middle joint of a chain of lengths ``l1``, ``l2`` whose ends are
    ``d (...)`` apart (law of cosines; ``d`` is clipped to the reachable range)."""
    d = np.clip(np.asarray(d, dtype=np.float64), abs(l1 - l2), l1 + l2)
    c = np.clip((l1 * l1 + l2 * l2 - d * d) / (2.0 * l1 * l2), -1.0, 1.0)
    return np.pi - np.arccos(c)


def _frame(a, b) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` with columns ``a``, ``b``, ``a x b`` (a, b orthonormal)."""
    return np.stack([a, b, np.cross(a, b)], axis=-1)


def two_bone_ik(root, parent_rot, target, pole, l1: float, l2: float, bone=(0.0, 0.0, -1.0),
                hinge=(0.0, 1.0, 0.0), eps: float = 1e-9) -> TwoBoneSolution:
    """Rotations putting the end of a two-bone chain at ``target``, bending toward ``pole``.

    Args:
        root: ``(..., 3)`` world position of the upper joint (hip, shoulder).
        parent_rot: ``(..., 4)`` world rotation of the upper joint's parent (pelvis, clavicle).
        target: ``(..., 3)`` world position wanted for the end joint (ankle, wrist).
        pole: ``(..., 3)`` world direction the middle joint (knee, elbow) should point to; only its
            part perpendicular to ``target - root`` matters, so it must not be parallel to it.
        l1, l2: upper and lower bone lengths (m).
        bone: ``(3,)`` rest direction of both bones in the upper joint's local frame.
        hinge: ``(3,)`` hinge axis of the middle joint in its local frame (perpendicular to ``bone``);
            a positive angle about it is flexion.
        eps: the distance is kept ``eps`` inside the reachable range so the hinge angle stays smooth.

    Returns:
        :class:`TwoBoneSolution`. When the target is reachable, forward kinematics of the result puts
        the end joint on it (to rounding error); otherwise the chain points at it.
    """
    if l1 <= 0 or l2 <= 0:
        raise ParameterError(f"bone lengths must be positive, got {l1} and {l2}")
    root = np.asarray(root, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    parent_rot = np.asarray(parent_rot, dtype=np.float64)
    pole = np.asarray(pole, dtype=np.float64)
    bone = np.asarray(bone, dtype=np.float64)
    bone = bone / np.linalg.norm(bone)
    hinge = np.asarray(hinge, dtype=np.float64)
    hinge = hinge / np.linalg.norm(hinge)
    if abs(float(bone @ hinge)) > 1e-9:
        raise ParameterError("the hinge axis must be perpendicular to the bone direction")
    bend = bend_direction(bone, hinge)

    v = target - root
    dist = np.linalg.norm(v, axis=-1)
    lo, hi = abs(l1 - l2) + eps, l1 + l2 - eps
    reached = (dist >= lo) & (dist <= hi)
    d = np.clip(dist, lo, hi)
    u = v / np.maximum(dist, _EPS)[..., None]
    # Pole direction made perpendicular to the root-target line.
    m = pole - np.sum(pole * u, axis=-1, keepdims=True) * u
    m = m / np.maximum(np.linalg.norm(m, axis=-1, keepdims=True), _EPS)
    # Angle at the upper joint between the upper bone and the root-target line.
    ca = np.clip((l1 * l1 + d * d - l2 * l2) / (2.0 * l1 * d), -1.0, 1.0)
    sa = np.sqrt(1.0 - ca * ca)
    t = ca[..., None] * u + sa[..., None] * m  # upper bone direction (world)
    x = -sa[..., None] * u + ca[..., None] * m  # where the middle joint points (world), normal to t
    world = _frame(t, x) @ _frame(bone, bend).T  # maps bone -> t, bend -> x
    upper_world = quat.from_matrix(world)
    theta = knee_angle(l1, l2, d)
    lower_local = quat.from_axis_angle(hinge, theta)
    upper_local = quat.inv_mul(parent_rot, upper_world)
    lower_world = quat.mul(upper_world, lower_local)
    return TwoBoneSolution(upper_local, lower_local, upper_world, lower_world, theta, reached)


def two_bone_fk(root, parent_rot, upper_local, lower_local, l1: float, l2: float,
                bone=(0.0, 0.0, -1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics of the chain: world positions ``(..., 3)`` of the middle and end joints."""
    bone = np.asarray(bone, dtype=np.float64)
    bone = bone / np.linalg.norm(bone)
    uw = quat.mul(parent_rot, upper_local)
    mid = np.asarray(root, dtype=np.float64) + quat.mul_vec(uw, l1 * bone)
    end = mid + quat.mul_vec(quat.mul(uw, lower_local), l2 * bone)
    return mid, end


def _norm(v, eps=1e-9):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, eps), n[..., 0]


def two_bone_delta(a, b, c, t, a_gr, b_gr, fallback_axis, eps: float = 1e-5):
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


@numba.njit(cache=True, inline="always")
def two_bone_delta_kernel(ax, ay, az, bx, by, bz, cx, cy, cz, tx, ty, tz, A0, A1, A2, A3, B0, B1, B2, B3,
                          fx, fy, fz, eps):  # pragma: no cover - compiled
    """Compiled :func:`two_bone_delta` for one chain, on scalars: ``a``, ``b``, ``c`` the joints, ``t``
    the target, ``A``, ``B`` the world rotations of ``a`` and ``b``, ``f`` the fallback bend axis.
    Returns ``(da, db)`` as two 4-tuples."""
    lab = np.sqrt((bx - ax) ** 2 + (by - ay) ** 2 + (bz - az) ** 2)
    lcb = np.sqrt((bx - cx) ** 2 + (by - cy) ** 2 + (bz - cz) ** 2)
    lat = np.sqrt((tx - ax) ** 2 + (ty - ay) ** 2 + (tz - az) ** 2)
    lat = min(max(lat, eps), lab + lcb - eps)
    cax, cay, caz, _ = unit(cx - ax, cy - ay, cz - az)
    bax, bay, baz, _ = unit(bx - ax, by - ay, bz - az)
    abx, aby, abz, _ = unit(ax - bx, ay - by, az - bz)
    cbx, cby, cbz, _ = unit(cx - bx, cy - by, cz - bz)
    tax, tay, taz, _ = unit(tx - ax, ty - ay, tz - az)
    ac_ab_0 = acos_clipped(cax * bax + cay * bay + caz * baz)
    ba_bc_0 = acos_clipped(abx * cbx + aby * cby + abz * cbz)
    xx, xy_, xz = cay * taz - caz * tay, caz * tax - cax * taz, cax * tay - cay * tax
    ac_at_0 = np.arctan2(np.sqrt(xx * xx + xy_ * xy_ + xz * xz), cax * tax + cay * tay + caz * taz)
    ac_ab_1 = acos_clipped((lcb * lcb - lab * lab - lat * lat) / (-2.0 * lab * lat))
    ba_bc_1 = acos_clipped((lat * lat - lab * lab - lcb * lcb) / (-2.0 * lab * lcb))
    # axis0 = (c - a) x (b - a), axis1 = (c - a) x (t - a)
    ux, uy, uz = cx - ax, cy - ay, cz - az
    vx, vy, vz = bx - ax, by - ay, bz - az
    a0x, a0y, a0z, n0 = unit(uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx)
    if n0 < 1e-6:
        a0x, a0y, a0z = fx, fy, fz
    wx, wy, wz = tx - ax, ty - ay, tz - az
    a1x, a1y, a1z, n1 = unit(uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx)
    if n1 < 1e-9:
        a1x, a1y, a1z = a0x, a0y, a0z
    lx, ly, lz = qrot_inv(A0, A1, A2, A3, a0x, a0y, a0z)
    r0 = axis_angle(lx, ly, lz, ac_ab_1 - ac_ab_0)
    lx, ly, lz = qrot_inv(B0, B1, B2, B3, a0x, a0y, a0z)
    r1 = axis_angle(lx, ly, lz, ba_bc_1 - ba_bc_0)
    lx, ly, lz = qrot_inv(A0, A1, A2, A3, a1x, a1y, a1z)
    r2 = axis_angle(lx, ly, lz, ac_at_0)
    da = qmul(r0[0], r0[1], r0[2], r0[3], r2[0], r2[1], r2[2], r2[3])
    return da, r1
