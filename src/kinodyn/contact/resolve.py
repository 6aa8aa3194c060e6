"""Overlap avoidance for the articulated avatar: torso translation, CCD per chain, Algorithm 1 fallback.

Schmidl and Lin, "Geometric and kinematic overlap avoidance" and figure 6. Each frame, starting from
the tracked pose (pulled toward it from the last solved pose where IK was needed: the coach-trainee
attraction of Boulic and Thalmann):

1. the torso (segments outside every chain) gives way to fixed objects by translation of the root
   by its global penetration depth (equation 1);
2. chains (arms, legs, neck) in random order: find the penetrating link ``i`` nearest the chain's
   root, its end effector at the mean of its contacts (equation 2), the goal pushed out of the
   obstacle by the link's global depth (equation 3), and CCD (:func:`kinodyn.ik.ccd.ccd_solve`)
   from link ``i`` inwards; a link lying along the surface is moved out by translation and the parent
   chain reconnected; repeat until no link penetrates. Obstacles are fixed objects and the avatar's
   own other chains and torso (self-collision);
3. what is still overlapping (normals that cancel, goals out of reach) is moved back toward the last
   non-overlapping pose (Algorithm 1, step 4).

:class:`AvatarDriver` is mutable (the last solved and last free poses) and moves the avatar's
segments in the collision world. Shapes: ``J`` joints; metres, radians, ``(w, x, y, z)``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from kinodyn.contact.avatar import Avatar, pose_fk, segment_poses
from kinodyn.contact.collide import CollisionWorld
from kinodyn.contact.depth import global_depth, interpolate_back
from kinodyn.ik.ccd import CCDConfig, ccd_solve, chain_fk, chain_limits, project_chain
from kinodyn.math import quat
from kinodyn.math.array_kernels import qmul, qrot

__all__ = ["AvatarDriver", "FrameStats", "ResolveConfig"]


@dataclass(frozen=True)
class ResolveConfig:
    """Avatar overlap-avoidance settings.

    Attributes:
        ccd: CCD solver settings.
        max_iterations: goal readjustments per chain and round.
        max_rounds: rounds over all chains.
        parallel_angle: a link within this angle of the surface is translated out (rad).
        skin: goals are pushed this far beyond the surface (m): 2 mm saves CCD iterations where
            chains press on each other (self-collision: 7 instead of 11 per frame).
        tolerance: overlap that counts as none (m).
        attraction_halflife: halflife of the pull from the last solved pose to the tracked one (s).
        release_angle: a chain pulled back toward the tracked angles is released (takes them as they
            are) once no joint of it is further from them than this (rad).
        self_collision: chains also avoid the avatar's other chains and torso.
        sweep_step: once the torso has been held off the tracked root, the way from where it was held
            to the tracked root is checked in steps this long (m; less than the thinnest wall).
        keep_free: a tracked pose that overlaps nothing is taken as it is, even right after a frame
            that IK changed (no attraction from the last solved pose): what cleaning recorded motion
            wants, so that frames without overlap stay bit-identical. Live tracking leaves it off, so
            that limbs leaving an obstacle are pulled back to the tracked angles instead of popping.
        seed: seed of the random chain order.
    """

    ccd: CCDConfig = field(default_factory=CCDConfig)
    max_iterations: int = 8
    max_rounds: int = 4
    parallel_angle: float = np.deg2rad(30.0)
    skin: float = 2e-3
    tolerance: float = 2e-4
    attraction_halflife: float = 0.03
    release_angle: float = 1e-4
    self_collision: bool = True
    sweep_step: float = 0.05
    keep_free: bool = False
    seed: int = 0


@dataclass
class FrameStats:
    """Per-frame figures of :meth:`AvatarDriver.step` (Table 2's columns).

    Attributes: iterations (CCD solves with a readjusted goal), joints (joints turned by IK), pairs
    (overlapping object pairs found), ik_s and query_s (time in IK and in collision queries),
    penetration (deepest overlap left, m), fallback (Algorithm 1's interpolation was used), solved
    (chains turned by IK or held from the last frame: those are inside their limits and reach cones;
    chains IK never touched keep the tracked angles).
    """

    iterations: int = 0
    joints: int = 0
    pairs: int = 0
    ik_s: float = 0.0
    query_s: float = 0.0
    penetration: float = 0.0
    fallback: bool = False
    solved: tuple = ()


class AvatarDriver:
    """Drives an avatar's segments (objects ``first .. first + S - 1`` of ``world``) without overlap."""

    def __init__(self, avatar: Avatar, world: CollisionWorld, first: int, fps: float,
                 config: ResolveConfig | None = None):
        self.avatar, self.world, self.first = avatar, world, int(first)
        self.cfg = config or ResolveConfig()
        self.fps = float(fps)
        self.rng = np.random.default_rng(self.cfg.seed)
        n = world.num_objects
        self.objs = np.arange(len(avatar.segments)) + self.first
        self.mine = np.zeros(n, bool)
        self.mine[self.objs] = True
        kinds = np.array([o.kind for o in world.objects])
        self.obstacle = kinds == "fixed"
        self.limits = [chain_limits(avatar.limits, avatar.cone_axes, avatar.cone_points, c) for c in avatar.chains]
        self.solved = None  # (root_pos, local_rot) of the last frame
        self.free = None  # last pose without overlap
        self.held_back = False  # the last frame's root was moved off the tracked one
        self.active = np.zeros(len(avatar.chains), bool)
        self.stats = FrameStats()

    # ------------------------------------------------------------------ helpers
    def _place(self, root_pos, local_rot) -> None:
        pos, rot = segment_poses(self.avatar, root_pos, local_rot)
        self.world.set_poses(self.objs, pos, rot)

    def _contacts(self, objs):
        t0 = time.perf_counter()
        c = self.world.contacts(objs, first=self._mask(objs))
        self.stats.query_s += time.perf_counter() - t0
        ob = c.object_b
        ok = self._mask(objs)[c.object_a] & (c.depth > self.cfg.tolerance)
        ok &= self.obstacle[ob] | (self.mine[ob] & self.cfg.self_collision)
        rows = np.nonzero(ok)[0]
        return c, rows

    def _mask(self, objs):
        m = np.zeros(self.world.num_objects, bool)
        m[objs] = True
        return m

    def _deepest(self) -> float:
        c, rows = self._contacts(self.objs)
        return float(c.depth[rows].max()) if len(rows) else 0.0

    # ------------------------------------------------------------------ the frame
    def step(self, root_pos, local_rot) -> tuple[np.ndarray, np.ndarray, FrameStats]:
        """Solve one frame for the tracked pose ``root_pos (3,)``, ``local_rot (J, 4)``; returns the
        avatar's pose ``(root_pos, local_rot)`` and the frame's figures."""
        self.stats = FrameStats()
        root = np.array(root_pos, dtype=np.float64)
        q = np.array(local_rot, dtype=np.float64)
        tracked_q = np.array(q)
        if self.cfg.keep_free and self.active.any() and self._free_as_tracked(root, q):
            return root, q, self.stats
        if self.solved is not None:
            alpha = 1.0 - 0.5 ** (1.0 / (self.fps * self.cfg.attraction_halflife))
            for c, chain in enumerate(self.avatar.chains):
                if self.active[c]:
                    q[chain] = quat.slerp(self.solved[1][chain], q[chain], alpha)
        for c, chain in enumerate(self.avatar.chains):
            if self.active[c]:  # still held by IK: inside its limits and cones from here on
                q[chain] = project_chain(q[chain], self.limits[c])
        tracked_root = root
        if self.held_back:  # from where the torso was held, not straight to the tracked root
            root = self._sweep_torso(self.solved[0], root, q)
        self._place(root, q)
        root = self._torso(root, q)
        self.held_back = bool(np.any(root != tracked_root))
        held = self.active.copy()
        self.active[:] = False
        pen = None
        for _ in range(self.cfg.max_rounds):
            cts, rows = self._contacts(self.objs)  # one query per round; chains re-query only themselves
            if not len(rows):
                pen = 0.0
                break
            for c in self.rng.permutation(len(self.avatar.chains)):
                self._chain(int(c), root, q, (cts, rows))
        if pen is None:
            pen = self._deepest()
        if pen > self.cfg.tolerance and self.free is not None:
            root, q = self._fall_back(root, q)
            for c in np.nonzero(self.active | held)[0]:  # the way back stays inside the limits
                chain = self.avatar.chains[c]
                q[chain] = project_chain(q[chain], self.limits[c])
            self._place(root, q)
            pen = self._deepest()
            self.stats.fallback = True
        self.stats.penetration = pen
        self.stats.solved = tuple(int(c) for c in np.nonzero(self.active | held)[0])
        for c in np.nonzero(held & ~self.active)[0]:  # held, not solved: still pulled back next frame
            chain = self.avatar.chains[c]
            self.active[c] = quat.angle_between(q[chain], tracked_q[chain]).max() > self.cfg.release_angle
        self.solved = (root.copy(), q.copy())
        if pen <= self.cfg.tolerance:
            self.free = (root.copy(), q.copy())
        return root, q, self.stats

    def _free_as_tracked(self, root, q) -> bool:
        """Whether the tracked pose overlaps nothing; if so it becomes the last solved and free pose."""
        self._place(root, q)
        if self._deepest() > self.cfg.tolerance:
            return False
        self.active[:] = False
        self.held_back = False
        self.solved = self.free = (root.copy(), q.copy())
        return True

    def _torso_depth(self, root, q) -> float:
        self._place(root, q)
        c, rows = self._contacts(self.objs[self.avatar.torso])
        rows = rows[self.obstacle[c.object_b[rows]]]
        return float(c.depth[rows].max()) if len(rows) else 0.0

    def _sweep_torso(self, start, root, q) -> np.ndarray:
        """The root moved from ``start`` (last frame's, held off the tracked one) toward ``root`` until
        the torso first touches a fixed object: Algorithm 1's interpolation along the way, marched in
        steps of :attr:`ResolveConfig.sweep_step` so that the torso is never carried through a wall it
        was held against (a tracked root that has gone through would otherwise be taken as free)."""
        way = root - start
        n = max(1, int(np.ceil(np.linalg.norm(way) / self.cfg.sweep_step)))
        tol = self.cfg.tolerance
        t = 1.0
        for k in range(1, n + 1):
            if self._torso_depth(start + (k / n) * way, q) > tol:
                t = interpolate_back(lambda s: self._torso_depth(start + s * way, q), (k - 1) / n, k / n,
                                     iterations=8, tolerance=tol)
                break
        return start + t * way

    def _torso(self, root, q) -> np.ndarray:
        torso = self.objs[self.avatar.torso]
        for _ in range(4):
            c, rows = self._contacts(torso)
            rows = rows[self.obstacle[c.object_b[rows]]]
            if not len(rows):
                break
            self.stats.pairs += len(np.unique(c.object_a[rows] * 100000 + c.object_b[rows]))
            g = global_depth(c.depth[rows], c.normal[rows], c.point[rows])
            if g.cancelling:
                break  # left to the final fallback
            root = root + g.vector * (1.0 + self.cfg.skin / max(g.depth, 1e-12))
            self._place(root, q)
        return root

    def _base(self, root, q, chain):
        sk = self.avatar.skeleton
        gr, gp = pose_fk(sk, root, q)
        p = sk.parents[chain[0]]
        return gr[p], gp[p]

    def _chain(self, c: int, root, q, first=None) -> bool:
        """Resolve chain ``c`` in place (``q`` is changed); True when it moved. ``first``: contacts of the
        whole avatar already found this round (used for the first iteration)."""
        av, cfg = self.avatar, self.cfg
        chain = av.chains[c]
        segs = av.joint_segment[chain]
        objs = self.objs[segs[segs >= 0]]
        pos_of = {int(o): int(k) for k, o in zip(np.nonzero(segs >= 0)[0], objs)}
        obj_of = {k: o for o, k in pos_of.items()}
        offs = av.skeleton.offsets[chain]
        moved = False
        base_r = base_p = None
        for it in range(cfg.max_iterations):
            if it == 0 and first is not None:  # the round's query says whether this chain touches anything
                cts, rows = first
                if not (np.isin(cts.object_a[rows], objs) | np.isin(cts.object_b[rows], objs)).any():
                    break
            cts, rows = self._contacts(objs)  # with the chain's links as ``a``
            if not len(rows):
                break
            if base_r is None:
                base_r, base_p = self._base(root, q, chain)
            link = min(pos_of[int(o)] for o in cts.object_a[rows])
            rows = rows[cts.object_a[rows] == obj_of[link]]
            self.stats.pairs += len(np.unique(cts.object_b[rows]))
            g = global_depth(cts.depth[rows], cts.normal[rows], cts.point[rows])
            if g.cancelling:
                break
            t0 = time.perf_counter()
            q[chain] = self._solve(c, base_r, base_p, offs, q[chain], link, g)
            self.stats.ik_s += time.perf_counter() - t0
            gr, gp = chain_fk(base_r, base_p, offs, q[chain])
            keep = segs >= 0
            self.world.set_poses(objs, gp[keep], gr[keep])
            self.stats.iterations += 1
            moved = self.active[c] = True
        return moved

    def _solve(self, c, base_r, base_p, offs, qc, link, g) -> np.ndarray:
        cfg = self.cfg
        gr, gp = chain_fk(base_r, base_p, offs, qc)
        push = g.vector * (1.0 + cfg.skin / max(g.depth, 1e-12))
        n = g.vector / max(g.depth, 1e-12)
        d0 = self.avatar.cone_axes[self.avatar.chains[c][link], 0]
        along = abs(float(qrot(gr[link], d0) @ n)) < np.sin(cfg.parallel_angle)
        if along and link > 0:  # translate the link out, reconnect the chain above it
            keep = gr[link].copy()
            r = ccd_solve(base_r, base_p, offs, qc, link, np.zeros(3), gp[link] + push, self.limits[c], cfg.ccd,
                          top=link - 1)
            qn = r.local_rot
            gr2, _ = chain_fk(base_r, base_p, offs, qn)
            qn[link] = qmul(gr2[link - 1] * np.array([1.0, -1.0, -1.0, -1.0]), keep)
            self.stats.joints += link
            return project_chain(qn, self.limits[c])
        inv = gr[link] * np.array([1.0, -1.0, -1.0, -1.0])
        ee_local = qrot(inv, g.point - gp[link])
        r = ccd_solve(base_r, base_p, offs, qc, link, ee_local, g.point + push, self.limits[c], cfg.ccd)
        self.stats.joints += link + 1
        return r.local_rot

    def _fall_back(self, root, q):
        """Algorithm 1, step 4: move back along the way from the last free pose until free."""
        r0, q0 = self.free

        def pose(t):
            return r0 + t * (root - r0), quat.slerp(q0, q, t)

        def overlap(t):
            self._place(*pose(t))
            return self._deepest()

        t = interpolate_back(overlap, iterations=8, tolerance=self.cfg.tolerance)
        root, q = pose(t)
        self._place(root, q)
        return root, q
