"""What a picture of a contact run needs: object shapes along their trajectories, penetrating segments
of a motion, contact normals.

Schmidl and Lin, figures 1, 5 and 7: the scene's objects with the avatar, the segments that overlap
an obstacle, the contact normals along which overlap is removed. These are plain arrays (no drawing
library): :mod:`kinodyn.contact.command` turns them into viewer objects.

Shapes: ``F`` frames, ``J`` joints, ``V`` vertices, ``T`` triangles; metres, ``(w, x, y, z)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinodyn.contact import motions
from kinodyn.contact.avatar import build_avatar, segment_poses
from kinodyn.contact.collide import CollisionWorld
from kinodyn.contact.plots import piece_mesh
from kinodyn.contact.setting import Piece
from kinodyn.math import quat

__all__ = ["ShapeTrack", "contact_normals", "penetrating_joints", "shape_tracks"]

_PRIMITIVE = ("box", "sphere", "capsule")


@dataclass(frozen=True)
class ShapeTrack:
    """One drawable shape of a scene object along the run.

    Attributes:
        name: the object's name (``hand/3`` for a piece of an articulated object); kind: its kind.
        shape: ``"box"``, ``"sphere"``, ``"capsule"`` (``size`` as in :data:`kinodyn.contact.setting.SHAPES`)
            or ``"mesh"`` (``vertices (V, 3)`` and ``faces (T, 3)`` in the shape's frame).
        positions: ``(F, 3)`` or ``(1, 3)`` for an object that never moves; quats: the same, ``(., 4)``.
    """

    name: str
    kind: str
    shape: str
    size: tuple[float, ...]
    positions: np.ndarray
    quats: np.ndarray
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None


def _compose(pos, q, piece: Piece) -> tuple[np.ndarray, np.ndarray]:
    """World ``(F, 3)``, ``(F, 4)`` of a piece on an object at ``pos (F, 3)``, ``q (F, 4)``."""
    return pos + quat.mul_vec(q, np.broadcast_to(piece.pos, pos.shape)), quat.mul(q, np.broadcast_to(piece.quat, q.shape))


def _still(pos, q) -> tuple[np.ndarray, np.ndarray]:
    if np.ptp(pos, axis=0).max(initial=0) < 1e-9 and np.ptp(q, axis=0).max(initial=0) < 1e-9:
        return pos[:1], q[:1]
    return pos, q


def _piece_track(name, kind, piece: Piece, pos, q) -> ShapeTrack:
    p, r = _still(*_compose(pos, q, piece))
    if piece.shape in _PRIMITIVE:
        return ShapeTrack(name, kind, piece.shape, piece.size, p, r)
    v, f = piece_mesh(Piece(piece.shape, piece.size, vertices=piece.vertices))
    return ShapeTrack(name, kind, "mesh", (), p, r, v, f)


def shape_tracks(scene, result) -> list[ShapeTrack]:
    """Shapes of every object of a run but the avatar's segments (the avatar is drawn from its motion).

    An object of one box, sphere or capsule piece is that primitive; an object of several pieces is one
    mesh of them all; the articulated hand is one shape per piece (its fingers flex), posed per frame by
    its tracked path.

    Args:
        scene: the :class:`~kinodyn.contact.scenefile.Scene` run; result: its
            :class:`~kinodyn.contact.simulate.RunResult` (``pos (F, N, 3)``, ``quat (F, N, 4)``).
    """
    out = []
    objects = list(scene.objects)
    if scene.hand is not None:
        objects.append(motions.hand_object(scene.hand.mass))
    for k, obj in enumerate(objects):  # the avatar's segments follow these in the run's objects
        pos, q = result.pos[:, k], result.quat[:, k]
        if scene.hand is not None and k == len(scene.objects):
            out += _hand_tracks(scene, result, obj, pos, q)
        elif len(obj.pieces) == 1 and obj.pieces[0].shape in _PRIMITIVE:
            out.append(_piece_track(obj.name, obj.kind, obj.pieces[0], pos, q))
        else:
            meshes = [piece_mesh(p) for p in obj.pieces]
            first = np.cumsum([0] + [len(v) for v, _ in meshes])[:-1]
            v = np.concatenate([v for v, _ in meshes])
            f = np.concatenate([f + o for (_, f), o in zip(meshes, first)])
            p, r = _still(pos, q)
            out.append(ShapeTrack(obj.name, obj.kind, "mesh", (), p, r, v, f))
    return out


def _hand_tracks(scene, result, obj, pos, q) -> list[ShapeTrack]:
    _, flex, index, _ = motions.hand_path(scene.hand.path, result.fps)
    frames = np.minimum(np.arange(len(pos)), len(flex) - 1)
    lp, lq, rad = zip(*(motions.hand_pose(flex[f], index[f]) for f in frames))
    lp, lq, rad = np.array(lp), np.array(lq), np.array(rad)  # (F, 15, 3), (F, 15, 4), (F, 15, 3)
    out = []
    for i in range(lp.shape[1]):
        wp = pos + quat.mul_vec(q, lp[:, i])
        wq = quat.mul(q, lq[:, i])
        v, f = piece_mesh(Piece("ellipsoid", tuple(rad[0, i])))
        out.append(ShapeTrack(f"{obj.name}/{i}", obj.kind, "mesh", (), wp, wq, v, f))
    return out


def _avatar_world(scene, skeleton):
    avatar = build_avatar(skeleton)
    fixed = [o for o in scene.objects if o.kind == "fixed"]
    first = len(fixed)
    world = CollisionWorld(fixed + list(avatar.segments), [(first + a, first + b) for a, b in avatar.exclude])
    return avatar, world, first


def penetrating_joints(motion, scene, tolerance: float = 1e-3, self_collision: bool | None = None) -> np.ndarray:
    """``(F, J)`` bool: the segment carried by joint ``j`` overlaps a fixed object of ``scene`` (or,
    with ``self_collision``, another segment it may touch: arm through arm or torso) by more than
    ``tolerance`` (m) in frame ``f`` of ``motion`` (the motion as given, unresolved).
    ``self_collision=None`` takes the scene avatar's setting (on without an avatar entry)."""
    if self_collision is None:
        self_collision = scene.avatar.self_collision if scene.avatar is not None else True
    avatar, world, first = _avatar_world(scene, motion.skeleton)
    objs = np.arange(len(avatar.segments)) + first
    out = np.zeros((motion.num_frames, motion.skeleton.num_joints), dtype=bool)
    for f in range(motion.num_frames):
        world.set_poses(objs, *segment_poses(avatar, motion.root_pos[f], motion.local_rot[f]))
        c = world.contacts(objs)
        deep = c.depth > tolerance
        fixed = (c.object_a < first) | (c.object_b < first)
        seg = np.where(c.object_a >= first, c.object_a, c.object_b) - first
        out[f, avatar.segment_joint[seg[deep & fixed]]] = True
        if self_collision:
            own = deep & ~fixed
            out[f, avatar.segment_joint[c.object_a[own] - first]] = True
            out[f, avatar.segment_joint[c.object_b[own] - first]] = True
    return out


def contact_normals(motion, scene, margin: float = 0.01) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Contacts of ``motion``'s segments with ``scene``'s fixed objects, closer than ``margin`` (m).

    Returns:
        frame indices ``(C,)``, world contact points ``(C, 3)`` and unit normals ``(C, 3)`` pointing
        out of the fixed object towards the avatar (the direction overlap removal pushes it).
    """
    avatar, world, first = _avatar_world(scene, motion.skeleton)
    objs = np.arange(len(avatar.segments)) + first
    mine = np.zeros(world.num_objects, bool)
    mine[objs] = True
    frames, points, normals = [], [], []
    for f in range(motion.num_frames):
        world.set_poses(objs, *segment_poses(avatar, motion.root_pos[f], motion.local_rot[f]))
        c = world.contacts(objs, first=mine, margin=margin)
        keep = mine[c.object_a] & ~mine[c.object_b]
        frames.append(np.full(int(keep.sum()), f))
        points.append(c.point[keep])
        normals.append(c.normal[keep])
    return (np.concatenate(frames).astype(np.int64), np.concatenate(points).reshape(-1, 3),
            np.concatenate(normals).reshape(-1, 3))
