"""Cleaning motion data: resolve every frame of a clip against a scene (floor, props, the body itself).

The avatar loop of :mod:`kinodyn.contact.resolve` run on recorded motion instead of a live tracker:
segments that pass through the scene's fixed objects or through the body's other limbs are moved out
by CCD IK within the joint limits and reach cones, the torso by translation, with Algorithm 1's
interpolation where IK cannot. Frames without overlap are returned as they are, bit for bit
(:attr:`~kinodyn.contact.resolve.ResolveConfig.keep_free`): the clip may leave the joint limits there,
and nothing is projected or pulled from the frame before.

Shapes: ``F`` frames, ``J`` joints; metres, degrees in the report.
"""

from __future__ import annotations

import numpy as np

from kinodyn.contact.avatar import build_avatar, segment_poses
from kinodyn.contact.collide import CollisionWorld
from kinodyn.contact.resolve import AvatarDriver, ResolveConfig
from kinodyn.contact.scenefile import Scene
from kinodyn.math import quat
from kinodyn.motion import Motion

__all__ = ["fix_motion", "penetration_before"]


def _world(motion: Motion, scene: Scene):
    avatar = build_avatar(motion.skeleton)
    fixed = [o for o in scene.objects if o.kind == "fixed"]
    first = len(fixed)
    world = CollisionWorld(fixed + list(avatar.segments), [(first + a, first + b) for a, b in avatar.exclude])
    return avatar, world, first


def penetration_before(motion: Motion, scene: Scene, self_collision: bool = False) -> np.ndarray:
    """``(F,)`` deepest overlap (m) of the clip's segments with the scene's fixed objects, as recorded;
    with ``self_collision``, overlaps between the body's own segments count too (those the avatar
    resolves: not parent and child, not the same limb, not touching at rest)."""
    avatar, world, first = _world(motion, scene)
    objs = np.arange(len(avatar.segments)) + first
    out = np.zeros(motion.num_frames)
    for f in range(motion.num_frames):
        world.set_poses(objs, *segment_poses(avatar, motion.root_pos[f], motion.local_rot[f]))
        c = world.contacts(objs)
        keep = (c.object_a < first) | (c.object_b < first) | self_collision
        out[f] = c.depth[keep].max() if keep.any() else 0.0
    return out


def fix_motion(motion: Motion, scene: Scene, config: ResolveConfig | None = None) -> tuple[Motion, dict]:
    """The clip resolved frame by frame against ``scene``'s fixed objects and itself.

    Returns:
        the fixed motion and a per-frame report: ``changed_deg`` (largest joint rotation change),
        ``root_moved_mm``, ``before_mm`` (deepest overlap with the scene as recorded),
        ``penetration_mm`` (after), ``iterations`` (CCD iterations), ``fallback`` (1 where Algorithm 1's
        interpolation was used), each ``(F,)``.
    """
    avatar, world, first = _world(motion, scene)
    driver = AvatarDriver(avatar, world, first, motion.fps, config or ResolveConfig(keep_free=True))
    roots, rots = np.array(motion.root_pos), np.array(motion.local_rot)
    rep = {k: np.zeros(motion.num_frames) for k in ("changed_deg", "root_moved_mm", "before_mm", "penetration_mm",
                                                     "iterations", "fallback")}
    rep["before_mm"] = penetration_before(motion, scene) * 1e3
    for f in range(motion.num_frames):
        r, q, st = driver.step(motion.root_pos[f], motion.local_rot[f])
        roots[f], rots[f] = r, q
        rep["changed_deg"][f] = np.rad2deg(quat.angle_between(q, motion.local_rot[f]).max())
        rep["root_moved_mm"][f] = np.linalg.norm(r - motion.root_pos[f]) * 1e3
        rep["penetration_mm"][f] = st.penetration * 1e3
        rep["iterations"][f] = st.iterations
        rep["fallback"][f] = float(st.fallback)
    return motion.replace(root_pos=roots, local_rot=quat.unroll(rots), name=f"{motion.name}_fixed"), rep
