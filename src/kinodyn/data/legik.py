"""Analytic two-bone inverse kinematics (hip-knee-ankle, shoulder-elbow-wrist).

The closed-form solution of a two-link chain: the law of cosines gives the middle joint's bend, a
pole direction picks the plane the limb bends in. This is the ``ik_two_bone`` of Daniel Holden's
Motion-Matching code and of most game engines, written batch-first.

Conventions (those of :mod:`kinodyn.data.skeleton`): in the rest pose both bones of the chain are
collinear along the upper joint's local ``bone`` axis (``-Z``), and the middle joint is a hinge about a
local ``hinge`` axis perpendicular to it, positive angle = flexion. A flexed middle joint then points,
in the upper bone's frame, along :func:`bend_direction` ``= bone x hinge`` (``+X`` for a knee with hinge
``+Y``, ``-X`` for an elbow with hinge ``-Y``); the solver turns that direction toward the pole.

Shapes: ``(..., 3)`` points and directions, ``(..., 4)`` quaternions ``(w, x, y, z)``; every function
broadcasts over the leading axes (frames). Lengths in metres, angles in radians.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.math import quat

__all__ = ["TwoBoneSolution", "bend_direction", "knee_angle", "two_bone_fk", "two_bone_ik"]

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
