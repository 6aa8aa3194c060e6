"""The frame loop of figure 3: driven objects first (coupling, overlap removal, IK), then simulated ones.

Schmidl and Lin, "System architecture": each frame, virtual coupling pulls the driven objects toward
their trackers, collision detection and overlap elimination find non-overlapping positions (pure
translation for the rigid hand, CCD IK for the avatar's chains); then the simulated objects move for
the frame's time under gravity with impulses at their collisions. Fixed objects never move.

:class:`ContactSimulation` is the mutable simulator; :func:`run_scene` runs a scene file's scenario and
returns a :class:`RunResult` with the solved motion, object trajectories and per-frame figures.
Shapes: ``F`` frames, ``N`` objects; metres, seconds, ``(w, x, y, z)``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from kinodyn.contact import motions
from kinodyn.contact.avatar import build_avatar
from kinodyn.contact.collide import CollisionWorld
from kinodyn.contact.impulse import Bodies, ImpulseConfig, ImpulseStats, couple, step
from kinodyn.contact.overlap import OverlapConfig, remove_overlap
from kinodyn.contact.resolve import AvatarDriver, ResolveConfig
from kinodyn.contact.scenefile import Scene, resolve_motion
from kinodyn.motion import Motion

__all__ = ["FRAME_KEYS", "ContactSimulation", "RunResult", "SimulationConfig", "run_scene"]

#: Per-frame figures recorded by :meth:`ContactSimulation.run` (Table 2's columns and more).
FRAME_KEYS = ("frame_ms", "wall_ms", "ik_ms", "query_ms", "impulse_ms", "iterations", "joints", "pairs", "penetration_mm",
              "fallback", "collisions", "phase")


@dataclass(frozen=True)
class SimulationConfig:
    """Settings of the frame loop (defaults: the paper's K = 1000, R = 40, Table 1 materials)."""

    resolve: ResolveConfig = field(default_factory=ResolveConfig)
    impulse: ImpulseConfig = field(default_factory=ImpulseConfig)
    overlap: OverlapConfig = field(default_factory=OverlapConfig)


@dataclass(frozen=True)
class RunResult:
    """What a scenario run produced.

    Attributes:
        scene: the scene's name; names: ``N`` object names.
        motion: the avatar's solved motion (None without an avatar); tracked: its input.
        pos, quat: ``(F, N, 3)``, ``(F, N, 4)`` object trajectories.
        frames: per-frame figures, a ``(F,)`` array per key of :data:`FRAME_KEYS`.
        fps: frame rate.
        solved: per frame, the avatar chains IK solved or held (inside their limits and cones).
    """

    scene: str
    names: tuple[str, ...]
    motion: Motion | None
    tracked: Motion | None
    pos: np.ndarray
    quat: np.ndarray
    frames: dict
    fps: float
    solved: tuple = ()


class ContactSimulation:
    """A scene being simulated (mutable)."""

    def __init__(self, scene: Scene, config: SimulationConfig | None = None):
        self.scene, self.cfg = scene, config or SimulationConfig()
        objects = list(scene.objects)
        self.tracked = None
        self.hand = None
        if scene.hand is not None:
            self.hand = len(objects)
            objects.append(motions.hand_object(scene.hand.mass))
            fps = scene.fps or 60.0
            self.hand_track = motions.hand_path(scene.hand.path, fps)
        exclude = []
        self.avatar, self.first = None, len(objects)
        if scene.avatar is not None:
            m = motions.scenario_motion(resolve_motion(scene.avatar.motion))
            x, y, h = scene.avatar.place
            self.tracked = m.aligned_to(np.array([x, y, np.deg2rad(h)]), 0)
            if scene.fps and abs(scene.fps - m.fps) > 1e-9:
                self.tracked = self.tracked.resample(scene.fps)
            self.avatar = build_avatar(m.skeleton, scene.avatar.material)
            objects += list(self.avatar.segments)
            exclude = [(self.first + a, self.first + b) for a, b in self.avatar.exclude]
        self.fps = float(scene.fps or (self.tracked.fps if self.tracked is not None else 60.0))
        self.world = CollisionWorld(objects, exclude)
        self.bodies = Bodies(self.world)
        if self.hand is not None:
            self.bodies.inv_mass[self.hand] = 1.0 / scene.hand.mass
        self.driver = None
        if self.avatar is not None:
            rc = self.cfg.resolve
            if not scene.avatar.self_collision:
                from dataclasses import replace

                rc = replace(rc, self_collision=False)
            self.driver = AvatarDriver(self.avatar, self.world, self.first, self.fps, rc)
        self.hand_free = None

    def num_frames(self) -> int:
        n = []
        if self.tracked is not None:
            n.append(self.tracked.num_frames)
        if self.hand is not None:
            n.append(len(self.hand_track[0]))
        return int(self.scene.frames or (min(n) if n else int(self.fps * 5)))

    def _hand(self, f: int) -> None:
        pos, flex, index, _ = self.hand_track
        f = min(f, len(pos) - 1)
        lp, lq, _ = motions.hand_pose(flex[f], index[f])
        self.world.set_local(self.hand, lp, lq)
        vel = (pos[min(f + 1, len(pos) - 1)] - pos[max(f - 1, 0)]) * self.fps / 2.0
        if f == 0:
            self.world.set_poses([self.hand], pos[0], self.world.quat[self.hand])
            self.bodies.vel[self.hand] = vel
        couple(self.bodies, self.hand, pos[f], vel, 1.0 / self.fps, self.scene.hand.mass, self.cfg.impulse)
        free = self.hand_free if self.hand_free is not None else self.world.pos[self.hand].copy()
        remove_overlap(self.world, [self.hand], free[None], self.cfg.overlap)
        self.hand_free = self.world.pos[self.hand].copy()

    def frame(self, f: int, out: dict) -> tuple:
        """Simulate frame ``f``; fills ``out`` (one value per :data:`FRAME_KEYS` key)."""
        c0, t0 = time.thread_time(), time.perf_counter()
        pose = None
        if self.hand is not None:
            self._hand(f)
        if self.driver is not None:
            ff = min(f, self.tracked.num_frames - 1)
            root, q, st = self.driver.step(self.tracked.root_pos[ff], self.tracked.local_rot[ff])
            pose = (root, q)
            out.update(ik_ms=st.ik_s * 1e3, query_ms=st.query_s * 1e3, iterations=st.iterations, joints=st.joints,
                       pairs=st.pairs, penetration_mm=st.penetration * 1e3, fallback=float(st.fallback))
        t1 = time.perf_counter()
        ist = ImpulseStats()
        sub = self.cfg.impulse.substeps
        for _ in range(sub):
            step(self.bodies, 1.0 / (self.fps * sub), self.cfg.impulse, ist)
        t2 = time.perf_counter()
        out.update(frame_ms=(time.thread_time() - c0) * 1e3, wall_ms=(t2 - t0) * 1e3, impulse_ms=(t2 - t1) * 1e3,
                   collisions=ist.collisions)
        if self.hand is not None:
            out["phase"] = float(self.hand_track[3][min(f, len(self.hand_track[3]) - 1)])
        return pose

    def run(self, frames: int | None = None, progress=None) -> RunResult:
        """Run ``frames`` frames (default :meth:`num_frames`)."""
        n = frames or self.num_frames()
        rec = {k: np.zeros(n) for k in FRAME_KEYS}
        pos = np.zeros((n, self.world.num_objects, 3))
        quats = np.zeros((n, self.world.num_objects, 4))
        roots, rots, solved = [], [], []
        it = range(n) if progress is None else progress(range(n), desc=self.scene.name)
        for f in it:
            out = {}
            pose = self.frame(f, out)
            for k, v in out.items():
                rec[k][f] = v
            pos[f], quats[f] = self.world.pos, self.world.quat
            if pose is not None:
                roots.append(pose[0])
                rots.append(pose[1])
                solved.append(self.driver.stats.solved)
        motion = tracked = None
        if self.tracked is not None:
            tracked = self.tracked[: min(n, self.tracked.num_frames)]
            k = len(tracked.root_pos)
            motion = tracked.replace(root_pos=np.array(roots[:k]), local_rot=np.array(rots[:k]),
                                     name=f"{self.scene.name}_resolved")
        return RunResult(self.scene.name, tuple(o.name for o in self.world.objects), motion, tracked, pos, quats,
                         rec, self.fps, tuple(solved))


def run_scene(scene: Scene, frames: int | None = None, config: SimulationConfig | None = None,
              progress=None) -> RunResult:
    """Simulate a scene (see :class:`ContactSimulation`)."""
    return ContactSimulation(scene, config).run(frames, progress)
