"""Joint limits: the one specification of human joint ranges in kinodyn.

Physics bodies take their joint ranges from here (MuJoCo ball joints bound the total rotation angle,
hinges a signed angle about their axis), inverse kinematics clamps with :func:`clamp`, and clip checks
use :func:`violations`. Limits are measured from the skeleton's rest pose (zero local rotation), which
for BVH skeletons is the T-pose or the standing pose the file was drawn in.

Joint kinds are found from joint names by the rows of :data:`JOINT_TYPES` (first match wins, case
insensitive), so CMU (``LeftUpLeg``, ``LeftLeg``), 3ds Max (``LeftHip``, ``LeftKnee``), ASF (``lfemur``,
``ltibia``) and kinodyn's built-in names all work. Hinge axes come from the rest geometry: the axis is
perpendicular to the bone and to the facing direction (+X), signed so that a positive angle is
flexion (the knee moves the foot backward, the elbow moves the hand forward).

Angles are radians. Shapes: ``J`` joints, ``(..., J, 4)`` local rotations.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.math import quat
from kinodyn.roles import ROLES, has_role
from kinodyn.skeleton import Skeleton

__all__ = ["JointLimit", "JOINT_TYPES", "limits_for", "joint_kind", "violations", "LimitReport", "clamp",
           "HINGE_OFF_AXIS_TOLERANCE", "bone_direction"]

_DEG = np.pi / 180.0
FORWARD = np.array([1.0, 0.0, 0.0])
LATERAL = np.array([0.0, 1.0, 0.0])
#: Off-axis rotation a hinge may show in captured data before it counts as a violation.
HINGE_OFF_AXIS_TOLERANCE = 25.0 * _DEG


@dataclass(frozen=True)
class JointLimit:
    """Range of one joint, measured from the rest pose.

    Attributes:
        kind: ``"root"`` (free, unlimited), ``"ball"`` (total rotation angle at most ``max_angle``),
            ``"hinge"`` (rotation about ``axis`` between ``lower`` and ``upper``) or ``"fixed"``
            (nearly rigid: at most ``max_angle``, merged or welded by physics).
        max_angle: bound of the rotation angle for ball and fixed joints (rad).
        axis: unit hinge axis in the joint's local frame.
        lower, upper: hinge angle range (rad), positive = flexion.
        name: the joint type (row of :data:`JOINT_TYPES`) that matched.
        twist_axis: for hinges, the rest direction of the bone below the joint; captured data may
            turn about it (forearm pronation, tibial rotation) by up to ``max_twist`` (rad). Physics
            and IK model the hinge alone.
    """

    kind: str
    max_angle: float = np.pi
    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)
    lower: float = 0.0
    upper: float = 0.0
    name: str = ""
    twist_axis: tuple[float, float, float] = (0.0, 0.0, -1.0)
    max_twist: float = 0.0

    def __post_init__(self):
        if self.kind not in ("root", "ball", "hinge", "fixed"):
            raise ParameterError(f"joint kind must be root, ball, hinge or fixed, got {self.kind!r}")
        if not (0.0 <= self.max_angle <= np.pi):
            raise ParameterError(f"max_angle must be within [0, pi], got {self.max_angle}")
        if self.kind == "hinge" and not (self.lower <= self.upper):
            raise ParameterError(f"hinge range must have lower <= upper, got [{self.lower}, {self.upper}]")


# (type name, kind, parameters), tried in this order (first match wins); each type's name pattern is its
# row of kinodyn.roles.ROLES. Ranges are generous human ranges from the rest pose; "flex" hinges bend the
# distal end backward (knee) or forward (elbow).
_TYPE_LIMITS: tuple[tuple[str, str, dict], ...] = (
    ("hip_joint", "fixed", {"max_angle": 10 * _DEG}),
    ("thigh", "ball", {"max_angle": 125 * _DEG}),
    ("knee", "hinge", {"lower": -10 * _DEG, "upper": 155 * _DEG, "bend": "backward", "twist": 45 * _DEG}),
    ("ankle", "ball", {"max_angle": 60 * _DEG}),
    ("toe", "ball", {"max_angle": 60 * _DEG}),
    ("clavicle", "ball", {"max_angle": 35 * _DEG}),
    ("forearm", "hinge", {"lower": -10 * _DEG, "upper": 155 * _DEG, "bend": "forward", "twist": 100 * _DEG}),
    ("upper_arm", "ball", {"max_angle": 175 * _DEG}),
    ("shoulder", "ball", {"max_angle": 35 * _DEG}),  # CMU: the clavicle is "LeftShoulder"
    ("finger", "ball", {"max_angle": 90 * _DEG}),
    ("wrist", "ball", {"max_angle": 85 * _DEG}),
    ("neck", "ball", {"max_angle": 60 * _DEG}),
    ("head", "ball", {"max_angle": 60 * _DEG}),
    ("spine", "ball", {"max_angle": 50 * _DEG}),
)
#: (type name, regex on the joint name, kind, parameters), first match wins.
JOINT_TYPES: tuple[tuple[str, str, str, dict], ...] = tuple((n, ROLES[n], k, kw) for n, k, kw in _TYPE_LIMITS)
_DEFAULT = ("other", "ball", {"max_angle": 90 * _DEG})
_COMPILED = [(n, re.compile(p, re.IGNORECASE), k, kw) for n, p, k, kw in JOINT_TYPES]


def joint_kind(skeleton: Skeleton, j: int) -> tuple[str, str, dict]:
    """``(type name, kind, parameters)`` of joint ``j`` from its name (and its parent's, for shoulders)."""
    if j == 0:
        return "root", "root", {}
    name = skeleton.names[j]
    for tname, reg, kind, kw in _COMPILED:
        if reg.search(name):
            if tname == "shoulder":
                # 3ds Max and others call the upper arm "Shoulder" and the clavicle "Collar".
                parent = skeleton.names[skeleton.parents[j]]
                if has_role(parent, "clavicle"):
                    return ("upper_arm", "ball", {"max_angle": 175 * _DEG})
            return tname, kind, kw
    return _DEFAULT


def bone_direction(skeleton: Skeleton, j: int) -> np.ndarray:
    """Rest direction of the bone that starts at joint ``j`` (toward its first child or end site)."""
    kids = skeleton.children(j)
    if len(kids):
        v = skeleton.offsets[kids].mean(axis=0)
    else:
        ends = np.nonzero(skeleton.end_parents == j)[0]
        v = skeleton.end_offsets[ends].mean(axis=0) if len(ends) else skeleton.offsets[j]
    n = np.linalg.norm(v)
    return v / n if n > 1e-9 else np.array([0.0, 0.0, -1.0])


def _hinge_axis(d: np.ndarray, bend: str) -> np.ndarray:
    """Axis a with ``a x d`` pointing backward (knee) or forward (elbow) for bone direction ``d``."""
    target = -FORWARD if bend == "backward" else FORWARD
    a = np.cross(d, target)
    n = np.linalg.norm(a)
    if n < 0.3:  # bone along the facing direction: fall back to the lateral axis
        return LATERAL if bend == "backward" else -LATERAL
    return a / n


def limits_for(skeleton: Skeleton) -> tuple[JointLimit, ...]:
    """One :class:`JointLimit` per joint of ``skeleton`` (see the module docstring)."""
    out = []
    for j in range(skeleton.num_joints):
        tname, kind, kw = joint_kind(skeleton, j)
        if kind == "root":
            out.append(JointLimit("root", name="root"))
        elif kind == "hinge":
            bone = bone_direction(skeleton, j)
            axis = _hinge_axis(bone, kw["bend"])
            out.append(JointLimit("hinge", axis=tuple(float(x) for x in axis), lower=kw["lower"],
                                  upper=kw["upper"], name=tname, twist_axis=tuple(float(x) for x in bone),
                                  max_twist=kw["twist"]))
        else:
            out.append(JointLimit(kind, max_angle=kw["max_angle"], name=tname))
    return tuple(out)


def _hinge_angles(q: np.ndarray, axis: np.ndarray, bone: np.ndarray | None = None):
    """Hinge angle about ``axis``, twist angle about ``bone`` and the remaining off-axis angle of
    rotations ``q (..., 4)``, from ``q = off * bone_twist * hinge``."""
    q = quat.abs(q)
    swing, hinge = quat.swing_twist(q, axis)
    theta = 2.0 * np.arctan2(hinge[..., 1:] @ axis, hinge[..., 0])
    if bone is None:
        return theta, np.zeros_like(theta), quat.angle(swing)
    off, twist = quat.swing_twist(swing, bone)
    return theta, quat.angle(twist), quat.angle(off)


@dataclass(frozen=True)
class LimitReport:
    """How far a motion goes outside the joint limits.

    Attributes:
        excess: ``(J,)`` largest excess angle (rad) of each joint over all frames (0 inside the limits).
        worst_joint: name of the joint with the largest excess.
        worst_frame: frame where it happens.
        ok: True when every excess is within the tolerance used.
    """

    excess: np.ndarray
    worst_joint: str
    worst_frame: int
    ok: bool

    def __str__(self) -> str:
        if self.ok:
            return "all joints within limits"
        return (f"joint {self.worst_joint!r} exceeds its limit by {np.rad2deg(self.excess.max()):.1f} deg "
                f"at frame {self.worst_frame}")


def _excess(local_rot: np.ndarray, limits) -> np.ndarray:
    """``(F, J)`` excess angle of each joint in each frame."""
    f, j = local_rot.shape[:2]
    out = np.zeros((f, j))
    for k, lim in enumerate(limits):
        q = local_rot[:, k]
        if lim.kind in ("ball", "fixed"):
            out[:, k] = np.maximum(quat.angle(q) - lim.max_angle, 0.0)
        elif lim.kind == "hinge":
            theta, twist, off = _hinge_angles(q, np.asarray(lim.axis), np.asarray(lim.twist_axis))
            out[:, k] = (np.maximum(theta - lim.upper, 0.0) + np.maximum(lim.lower - theta, 0.0)
                         + np.maximum(twist - lim.max_twist, 0.0)
                         + np.maximum(off - HINGE_OFF_AXIS_TOLERANCE, 0.0))
    return out


def violations(motion, limits=None, tolerance: float = 1e-6) -> LimitReport:
    """Check a motion against joint limits (default: :func:`limits_for` its skeleton)."""
    limits = limits_for(motion.skeleton) if limits is None else tuple(limits)
    if len(limits) != motion.num_joints:
        raise ParameterError(f"need one limit per joint ({motion.num_joints}), got {len(limits)}")
    ex = _excess(motion.local_rot, limits)
    per_joint = ex.max(axis=0) if len(ex) else np.zeros(motion.num_joints)
    jw = int(np.argmax(per_joint))
    fw = int(np.argmax(ex[:, jw])) if len(ex) else 0
    return LimitReport(per_joint, motion.skeleton.names[jw], fw, bool(per_joint.max(initial=0.0) <= tolerance))


def clamp(local_rot, limits) -> np.ndarray:
    """Project local rotations ``(..., J, 4)`` into the limits (ball: shorten the rotation to
    ``max_angle``; hinge: keep only the rotation about the axis, clipped to its range)."""
    q = np.array(local_rot, dtype=np.float64, copy=True)
    limits = tuple(limits)
    if q.shape[-2] != len(limits):
        raise ParameterError(f"need one limit per joint ({q.shape[-2]}), got {len(limits)}")
    ball = [k for k, lim in enumerate(limits) if lim.kind in ("ball", "fixed")]
    if ball:
        maxa = np.array([limits[k].max_angle for k in ball])
        v = quat.to_rotvec(q[..., ball, :])
        a = np.linalg.norm(v, axis=-1)
        s = np.where(a > maxa, maxa / np.maximum(a, 1e-12), 1.0)
        q[..., ball, :] = np.where((a > maxa)[..., None], quat.from_rotvec(v * s[..., None]), q[..., ball, :])
    for k, lim in enumerate(limits):
        if lim.kind == "hinge":
            axis = np.asarray(lim.axis)
            theta = _hinge_angles(q[..., k, :], axis)[0]
            q[..., k, :] = quat.from_axis_angle(axis, np.clip(theta, lim.lower, lim.upper))
    return q
