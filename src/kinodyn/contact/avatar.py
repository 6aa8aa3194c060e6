"""The driven avatar: convex segments sized like the physics body, IK chains, reach cones.

Schmidl and Lin, "Geometric and kinematic overlap avoidance": the avatar is an articulated driven
object; its five chains (two arms, two legs, the neck) are solved by CCD (:mod:`kinodyn.ik.ccd`).
Its segments are the capsules and boxes of :func:`kinodyn.physics.body.build_body` (radii a fraction
of the standing height, boxes for the feet), so contact and physics see the same body. Each segment
is one driven :class:`~kinodyn.contact.setting.SceneObject` whose frame is its joint's frame.

Joint limits come from :mod:`kinodyn.limits` (the one specification): hinges keep its axis and range;
ball joints get a reach cone (Wilhelms and Van Gelder 2001) for the direction of their bone
(:func:`kinodyn.ik.cones.reach_cones`: anatomical, so the same for an arms-down and a T-pose rest
pose), a spherical polygon whose every point lies within the joint's ``max_angle`` of the rest
direction, so a pose inside the cone, with its twist limited as in :mod:`kinodyn.ik.cones`, is inside
the limits too.

Shapes: ``J`` joints, ``S`` segments (one per joint for the built-in humanoid), ``K`` cone vertices.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from kinodyn import limits as jl
from kinodyn.contact.setting import Piece, SceneObject
from kinodyn.ik.cones import reach_cones
from kinodyn.kinematics import fk_link
from kinodyn.math import quat
from kinodyn.skeleton import Skeleton

__all__ = ["Avatar", "build_avatar", "pose_fk", "segment_poses"]


@dataclass(frozen=True, eq=False)
class Avatar:
    """An articulated driven object.

    Attributes:
        skeleton: its skeleton.
        name: prefix of its segment objects.
        segments: ``S`` driven objects, one per body segment.
        segment_joint: ``(S,)`` skeleton joint whose frame carries each segment.
        joint_segment: ``(J,)`` segment of each joint (-1 when none).
        chains: IK chains (arms, legs, neck), each the ``(n,)`` joints from the chain root to its tip.
        torso: ``(T,)`` segments not in any chain (pelvis, spine, chest).
        exclude: segment pairs ``(i, j)`` that never collide (parent and child, touching at rest, same
            limb).
        limits: the joint limits (:func:`kinodyn.limits.limits_for`).
        cone_axes: ``(J, 4, 3)`` per joint: rest bone direction, cone centre, chart x (forward) and chart
            y (out) (:func:`kinodyn.ik.cones.reach_cones`).
        cone_points: ``(J, K, 2)`` reach-cone polygon in the azimuthal chart (radians).
    """

    skeleton: Skeleton
    name: str
    segments: tuple[SceneObject, ...]
    segment_joint: np.ndarray
    joint_segment: np.ndarray
    chains: tuple[np.ndarray, ...]
    torso: np.ndarray
    exclude: tuple[tuple[int, int], ...]
    limits: tuple[jl.JointLimit, ...]
    cone_axes: np.ndarray
    cone_points: np.ndarray


def _pieces(model, body: int) -> tuple[Piece, ...]:
    import mujoco

    out = []
    for g in np.nonzero(model.geom_bodyid == body)[0]:
        t, size = model.geom_type[g], model.geom_size[g]
        pos, q = model.geom_pos[g].copy(), model.geom_quat[g].copy()
        if t == mujoco.mjtGeom.mjGEOM_CAPSULE:
            out.append(Piece("capsule", (size[0], size[1]), pos, q))
        elif t == mujoco.mjtGeom.mjGEOM_BOX:
            out.append(Piece("box", tuple(size), pos, q))
        elif t == mujoco.mjtGeom.mjGEOM_SPHERE:
            out.append(Piece("sphere", (size[0],), pos, q))
    return tuple(out)


def _chains(skeleton: Skeleton, lims) -> tuple[list[np.ndarray], list[int]]:
    torso_types = ("root", "spine", "hip_joint")
    torso = [j for j in range(skeleton.num_joints) if lims[j].name in torso_types]
    chains = []
    for j in range(1, skeleton.num_joints):
        if j in torso or skeleton.parents[j] not in torso:
            continue
        chain = [j]
        while len(kids := skeleton.children(chain[-1])):
            chain.append(int(kids[0]))
        chains.append(np.array(chain, dtype=np.int64))
    return chains, torso


def build_avatar(skeleton: Skeleton, material: str = "human", name: str = "avatar", mass: float = 70.0) -> Avatar:
    """The avatar of ``skeleton``: segments from the physics body, chains, limits and reach cones."""
    from kinodyn.physics.body import BodyConfig, build_body

    body = build_body(skeleton, BodyConfig(mass=mass))
    model = body.model()
    segs, seg_joint = [], []
    for b, seg in enumerate(body.map.segments):
        pieces = _pieces(model, b + 1)
        if pieces:
            m = float(model.body_mass[b + 1])
            segs.append(SceneObject(f"{name}/{seg.name}", "driven", material, pieces, mass=max(m, 1e-3)))
            seg_joint.append(seg.joint)
    seg_joint = np.array(seg_joint, dtype=np.int64)
    joint_segment = np.full(skeleton.num_joints, -1, dtype=np.int64)
    joint_segment[seg_joint] = np.arange(len(seg_joint))
    lims = jl.limits_for(skeleton)
    chains, _ = _chains(skeleton, lims)
    axes, pts = reach_cones(skeleton, lims)
    limb = np.full(len(seg_joint), -1)
    for c, chain in enumerate(chains):
        s = joint_segment[chain]
        limb[s[s >= 0]] = c
    torso = np.nonzero(limb < 0)[0]
    exclude = _exclusions(segs, seg_joint, skeleton, limb)
    return Avatar(skeleton, name, tuple(segs), seg_joint, joint_segment, tuple(chains), torso, exclude, lims,
                  axes, pts)


def _exclusions(segs, seg_joint, skeleton, limb) -> tuple[tuple[int, int], ...]:
    """Segment pairs that never collide: same limb, both torso, parent and child, or touching at rest."""
    from kinodyn.contact.collide import CollisionWorld

    n = len(segs)
    gr, gp = segment_rest(skeleton, seg_joint)
    placed = [s.__class__(s.name, "driven", s.material, s.pieces, p, q, s.mass) for s, p, q in zip(segs, gp, gr)]
    world = CollisionWorld(placed)
    touching = set()
    for ia, ib in world.candidate_pairs().tolist():
        a, b = int(world.geom_object[ia]), int(world.geom_object[ib])
        if world.distance(ia, ib, 0.02)[0] < 0.01:
            touching.add((min(a, b), max(a, b)))
    out = []
    par = skeleton.parents
    for a in range(n):
        for b in range(a + 1, n):
            ja, jb = seg_joint[a], seg_joint[b]
            same = limb[a] == limb[b]
            adjacent = par[ja] == jb or par[jb] == ja
            if same or adjacent or (a, b) in touching:
                out.append((a, b))
    return tuple(out)


def segment_rest(skeleton: Skeleton, seg_joint) -> tuple[np.ndarray, np.ndarray]:
    """Rest-pose global rotations ``(S, 4)`` and positions ``(S, 3)`` of the segments' joints."""
    gr = quat.identity((len(seg_joint),))
    return gr, skeleton.rest_positions()[seg_joint]


@numba.njit(cache=True)
def _pose_fk(root_pos, local_rot, offsets, parents, gr, gp):  # pragma: no cover - compiled
    gr[0] = local_rot[0]
    gp[0] = root_pos
    for j in range(1, local_rot.shape[0]):
        fk_link(gr, gp, parents[j], j, local_rot[j], offsets[j])


def pose_fk(skeleton: Skeleton, root_pos, local_rot) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations ``(J, 4)`` and positions ``(J, 3)`` of one pose (``root_pos (3,)``,
    ``local_rot (J, 4)``), serial and compiled: the per-frame FK of the contact loop."""
    gr = np.empty((skeleton.num_joints, 4))
    gp = np.empty((skeleton.num_joints, 3))
    _pose_fk(np.asarray(root_pos, dtype=np.float64), np.ascontiguousarray(local_rot, dtype=np.float64),
             skeleton.offsets, skeleton.parents, gr, gp)
    return gr, gp


def segment_poses(avatar: Avatar, root_pos, local_rot) -> tuple[np.ndarray, np.ndarray]:
    """Segment positions ``(S, 3)`` and rotations ``(S, 4)`` of one pose: ``root_pos (3,)``,
    ``local_rot (J, 4)``."""
    gr, gp = pose_fk(avatar.skeleton, root_pos, local_rot)
    return gp[avatar.segment_joint], gr[avatar.segment_joint]
