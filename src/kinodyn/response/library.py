"""The reaction library (dynamic response, section 7.1): one clip per reaction strategy, packed for search.

The built-in library holds the project's reaction clips (:mod:`kinodyn.data.library`, every clip tagged
``reaction`` plus its mirror): steps forward and back (small, large, several), side stumbles, falls
forward, backward and to the side, shoulder rolls forward and backward, and upper-body flinches from the
front, the side and the back. Any
folder of BVH clips can replace it (:func:`from_folder`); the clips are resampled to one frame rate.

A :class:`ReactionLibrary` packs the clips (:class:`kinodyn.clips.ClipStore`, starts/stops) and
precomputes the ground-aligned windows of the search (:func:`kinodyn.response.search.windows`) once.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinodyn.clips import ClipStore
from kinodyn.errors import MotionError, ParameterError
from kinodyn.motion import Motion
from kinodyn.response.search import SearchConfig, Windows, body_tracks, body_weights, windows

__all__ = ["ReactionLibrary", "builtin", "builtin_names", "from_folder", "from_motions"]


@dataclass(frozen=True, eq=False)
class ReactionLibrary:
    """Reaction clips of one skeleton, packed, with their search windows.

    Attributes:
        clips: the packed clips (:class:`~kinodyn.clips.ClipStore`, all at one frame rate).
        config: the search parameters the windows were made with.
        windows: every clip's windows, one clip after another (:class:`Windows`, ``N`` rows).
        rows: ``(K, 2)`` first and one-past-last window row of each clip.
        weights: ``(wp (J,), wt (J,), ww (W,))`` body and window weights.
        tracks: per clip, its body tracks ``(pos (F, J, 3), rot (F, J, 4))``.
    """

    clips: ClipStore
    config: SearchConfig
    windows: Windows
    rows: np.ndarray
    weights: tuple
    tracks: tuple

    def __len__(self) -> int:
        return len(self.clips)

    @property
    def names(self) -> tuple[str, ...]:
        return self.clips.names

    @property
    def skeleton(self):
        return self.clips.skeleton

    @property
    def fps(self) -> float:
        return float(self.clips.fps[0])

    @property
    def window(self) -> int:
        return self.config.window(self.fps)

    def clip(self, k: int | str) -> Motion:
        return self.clips.motion(k)

    def fingerprint(self) -> str:
        """A hash of everything the search reads: the clips' names and content (:meth:`Motion.digest`) and
        the search parameters. A clip edited under the same name changes it (unlike :meth:`signature`)."""
        text = repr(self.config) + "".join(f"|{n}:{self.clip(k).digest()}" for k, n in enumerate(self.names))
        return hashlib.blake2b(text.encode(), digest_size=20).hexdigest()

    def signature(self) -> str:
        """A short text naming the clips and skeleton, stored with trained models to catch a mismatch."""
        return f"{len(self)} clips @ {self.fps:g} fps, {self.skeleton.num_joints} joints: " + ",".join(self.names)


def from_motions(motions: list[Motion], config: SearchConfig = SearchConfig(), tags=None) -> ReactionLibrary:
    """A library of ``motions`` (same skeleton and fps, unique names; at least one clip)."""
    if not motions:
        raise ParameterError("a reaction library needs at least one clip, got none")
    rates = {float(m.fps) for m in motions}
    if len(rates) > 1:
        raise MotionError(f"the clips of a reaction library must share one frame rate, got {sorted(rates)} fps")
    db = ClipStore.from_motions(list(motions), tags=tags)
    fps = rates.pop()
    w = config.window(fps)
    tracks, parts, rows, start = [], [], [], 0
    for k in range(len(db)):
        pos, rot = body_tracks(db.motion(k))
        tracks.append((pos, rot))
        win = windows(pos, rot, w)
        parts.append(win)
        rows.append((start, start + len(win)))
        start += len(win)
    if start == 0:
        raise ParameterError(f"every clip is shorter than the {w}-frame search window")
    packed = Windows(np.concatenate([p.pos for p in parts]), np.concatenate([p.rot for p in parts]),
                     np.concatenate([p.ground for p in parts]))
    wp, wt = body_weights(db.skeleton.names, config)
    return ReactionLibrary(db, config, packed, np.array(rows, dtype=np.int64), (wp, wt, config.frame_weights(fps)),
                           tuple(tracks))


def builtin_names() -> list[str]:
    """The built-in library's clips: every clip tagged ``reaction`` and its mirror."""
    from kinodyn.data import library as data

    return [n for n in data.names() if "reaction" in data.info(n).tags]


def builtin(config: SearchConfig = SearchConfig()) -> ReactionLibrary:
    """The built-in reaction library on the project's humanoid (60 fps)."""
    from kinodyn.data import library as data

    names = builtin_names()
    return from_motions([data.load(n) for n in names], config, [data.info(n).tags for n in names])


def from_folder(folder, config: SearchConfig = SearchConfig(), fps: float | None = None) -> ReactionLibrary:
    """A library of every ``*.bvh`` file in ``folder`` (sorted by name), resampled to ``fps`` (default the
    first file's rate). A T-pose frame added by the converter before the capture (the cgspeed CMU files,
    :func:`kinodyn.io.drop_added_tpose`) is left out: it is no reaction to match. Clips of the same joint
    hierarchy but other bone lengths play on the first clip's skeleton. Raises :class:`ParameterError`
    when the folder holds no BVH file and :class:`MotionError` when a clip has another joint hierarchy."""
    from kinodyn.io import drop_added_tpose
    from kinodyn.io.bvh import read_bvh

    folder = Path(folder)
    if not folder.is_dir():
        raise ParameterError(f"library must be a folder of BVH clips, got {str(folder)!r} (not a folder)")
    files = sorted(folder.glob("*.bvh"))
    if not files:
        raise ParameterError(f"library folder {str(folder)!r} holds no .bvh file")
    motions = [drop_added_tpose(read_bvh(f))[0].replace(name=f.stem) for f in files]
    rate = float(fps or motions[0].fps)
    motions = [m if abs(m.fps - rate) < 1e-9 else m.resample(rate) for m in motions]
    first = motions[0]
    sk = first.skeleton
    out = [first]
    for m in motions[1:]:
        if not m.skeleton.same_topology(sk):
            raise MotionError(f"clip {m.name!r} has another skeleton than {first.name!r} (joints "
                              f"{m.skeleton.num_joints} vs {sk.num_joints} or another hierarchy)")
        # Same hierarchy, other bone lengths (another actor): play its rotations on the first skeleton,
        # the root path scaled by the ratio of the skeletons' heights.
        scale = sk.height() / m.skeleton.height()
        out.append(Motion(sk, m.root_pos * scale, m.local_rot, m.fps, None, m.name))
    return from_motions(out, config)
