"""Geometry of a character body: capsules along the bones, boxes for the feet, rest-contact exclusions.

The collision half of :func:`kinodyn.physics.body.build_body` (the rules are in that module's
docstring): :func:`add_geoms` gives a segment capsules sized from its bone lengths, the pelvis and chest
a lateral capsule between the hips or the shoulders, feet and toes a box from the heel to the tip with
the sole below the toe joints; :func:`exclude_rest_contacts` keeps segments that touch in the rest pose
from colliding.

Shapes: ``pts (k, 3)`` points a segment carries, in its body frame; metres.
"""

from __future__ import annotations

import mujoco
import numpy as np

from kinodyn import limits as _limits
from kinodyn.physics.layout import LIMIT_CLASS, is_descendant, joint_depth, joint_side
from kinodyn.skeleton import Skeleton

__all__ = ["HEEL_FRACTION", "add_geoms", "exclude_rest_contacts"]

#: Heel length behind the ankle as a fraction of the ankle-to-toe-tip length, when no heel site exists.
HEEL_FRACTION = 0.27


def add_geoms(body, seg, pts, kinds, skeleton: Skeleton, pos, sole: float, spine_cls: dict) -> None:
    """Capsules (or a box for a foot or toe) for one segment, in the body frame (rest orientation).

    ``pts``/``kinds``: what the segment carries (:func:`points_of_cluster`); ``spine_cls``: segment class of
    each kept joint, to find the child on the spine.
    """
    name, c, radius, j = seg.name, seg.cls, seg.radius, seg.joint
    capsule = mujoco.mjtGeom.mjGEOM_CAPSULE
    rgba = {"left": [0.55, 0.62, 0.75, 1.0], "right": [0.75, 0.58, 0.55, 1.0]}.get(seg.side, [0.6, 0.65, 0.6, 1.0])
    geoms = []
    if c == "foot":
        _foot_box(body, name, pts, radius, sole, rgba)
        return
    if c == "toe":
        _foot_box(body, name, pts, radius, sole, rgba, heel_fraction=0.0, top=0.6 * sole)
        return
    children = [(p, k) for p, k in zip(pts, kinds) if k[0] == "child"]
    far = [p for p, k in zip(pts, kinds) if k[0] in ("merged", "end")]
    if c in ("pelvis", "chest"):
        # lateral capsule between the left/right limb roots below this segment
        lat = _lateral_pair(skeleton, pos, seg)
        if lat is not None:
            a, e = lat
            geoms.append(("lat", a, e))
        # and a capsule up the spine, to the child on the path to the head
        ups = [p for p, k in children if spine_cls.get(k[1]) in ("spine", "chest", "neck", "head")]
        for p in ups:
            geoms.append(("cap", np.zeros(3), p))
        if not geoms:
            for p, _k in children:
                geoms.append(("cap", np.zeros(3), p))
    else:
        targets = [p for p, _ in children]
        if far and (not targets or c in ("hand", "head")):  # to the farthest fingertip or head top
            targets = [max(far, key=lambda v: np.linalg.norm(v))]
        if not targets:
            # a leaf with nothing below it: continue the bone that leads to it
            d = skeleton.offsets[j]
            n = np.linalg.norm(d)
            d = d / n if n > 1e-9 else np.array([0.0, 0.0, 1.0])
            targets = [d * 2.0 * radius]
        # branching segments other than pelvis/chest: one capsule to each child
        for p in targets:
            geoms.append(("cap", np.zeros(3), p))
    for k, (kind, a, e) in enumerate(geoms):
        gname = name if k == 0 else f"{name}_{k}"
        if np.linalg.norm(e - a) < 1e-6:
            body.add_geom(name=gname, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], pos=a, rgba=rgba)
        else:
            body.add_geom(name=gname, type=capsule, fromto=np.concatenate([a, e]), size=[radius, 0, 0], rgba=rgba)


def _lateral_pair(skeleton: Skeleton, pos, seg):
    """End points of the lateral capsule of the pelvis (between the hips) or chest (between the shoulders)."""
    j, c = seg.joint, seg.cls
    want = ("thigh",) if c == "pelvis" else ("upperarm",)
    # the shallowest left and right joints below j whose limit type makes them limb roots
    cand = {"left": [], "right": []}
    for k in range(skeleton.num_joints):
        if k == j or not is_descendant(skeleton, k, j):
            continue
        tname = _limits.joint_kind(skeleton, k)[0]
        cl = LIMIT_CLASS.get(tname, "other")
        if cl in want:
            side = joint_side(skeleton, k, pos)
            if side:
                cand[side].append(k)
    if not cand["left"] or not cand["right"]:
        return None
    lk = min(cand["left"], key=lambda k: joint_depth(skeleton, k))
    rk = min(cand["right"], key=lambda k: joint_depth(skeleton, k))
    a, e = pos[lk] - pos[j], pos[rk] - pos[j]
    r = seg.radius
    mid = 0.5 * (a + e)
    half = 0.5 * (a - e)
    n = np.linalg.norm(half)
    if n < 1e-9:
        return None
    # pull the ends inward by half a radius so the limb roots stay free; lower the chest capsule a bit
    shrink = max(n - 0.5 * r, 0.25 * n) / n
    drop = np.array([0.0, 0.0, -0.4 * r]) if c == "chest" else np.zeros(3)
    return mid + half * shrink + drop, mid - half * shrink + drop


def _foot_box(body, name, pts, radius, sole, rgba, heel_fraction=HEEL_FRACTION, top=None):
    """A box from the heel to the farthest point (the ball or the toe tip), its sole ``sole`` below the
    lowest point; toes use the same shape without a heel."""
    if len(pts):
        horiz = pts.copy()
        horiz[:, 2] = 0.0
        far = horiz[np.argmax(np.linalg.norm(horiz, axis=1))]
        n = np.linalg.norm(far)
    else:
        n = 0.0
    if n < 1e-6:
        fwd = np.array([1.0, 0.0, 0.0])
        toe_len = 6.0 * radius
        low = -2.0 * radius
    else:
        fwd = far / n
        toe_len = float(np.max(pts @ fwd))
        low = float(min(pts[:, 2].min(), 0.0)) - sole
    heel = heel_fraction * toe_len
    lo = min(low, -radius) if top is None else low
    top = 0.25 * radius if top is None else top
    half = np.array([(toe_len + heel) / 2.0, radius, (top - lo) / 2.0])
    center = fwd * (toe_len - heel) / 2.0 + np.array([0.0, 0.0, (top + lo) / 2.0])
    yaw = np.arctan2(fwd[1], fwd[0])
    q = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=half, pos=center, quat=q, rgba=rgba)


def exclude_rest_contacts(spec: mujoco.MjSpec, seg, cfg) -> None:
    """Exclude segment pairs that touch in the rest pose (and all pairs without self-collision)."""
    if not cfg.self_collision:
        names = [s.name for s in seg]
        for a in range(len(names)):
            for b in range(a + 1, len(names)):
                if seg[b].parent != a and seg[a].parent != b:
                    spec.add_exclude(bodyname1=names[a], bodyname2=names[b])
        return
    model = spec.compile()
    data = mujoco.MjData(model)
    # measure overlap with a margin so near-touching pairs are excluded too
    model.geom_margin[:] = 0.01
    mujoco.mj_forward(model, data)
    pairs = set()
    for i in range(data.ncon):
        g1, g2 = data.contact.geom1[i], data.contact.geom2[i]
        b1, b2 = model.geom_bodyid[g1], model.geom_bodyid[g2]
        if b1 == 0 or b2 == 0 or b1 == b2:
            continue
        pairs.add((min(b1, b2), max(b1, b2)))
    for b1, b2 in sorted(pairs):
        spec.add_exclude(bodyname1=model.body(b1).name, bodyname2=model.body(b2).name)
