"""Joint roles from joint names: which joint is a foot, a toe, a hand, a finger, the head..., and its side.

Skeletons from different sources name their joints differently (CMU BVH ``LeftUpLeg``, ASF ``lfemur``,
3ds Max ``LeftHip``, ``l_ankle``, kinodyn's built-in names). Every part of kinodyn that needs to know
what a joint is asks here, so a new naming convention is taught in one place:

- :data:`ROLES`: role -> regular expression searched in the joint name, case-insensitively. The rows
  that name joint types (``thigh``, ``knee``, ``forearm``...) are the patterns of
  :data:`kinodyn.limits.JOINT_TYPES`, which tries them in its own order (first match wins).
- :data:`BONE_ROLES`, :func:`bone_role`: what the bone ending at a point is (the viewer's capsule radii).
- :func:`side_of`: ``"left"``, ``"right"`` or None from side markers (``Left``, ``l_``, ``_R``, ``lfoot``).
- :func:`mirror_name`: the opposite side's name (``LeftArm`` -> ``RightArm``, ``lfemur`` -> ``rfemur``).
- :func:`feet`, :func:`end_sites_of`, :func:`foot_point_indices`: foot joints per side and their end
  sites, over a :class:`~kinodyn.skeleton.Skeleton` (any object with ``names``, ``num_joints`` and
  ``end_parents``).
"""

from __future__ import annotations

import re
from functools import cache

import numpy as np

from kinodyn.errors import UnknownNameError

__all__ = ["BONE_ROLES", "ROLES", "SIDES", "bone_role", "end_sites_of", "feet", "foot_point_indices", "has_role", "joints_with_role",
           "mirror_name", "pattern", "side_of"]

SIDES = ("left", "right")

#: role -> regex searched in the joint name (case-insensitive).
ROLES: dict[str, str] = {
    # body parts
    "foot": r"(foot|ankle|toe|heel|ball|tarsal|metatars)",  # every joint of a foot (contact detection)
    "finger": r"finger|thumb|index|middle|ring|pinky|hand.*\d|^[lr]hand$",
    "end_site": r"(_end|end|nub|site|tip)$",  # a leaf joint that only marks a bone's tip
    # joint types (kinodyn.limits), from the hip down, then the arm, then the trunk
    "hip_joint": r"hipjoint",
    "thigh": r"upleg|thigh|femur|^(left|right|l|r)_?hip$|upperleg",
    "knee": r"knee|shin|tibia|calf|lowerleg|(?<!up)leg$",
    "ankle": r"foot|ankle",
    "toe": r"toe",
    "clavicle": r"clavicle|collar",
    "forearm": r"forearm|elbow|radius|lowerarm",
    "upper_arm": r"upperarm|humerus|(?<!fore)arm$",
    "shoulder": r"shoulder",
    "wrist": r"hand|wrist",
    "neck": r"neck",
    "head": r"head",
    "spine": r"spine|chest|back|torso|abdomen|thorax|pelvis|waist|lowerback|upperback",
}

#: The bone ending at a point, from the point's name (joints, and end sites named ``<joint>_end``), tried
#: in order, first match wins. The bone ending at joint ``LeftLeg`` is the thigh, the one ending at
#: ``Head`` the neck, the one ending at ``Head_end`` the head itself.
BONE_ROLES: tuple[tuple[str, str], ...] = (
    ("head", r"head.*_end$"),
    ("hand", r"(finger|thumb|index|middle|ring|pinky|hand.*_end|wrist.*_end|fingers)"),
    ("neck", r"head"),
    ("neck_base", r"neck"),
    ("upper_arm", r"(forearm|elbow|radius|lowerarm)"),
    ("shoulder", r"(arm|humerus)"),
    ("clavicle", r"(shoulder|clavicle|collar)"),
    ("forearm", r"(hand|wrist)"),
    ("trunk", r"(spine|chest|back|thorax|torso|abdomen|pelvis|waist)"),
    ("pelvis", r"(upleg|thigh|femur|hip)"),
    ("toe", r"toe.*_end$"),
    ("foot", r"(toe|ball)"),
    ("shin", r"(foot|ankle)"),
    ("thigh", r"(leg|knee|tibia|shin|calf)"),
)
_BONES = tuple((role, re.compile(p)) for role, p in BONE_ROLES)

# Side markers: a prefix or suffix word (case as written), or CMU's lower-case l/r before a foot bone.
_LEFT = re.compile(r"^(left|[lL](?=[A-Z_])|l(?=(foot|toes?|ankle|heel)$))|(_l$|_L$|Left)")
_RIGHT = re.compile(r"^(right|[rR](?=[A-Z_])|r(?=(foot|toes?|ankle|heel)$))|(_r$|_R$|Right)")

# (pattern, replacement) tried in turn by mirror_name; the first that matches is replaced once.
_MIRROR_RULES = (
    (re.compile(r"^Left"), "Right"), (re.compile(r"^Right"), "Left"),
    (re.compile(r"^left"), "right"), (re.compile(r"^right"), "left"),
    (re.compile(r"^L(?=[A-Z_])"), "R"), (re.compile(r"^R(?=[A-Z_])"), "L"),
    (re.compile(r"^l(?=[A-Z_])"), "r"), (re.compile(r"^r(?=[A-Z_])"), "l"),
    (re.compile(r"^l_"), "r_"), (re.compile(r"^r_"), "l_"),
    (re.compile(r"Left"), "Right"), (re.compile(r"Right"), "Left"),
    (re.compile(r"_l$"), "_r"), (re.compile(r"_r$"), "_l"),
    (re.compile(r"_L$"), "_R"), (re.compile(r"_R$"), "_L"),
)
# CMU ASF style: lowercase l/r prefix before a lowercase bone name (lfemur, rhand, lthumb).
_CMU_SIDED = re.compile(r"^([lr])(femur|tibia|foot|toes|clavicle|humerus|radius|wrist|hand|fingers|thumb|hipjoint)$")


@cache
def pattern(role: str) -> re.Pattern:
    """The compiled (case-insensitive) pattern of ``role``."""
    if role not in ROLES:
        raise UnknownNameError(f"unknown joint role {role!r}; roles: {', '.join(ROLES)}")
    return re.compile(ROLES[role], re.IGNORECASE)


def has_role(name: str, role: str) -> bool:
    """Whether joint name ``name`` matches ``role``."""
    return pattern(role).search(name) is not None


def joints_with_role(skeleton, role: str) -> list[int]:
    """Indices of the joints of ``skeleton`` whose names match ``role``, in joint order."""
    reg = pattern(role)
    return [i for i, n in enumerate(skeleton.names) if reg.search(n)]


def bone_role(point_name: str) -> str | None:
    """The role (:data:`BONE_ROLES`) of the bone ending at a point, from its lower-cased name; None if
    no row matches."""
    n = point_name.lower()
    for role, reg in _BONES:
        if reg.search(n):
            return role
    return None


def side_of(name: str) -> str | None:
    """``"left"``, ``"right"`` or None (no side marker) for a joint name."""
    if _LEFT.search(name):
        return "left"
    if _RIGHT.search(name):
        return "right"
    return None


def mirror_name(name: str) -> str:
    """The name of the opposite-side joint (``LeftArm`` -> ``RightArm``, ``lfemur`` -> ``rfemur``).

    Names without a side marker map to themselves.
    """
    for pat, rep in _MIRROR_RULES:
        if pat.search(name):
            return pat.sub(rep, name, count=1)
    m = _CMU_SIDED.match(name)
    if m:
        return ("r" if m.group(1) == "l" else "l") + m.group(2)
    return name


def feet(skeleton) -> dict[str, list[int]]:
    """Foot joints per side (``{"left": [...], "right": [...]}``, joint order): joints in the ``foot`` role
    with a side marker. A side may be empty (:func:`kinodyn.contacts.find_feet` reports that)."""
    out: dict[str, list[int]] = {s: [] for s in SIDES}
    for j in joints_with_role(skeleton, "foot"):
        s = side_of(skeleton.names[j])
        if s is not None:
            out[s].append(j)
    return out


def end_sites_of(skeleton, joints) -> np.ndarray:
    """``(E',)`` indices of the end sites whose parent joint is among ``joints``."""
    return np.nonzero(np.isin(skeleton.end_parents, np.asarray(joints, dtype=np.int64)))[0]


def foot_point_indices(skeleton, foot_joints: dict) -> dict[str, np.ndarray]:
    """Point indices of each foot, points numbered joints first then end sites (``J + e``): the foot's
    joints ``foot_joints[side]`` followed by their end sites."""
    return {side: np.concatenate([np.asarray(idx, dtype=np.int64),
                                  end_sites_of(skeleton, idx) + skeleton.num_joints]).astype(np.int64)
            for side, idx in foot_joints.items()}
