"""Segment layout of a character body: which skeleton joints get a segment, their classes and sides.

The planning half of :func:`kinodyn.physics.body.build_body` (the rules are in that module's docstring):
:func:`merge_plan` decides which joints merge into their parent (fixed joints, fingers, toes when asked,
zero-length duplicates, empty leaves), :func:`segment_classes` names each kept segment's class from its
joint limits and from the tree (the spine path to the head, the chest where the arms attach, limb chains
named from their ends), :func:`joint_side` its side and :func:`points_of_cluster` what it carries.

Shapes: ``J`` skeleton joints, ``B`` kept segments; ``pos (J, 3)`` rest positions in metres.
"""

from __future__ import annotations

import numpy as np

from kinodyn import roles
from kinodyn.errors import SkeletonError, UnknownNameError
from kinodyn.skeleton import Skeleton

__all__ = [
    "ERR_ZERO_BONE",
    "LIMIT_CLASS",
    "is_descendant",
    "joint_depth",
    "joint_side",
    "merge_plan",
    "points_of_cluster",
    "segment_classes",
    "structural_classes",
]

LIMIT_CLASS = {"thigh": "thigh", "knee": "shin", "ankle": "foot", "toe": "toe", "clavicle": "clavicle",
                "shoulder": "clavicle", "upper_arm": "upperarm", "forearm": "forearm", "wrist": "hand",
                "neck": "neck", "head": "head", "spine": "spine", "finger": "hand", "hip_joint": "pelvis"}

ERR_ZERO_BONE = ("joint {name!r} has a zero-length bone ({mm:.2f} mm from its parent {parent!r}) in the middle "
                 "of a chain; a body segment cannot be built for it (fix the skeleton's offsets)")


def joint_side(skeleton: Skeleton, j: int, pos: np.ndarray) -> str:
    """``"left"``, ``"right"`` or ``""`` for joint ``j``: from its name, else from its rest ``y``."""
    s = roles.side_of(skeleton.names[j])
    if s:
        return s
    y = pos[j, 1]
    return "left" if y > 1e-3 else "right" if y < -1e-3 else ""


def merge_plan(skeleton: Skeleton, lims, cfg) -> tuple[np.ndarray, list[str]]:
    """``(J,)`` kept flags and a reason per merged joint."""
    j_n = skeleton.num_joints
    kept = np.ones(j_n, dtype=bool)
    reason = [""] * j_n
    nkids = np.bincount(skeleton.parents[1:], minlength=j_n) if j_n > 1 else np.zeros(1, dtype=int)
    nends = np.bincount(skeleton.end_parents, minlength=j_n) if len(skeleton.end_parents) else np.zeros(j_n, int)
    bone = skeleton.bone_lengths()
    from kinodyn.contacts import find_feet

    try:
        foot_sets = find_feet(skeleton)
    except UnknownNameError:  # feet are optional: a skeleton without named feet still builds
        foot_sets = {}
    toe_joints = set()  # every foot joint below the shallowest one of its side (toes, toe ends)
    for idx in foot_sets.values():
        idx = sorted(int(i) for i in idx)
        toe_joints.update(i for i in idx[1:] if is_descendant(skeleton, i, idx[0]))
    for j in range(1, j_n):
        name = skeleton.names[j]
        p = skeleton.parents[j]
        if lims[j].kind == "fixed":
            kept[j], reason[j] = False, "fixed joint"
        elif roles.has_role(name, "finger") and lims[j].name == "finger":
            kept[j], reason[j] = False, "finger"
        elif cfg.merge_toes and j in toe_joints:
            kept[j], reason[j] = False, "toe (the foot box covers it)"
        elif roles.has_role(name, "end_site") and nkids[j] == 0:
            kept[j], reason[j] = False, "end joint"
        elif bone[j] < cfg.min_bone:
            kids = np.nonzero(skeleton.parents == j)[0]
            if len(kids) == 1 and lims[kids[0]].name == lims[j].name:
                # CMU's Neck/Neck1, LowerBack/Spine: two joints of one kind, the first at its parent
                kept[j], reason[j] = False, "zero-length duplicate of the joint below it"
            elif len(kids) == 0 and nends[j] == 0:
                kept[j], reason[j] = False, "end joint"
            elif nkids[p] < 2 and p != 0:
                raise SkeletonError(ERR_ZERO_BONE.format(name=name, mm=bone[j] * 1000,
                                                         parent=skeleton.names[p]))
            # else: a segment that starts where the skeleton branches (CMU's clavicles): kept
    # Merge the whole subtree below a merged finger/toe/end joint.
    for j in range(1, j_n):
        p = skeleton.parents[j]
        if not kept[p] and reason[p] in ("finger", "toe (the foot box covers it)", "end joint") and kept[j]:
            kept[j], reason[j] = False, reason[p]
    return kept, reason


def points_of_cluster(skeleton: Skeleton, owner: np.ndarray, pos: np.ndarray, b_joint: int):
    """Rest positions (relative to the segment's joint) of what the segment carries: merged joints,
    their end sites and the kept children's joints."""
    pts, kinds = [], []
    for j in range(skeleton.num_joints):
        if j == b_joint:
            continue
        if owner[j] == b_joint:
            pts.append(pos[j] - pos[b_joint])
            kinds.append(("merged", j))
        elif skeleton.parents[j] >= 0 and owner[skeleton.parents[j]] == b_joint and owner[j] == j:
            pts.append(pos[j] - pos[b_joint])
            kinds.append(("child", j))
    for e, p in enumerate(skeleton.end_parents):
        if owner[p] == b_joint:
            pts.append(pos[p] + skeleton.end_offsets[e] - pos[b_joint])
            kinds.append(("end", int(p)))
    return np.array(pts).reshape(-1, 3), kinds


def segment_classes(skeleton: Skeleton, lims, body_joint: np.ndarray, joint_body: np.ndarray,
                    pos: np.ndarray) -> list[str]:
    """``B`` segment classes (keys of :data:`kinodyn.physics.body.SEGMENT_RADII`) of the kept joints
    ``body_joint (B,)``: the root is the pelvis, the others are named by their joint limits ``lims`` and
    then by their place in the tree (:func:`structural_classes`)."""
    cls = []
    for j in body_joint:
        if j == 0:
            cls.append("pelvis")
            continue
        cls.append(LIMIT_CLASS.get(lims[j].name, "other"))
    return structural_classes(skeleton, body_joint, joint_body, cls, pos)


def structural_classes(skeleton, body_joint, joint_body, cls, pos):
    """Fix classes from the tree: the spine path from the root to the head, the chest where the arms
    attach, limb chains named from their ends when the names say nothing."""
    nb = len(body_joint)
    parent = np.array([-1] + [int(joint_body[skeleton.parents[j]]) for j in body_joint[1:]])
    children = [[c for c in range(nb) if parent[c] == b] for b in range(nb)]
    # head: a body named head, else the highest leaf.
    heads = [b for b in range(nb) if cls[b] == "head"]
    if heads:
        head = heads[0]
    else:
        leaves = [b for b in range(nb) if not children[b]]
        head = max(leaves, key=lambda b: pos[body_joint[b], 2]) if leaves else 0
        if head != 0:
            cls[head] = "head"
    path = []
    b = head
    while b >= 0:
        path.append(b)
        b = parent[b]
    path = path[::-1]
    on_path = set(path)
    # where do the arm chains attach? the path body (below the head) with the most side subtrees
    # that are not legs (legs hang off the root).
    attach = [b for b in path[1:-1] if any(c not in on_path for c in children[b])]
    chest = attach[-1] if attach else (path[-3] if len(path) >= 3 else path[0])
    for b in path[1:-1]:
        if b == chest:
            cls[b] = "chest"
        elif path.index(b) < path.index(chest):
            cls[b] = "spine"
        else:
            cls[b] = "neck" if cls[b] not in ("neck",) else cls[b]
    # limb chains: arms off the path (not the root), legs off the root.
    limb_names = {"arm": ["hand", "forearm", "upperarm", "clavicle"], "leg": ["foot", "shin", "thigh", "thigh"]}
    for start_parent in path:
        for c in children[start_parent]:
            if c in on_path:
                continue
            chain = [c]
            while children[chain[-1]]:
                chain.append(max(children[chain[-1]], key=lambda x: _subtree_size(children, x)))
            kind = "leg" if start_parent == path[0] else "arm"
            names = limb_names[kind]
            for k, b2 in enumerate(reversed(chain)):
                if cls[b2] == "other" or (kind == "leg" and cls[b2] in ("spine", "chest")):
                    cls[b2] = names[min(k, len(names) - 1)]
    return cls


def _subtree_size(children, b):
    return 1 + sum(_subtree_size(children, c) for c in children[b])


def is_descendant(skeleton, k, j):
    """Whether joint ``k`` is ``j`` or below it."""
    while k >= 0:
        if k == j:
            return True
        k = skeleton.parents[k]
    return False


def joint_depth(skeleton, k):
    """Number of joints above joint ``k``."""
    d = 0
    while k > 0:
        k = skeleton.parents[k]
        d += 1
    return d
