"""The packed clip store: many clips of one skeleton in one set of arrays, with ``starts``/``stops``.

Every capability that plays or searches clips (blending, the dynamic response, scene generation, the
crowd) uses this one store. Frame ``i`` of clip ``k`` is row ``starts[k] + i`` of every per-frame array,
so searches index frames globally. Each clip is kept twice: as given (``root_pos``, ``local_rot``, for
:meth:`ClipStore.motion`) and in its *facing frame* (Ménardais et al., support-phase synchronization,
section 3: the root is blended in each action's own frame): the root rotation without heading
(``rot``), the root height (``z``) and the ground transform ``(x, y, unwrapped heading)`` of every
frame (``ground``). A cyclic clip is closed (:func:`close_loop`) and loops: one loop moves the whole
clip on by ``loop[k]``, and :func:`unroll_loops` composes looped playback.

Per clip the store may also hold its support: the support-phase sequence (codes of
:mod:`kinodyn.phases`), the phase and the left foot's share of the weight at every frame, and the
height of its planted feet (:func:`rest_height`), as :class:`ClipSupport` rows computed by the caller
(blending builds them from foot contacts). A store is frozen: :meth:`ClipStore.add` returns a new one.
It saves to one ``.npz`` archive with JSON metadata (no pickles) and loads back exactly.

Shapes: ``N`` frames in all, ``C`` clips, ``J`` joints, ``E`` support-phase elements in all.
Units: seconds, metres, radians.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, fields
from pathlib import Path
from typing import NamedTuple

import numpy as np

from kinodyn import contacts
from kinodyn._arrays import readonly
from kinodyn.errors import FileFormatError, MotionError, ParameterError, UnknownNameError
from kinodyn.io.atomic import atomic_path
from kinodyn.math import quat, xform
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

__all__ = ["FORMAT", "NO_PHASE", "ClipStore", "ClipSupport", "close_loop", "facing_frames", "load", "rest_height",
           "unroll_loops"]

#: The ``format`` of a saved store's metadata.
FORMAT = "kinodyn.clips/2"
#: Phase code of the frames of a clip stored without support.
NO_PHASE = -1


class ClipSupport(NamedTuple):
    """The support of one clip, as the store keeps it (computed by the caller).

    Attributes:
        phases: ``(K,)`` int8 support-phase codes of its sequence (:mod:`kinodyn.phases`).
        durations: ``(K,)`` element durations in seconds.
        start: clip time of the first element's start (negative when it straddles a loop point).
        frame_phase: ``(F,)`` int8 phase code at every frame.
        left_share: ``(F,)`` share of the body's weight on the left foot at every frame.
        rest: height of the clip's planted feet (m), see :func:`rest_height`.
    """

    phases: np.ndarray
    durations: np.ndarray
    start: float
    frame_phase: np.ndarray
    left_share: np.ndarray
    rest: float


def rest_height(found) -> float:
    """Height of a planted foot's lowest point from a clip's :class:`~kinodyn.contacts.FootContacts`:
    the median over its contact frames (the lowest foot point of the whole clip when it never touches
    the ground; 0 when the skeleton has no feet, ``found is None``)."""
    if found is None:
        return 0.0
    z = np.concatenate([found.lowest[s][found.labels[s], 2] for s in contacts.SIDES])
    if len(z) == 0:
        return float(min(found.lowest[s][:, 2].min() for s in contacts.SIDES))
    return float(np.median(z))


def close_loop(rot, z):
    """Make a cyclic clip seamless: its last frame must equal its first, which captured cycles only
    approximate (a few degrees and centimetres apart). The mismatch of every joint rotation ``rot
    (F, J, 4)`` (facing frame) and of the root height ``z (F,)`` is spread linearly over the clip, half
    taken off the first frame and half added to the last, so the loop point no longer jumps."""
    n = len(z)
    s = np.arange(n) / (n - 1) - 0.5
    d = quat.inv_mul(rot[-1], rot[0])
    rot = quat.mul(rot, quat.exp(s[:, None, None] * quat.log(d)[None]))
    return rot, z + s * (z[0] - z[-1])


def facing_frames(motion: Motion, cyclic: bool):
    """A clip in its facing frame: ``rot (F, J, 4)`` local rotations with the root's heading taken out
    (hemisphere-continuous), ``z (F,)`` root heights, ``ground (F, 3)`` ground transforms with an
    unwrapped heading, and ``loop (3,)``: the world transform (applied on the left) by which one loop
    of a cyclic clip moves it, so the frame at time ``u`` of cycle ``c`` is ``compose(loop^c,
    ground(u))`` (zeros for a clip that does not loop). A cyclic clip is closed (:func:`close_loop`)."""
    lr = quat.unroll(motion.local_rot)
    g = motion.ground()
    g[:, 2] = np.unwrap(g[:, 2])
    lr = np.array(lr)
    lr[:, 0] = quat.inv_mul(quat.from_heading(g[:, 2]), lr[:, 0])
    lr = quat.unroll(lr)
    z = np.array(motion.root_pos[:, 2])
    if cyclic:
        lr, z = close_loop(lr, z)
    loop = xform.compose(g[-1], xform.inverse(g[0])) if cyclic else np.zeros(3)
    return lr, z, g, loop


def unroll_loops(loop, g, cycles) -> np.ndarray:
    """Ground transforms ``g (..., 3)`` moved on by ``cycles (...)`` whole loops of their clip (each
    loop composes ``loop (..., 3)`` on the left): ``compose(loop^cycles, g)``, elementwise.

    This is how looped playback is composed everywhere: the frame at clip time ``u`` of repetition
    ``c`` is ``unroll_loops(loop, ground(u), c)``; the transform of ``c >= 1`` repetitions alone is
    ``unroll_loops(loop, loop, c - 1)``.
    """
    cycles = np.asarray(cycles)
    for _ in range(int(cycles.max(initial=0))):
        g = np.where((cycles > 0)[..., None], xform.compose(loop, g), g)
        cycles = cycles - 1
    return g


#: per-frame arrays, per-clip arrays and support-element arrays of a store (the npz payload).
_FRAME_FIELDS = ("root_pos", "local_rot", "rot", "z", "ground", "frame_phase", "left_share")
_CLIP_FIELDS = ("fps", "is_cyclic", "starts", "stops", "loop", "rest", "seq_start", "seq_offsets")
_DTYPES = {"frame_phase": np.int8, "seq_phases": np.int8, "is_cyclic": np.bool_, "starts": np.int64,
           "stops": np.int64, "seq_offsets": np.int64}


@dataclass(frozen=True, eq=False)
class ClipStore:
    """Clips of one skeleton, packed (frozen; :meth:`add` returns a new store).

    Attributes:
        skeleton: the skeleton every clip plays on (clips of other bone lengths are retargeted).
        names: ``C`` unique clip names; ``tags``: per clip, a tuple of labels.
        fps: ``(C,)`` frame rate of each clip; ``is_cyclic``: ``(C,)`` whether it loops.
        starts, stops: ``(C,)`` first and one-past-last row of each clip.
        root_pos, local_rot: ``(N, 3)``, ``(N, J, 4)`` the clips as given (retargeted).
        rot, z, ground: ``(N, J, 4)``, ``(N,)``, ``(N, 3)`` the facing frames (:func:`facing_frames`).
        loop: ``(C, 3)`` the transform one loop moves a cyclic clip by (zeros otherwise).
        frame_phase, left_share: ``(N,)`` support phase (``NO_PHASE`` without support) and left share.
        rest: ``(C,)`` planted-foot heights (NaN without support).
        seq_phases, seq_durations: ``(E,)`` the support-phase sequences, one after another; clip ``k``'s
            elements are rows ``seq_offsets[k]:seq_offsets[k + 1]`` (``seq_offsets`` is ``(C + 1,)``),
            its first element starts at clip time ``seq_start[k]``.
    """

    skeleton: Skeleton
    names: tuple
    tags: tuple
    fps: np.ndarray
    is_cyclic: np.ndarray
    starts: np.ndarray
    stops: np.ndarray
    root_pos: np.ndarray
    local_rot: np.ndarray
    rot: np.ndarray
    z: np.ndarray
    ground: np.ndarray
    loop: np.ndarray
    frame_phase: np.ndarray
    left_share: np.ndarray
    rest: np.ndarray
    seq_phases: np.ndarray
    seq_durations: np.ndarray
    seq_offsets: np.ndarray
    seq_start: np.ndarray

    def __post_init__(self):
        if not isinstance(self.skeleton, Skeleton):
            raise ParameterError(f"skeleton must be a Skeleton, got {type(self.skeleton).__name__}")
        for f in fields(self):
            if f.name in ("skeleton", "names", "tags"):
                continue
            object.__setattr__(self, f.name, readonly(getattr(self, f.name), _DTYPES.get(f.name, np.float64)))
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "tags", tuple(tuple(t) for t in self.tags))
        self._check()

    def _check(self):
        k, n = len(self.names), len(self.rot)
        bad = [f for f in _CLIP_FIELDS if len(getattr(self, f)) != (k + 1 if f == "seq_offsets" else k)]
        bad += [f for f in _FRAME_FIELDS if len(getattr(self, f)) != n]
        if bad or len(self.tags) != k:
            raise MotionError(f"clip store arrays must have one row per clip ({k}) or frame ({n}): "
                              f"{', '.join(bad) or 'tags'} do not")
        if len(set(self.names)) != k:
            raise MotionError("clip names must be unique")
        if k and (self.starts[0] != 0 or self.stops[-1] != n or np.any(self.starts[1:] != self.stops[:-1])
                  or np.any(self.stops - self.starts < 2)):
            raise MotionError("clips must tile the packed arrays: starts[0] == 0, stops[-1] == N, "
                              "starts[k+1] == stops[k], and at least 2 frames per clip")

    # ------------------------------------------------------------------ building
    @classmethod
    def empty(cls, skeleton: Skeleton) -> ClipStore:
        """A store without clips for ``skeleton``."""
        if not isinstance(skeleton, Skeleton):
            raise ParameterError(f"skeleton must be a Skeleton, got {type(skeleton).__name__}")
        j = skeleton.num_joints
        return cls(skeleton, (), (), np.zeros(0), np.zeros(0, bool), np.zeros(0, np.int64), np.zeros(0, np.int64),
                   np.zeros((0, 3)), np.zeros((0, j, 4)), np.zeros((0, j, 4)), np.zeros(0), np.zeros((0, 3)),
                   np.zeros((0, 3)), np.zeros(0, np.int8), np.zeros(0), np.zeros(0), np.zeros(0, np.int8),
                   np.zeros(0), np.zeros(1, np.int64), np.zeros(0))

    def prepare(self, name: str, motion: Motion) -> Motion:
        """Check that ``motion`` may join the store as ``name``; returns it retargeted to the store's
        skeleton when its bone lengths differ (what :meth:`add` stores)."""
        if name in self.names:
            raise ParameterError(f"a clip named {name!r} is already in the library")
        if not isinstance(motion, Motion):
            raise ParameterError(f"motion must be a Motion, got {type(motion).__name__}")
        if not motion.skeleton.same_topology(self.skeleton):
            raise MotionError(f"clip {name!r} does not fit the library's skeleton (joint names or parents differ)")
        if motion.num_frames < 2:
            raise MotionError(f"clip {name!r} needs at least 2 frames, got {motion.num_frames}")
        if not np.allclose(motion.skeleton.offsets, self.skeleton.offsets, atol=1e-6):
            motion = motion.retargeted(self.skeleton)
        return motion

    def add(self, name: str, motion: Motion, cyclic: bool = False, support: ClipSupport | None = None,
            tags=()) -> ClipStore:
        """A new store with one more clip (this one is unchanged).

        Args:
            name: unique name.
            motion: the clip (any fps; the store's joint names and parents; other bone lengths are
                retargeted, see :meth:`prepare`).
            cyclic: the clip loops: its last frame is its first again, up to the root's floor position
                (a captured cycle that misses by a little is closed, see :func:`close_loop`).
            support: its :class:`ClipSupport` (per-frame rows for the prepared motion), or ``None``.
            tags: labels (e.g. ``("reaction", "back")``).
        """
        motion = self.prepare(name, motion)
        rot, z, g, loop = facing_frames(motion, bool(cyclic))
        f = motion.num_frames
        if support is None:
            support = ClipSupport(np.zeros(0, np.int8), np.zeros(0), 0.0, np.full(f, NO_PHASE, np.int8),
                                  np.full(f, np.nan), np.nan)
        elif len(support.frame_phase) != f or len(support.left_share) != f:
            raise ParameterError(f"support of clip {name!r} must have {f} frame rows, got "
                                 f"{len(support.frame_phase)} and {len(support.left_share)}")
        n = len(self.rot)
        cat = np.concatenate
        return ClipStore(
            self.skeleton, self.names + (name,), self.tags + (tuple(tags),), cat([self.fps, [motion.fps]]),
            cat([self.is_cyclic, [bool(cyclic)]]), cat([self.starts, [n]]), cat([self.stops, [n + f]]),
            cat([self.root_pos, motion.root_pos]), cat([self.local_rot, motion.local_rot]), cat([self.rot, rot]),
            cat([self.z, z]), cat([self.ground, g]), cat([self.loop, loop[None]]),
            cat([self.frame_phase, np.asarray(support.frame_phase, np.int8)]), cat([self.left_share, support.left_share]),
            cat([self.rest, [support.rest]]), cat([self.seq_phases, np.asarray(support.phases, np.int8)]),
            cat([self.seq_durations, support.durations]),
            cat([self.seq_offsets, [self.seq_offsets[-1] + len(support.phases)]]),
            cat([self.seq_start, [support.start]]))

    @classmethod
    def from_motions(cls, motions, names=None, cyclic=None, tags=None) -> ClipStore:
        """Pack motions (the first one's skeleton; names default to the motions' own, which must then be
        unique and non-empty) without support."""
        motions = list(motions)
        if not motions:
            raise MotionError("a clip store needs at least one motion")
        names = [m.name for m in motions] if names is None else list(names)
        cyclic = [False] * len(motions) if cyclic is None else list(cyclic)
        tags = [()] * len(motions) if tags is None else list(tags)
        if not (len(names) == len(cyclic) == len(tags) == len(motions)):
            raise ParameterError(f"names, cyclic and tags must have one entry per motion ({len(motions)})")
        store = cls.empty(motions[0].skeleton)
        for m, n, c, t in zip(motions, names, cyclic, tags):
            if not n:
                raise MotionError("every clip needs a non-empty name")
            store = store.add(n, m, c, tags=t)
        return store

    # ------------------------------------------------------------------ queries
    def __len__(self) -> int:
        return len(self.names)

    @property
    def num_frames(self) -> int:
        return len(self.rot)

    @property
    def nframes(self) -> np.ndarray:
        """``(C,)`` frames of each clip."""
        return self.stops - self.starts

    @property
    def durations(self) -> np.ndarray:
        """``(C,)`` clip durations in seconds (a cyclic clip's loop period)."""
        return (self.nframes - 1) / self.fps

    def index(self, name) -> int:
        """Index of a clip given by name (or by index, checked)."""
        if isinstance(name, (int, np.integer)):
            if not 0 <= int(name) < len(self.names):
                raise UnknownNameError(f"clip index {name} out of range (library has {len(self.names)} clips)")
            return int(name)
        try:
            return self.names.index(name)
        except ValueError:
            raise UnknownNameError(f"unknown clip {name!r}; the library has: {', '.join(self.names)}") from None

    def cyclic(self, name) -> bool:
        return bool(self.is_cyclic[self.index(name)])

    def duration(self, name) -> float:
        return float(self.durations[self.index(name)])

    def motion(self, name) -> Motion:
        """One clip as a :class:`Motion` (by name or index), as it was added (retargeted)."""
        k = self.index(name)
        a, b = self.starts[k], self.stops[k]
        return Motion(self.skeleton, self.root_pos[a:b], self.local_rot[a:b], float(self.fps[k]), None,
                      self.names[k])

    def support(self, name) -> tuple[np.ndarray, np.ndarray, float]:
        """``(phases (K,), durations (K,), start)`` of a clip's support-phase sequence (empty without)."""
        k = self.index(name)
        a, b = self.seq_offsets[k], self.seq_offsets[k + 1]
        return self.seq_phases[a:b], self.seq_durations[a:b], float(self.seq_start[k])

    def clip_of_frame(self, rows) -> np.ndarray:
        """Clip index of global frame rows ``(...)``."""
        return np.searchsorted(self.stops, np.asarray(rows), side="right")

    def with_tag(self, tag: str) -> list[int]:
        return [k for k, t in enumerate(self.tags) if tag in t]

    # ------------------------------------------------------------------ sampling
    def locate(self, clip, tau):
        """Where clips ``clip (...)`` are at clip times ``tau (...)`` (cyclic clips wrap, others clamp).

        Returns:
            ``i0 (...)`` the global frame before, ``a (...)`` the fraction toward ``i0 + 1``, ``cyc (...)``
            the number of whole loops played, ``g (..., 3)`` the ground transform within the loop.
        """
        if not len(self.names):
            raise ParameterError("the clip library is empty")
        fps = self.fps[clip]
        n = self.nframes[clip]
        dur = self.durations[clip]
        cyclic = self.is_cyclic[clip]
        cyc = np.where(cyclic, np.floor(tau / dur), 0.0)
        u = np.where(cyclic, tau - cyc * dur, np.clip(tau, 0.0, dur))
        x = u * fps
        i = np.clip(np.floor(x), 0, n - 2).astype(np.int64)
        a = np.clip(x - i, 0.0, 1.0)
        i0 = self.starts[clip] + i
        gr = self.ground
        g = gr[i0] * (1.0 - a[..., None]) + gr[i0 + 1] * a[..., None]
        return i0, a, cyc.astype(np.int64), g

    def sample(self, clip, tau, prev_tau=None):
        """Batched sampling of clips at clip times.

        Args:
            clip: ``(...)`` clip indices.
            tau: ``(...)`` clip times in seconds (cyclic clips wrap, others clamp).
            prev_tau: ``(...)`` clip times one frame earlier, for the root motion (optional).

        Returns:
            ``rot (..., J, 4)`` facing-frame local rotations, ``z (...)`` root heights, and when
            ``prev_tau`` is given the root motion ``delta (..., 3)`` (dx, dy, dheading) from
            ``prev_tau`` to ``tau`` in the facing frame at ``prev_tau``.
        """
        clip = np.asarray(clip, dtype=np.int64)
        tau = np.asarray(tau, dtype=np.float64)
        i0, a, cyc, g = self.locate(clip, tau)
        a4 = a[..., None, None]
        rot = self.rot[i0] * (1.0 - a4) + self.rot[i0 + 1] * a4
        z = self.z[i0] * (1.0 - a) + self.z[i0 + 1] * a
        if prev_tau is None:
            return rot, z
        _, _, cyc0, g0 = self.locate(clip, np.asarray(prev_tau, dtype=np.float64))
        g = unroll_loops(self.loop[clip], g, np.maximum(cyc - cyc0, 0))
        return rot, z, xform.relative(g0, g)

    # ------------------------------------------------------------------ files
    def save(self, path) -> None:
        """Write to ``path`` (``.npz``, JSON metadata) atomically."""
        sk = self.skeleton
        meta = {"format": FORMAT, "joint_names": list(sk.names), "names": list(self.names),
                "tags": [list(t) for t in self.tags]}
        arrays = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("skeleton", "names", "tags")}
        with atomic_path(path, suffix=".npz") as tmp:
            np.savez_compressed(tmp, meta=np.array(json.dumps(meta)), parents=sk.parents, offsets=sk.offsets,
                                end_parents=sk.end_parents, end_offsets=sk.end_offsets, **arrays)


def load(path) -> ClipStore:
    """Read a store written by :meth:`ClipStore.save` (never unpickles)."""
    try:
        with np.load(Path(path), allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("format") != FORMAT:
                raise FileFormatError(f"not a kinodyn clip store (format {meta.get('format')!r})", path)
            sk = Skeleton(tuple(meta["joint_names"]), z["parents"], z["offsets"], z["end_parents"], z["end_offsets"])
            arrays = {f.name: z[f.name] for f in fields(ClipStore) if f.name not in ("skeleton", "names", "tags")}
            return ClipStore(sk, meta["names"], meta["tags"], **arrays)
    except (KeyError, ValueError, OSError, json.JSONDecodeError, MotionError) as e:
        if isinstance(e, FileFormatError):
            raise
        raise FileFormatError(f"cannot read clip store: {e}", path) from None
