"""Clip databases: many clips of one skeleton packed into one array, with ``starts``/``stops``.

Searches over a database (motion graphs, reaction lookup, ranking) index frames globally: frame ``i``
of clip ``k`` is row ``starts[k] + i``. A database saves to one ``.npz`` archive whose metadata is JSON
(no pickles) and loads back exactly.

Shapes: ``N`` frames in all, ``K`` clips, ``J`` joints.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinodyn._arrays import readonly
from kinodyn.errors import FileFormatError, MotionError, UnknownNameError
from kinodyn.io.atomic import atomic_path
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

__all__ = ["ClipDatabase"]

FORMAT = "kinodyn.clips/1"


@dataclass(frozen=True, eq=False)
class ClipDatabase:
    """Clips of one skeleton at one frame rate, packed.

    Attributes:
        skeleton: the shared skeleton.
        root_pos: ``(N, 3)`` root positions of all clips, one after another.
        local_rot: ``(N, J, 4)`` local rotations.
        fps: frames per second of every clip.
        starts, stops: ``(K,)`` first and one-past-last row of each clip.
        names: ``K`` clip names (unique).
        tags: per clip, a tuple of labels (e.g. ``("reaction", "back")``).
    """

    skeleton: Skeleton
    root_pos: np.ndarray
    local_rot: np.ndarray
    fps: float
    starts: np.ndarray
    stops: np.ndarray
    names: tuple[str, ...]
    tags: tuple[tuple[str, ...], ...]

    def __post_init__(self):
        n = len(self.local_rot)
        object.__setattr__(self, "root_pos", readonly(self.root_pos))
        object.__setattr__(self, "local_rot", readonly(self.local_rot))
        object.__setattr__(self, "starts", readonly(self.starts, np.int64))
        object.__setattr__(self, "stops", readonly(self.stops, np.int64))
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "tags", tuple(tuple(t) for t in self.tags))
        k = len(self.names)
        if self.starts.shape != (k,) or self.stops.shape != (k,) or len(self.tags) != k:
            raise MotionError(f"starts, stops and tags must each have one entry per clip ({k})")
        if len(set(self.names)) != k:
            raise MotionError("clip names must be unique")
        if k and (self.starts[0] != 0 or self.stops[-1] != n or np.any(self.starts[1:] != self.stops[:-1])
                  or np.any(self.stops <= self.starts)):
            raise MotionError("clips must tile the packed arrays: starts[0] == 0, stops[-1] == N, "
                              "starts[k+1] == stops[k], and no empty clip")

    @classmethod
    def from_motions(cls, motions: list[Motion], tags: list[tuple[str, ...]] | None = None) -> "ClipDatabase":
        """Pack motions (same skeleton topology and fps; names must be unique and non-empty)."""
        if not motions:
            raise MotionError("a clip database needs at least one motion")
        sk, fps = motions[0].skeleton, motions[0].fps
        for m in motions:
            if not m.skeleton.same_topology(sk) or not np.allclose(m.skeleton.offsets, sk.offsets, atol=1e-9):
                raise MotionError(f"clip {m.name!r} has another skeleton than {motions[0].name!r}")
            if abs(m.fps - fps) > 1e-9:
                raise MotionError(f"clip {m.name!r} is at {m.fps:g} fps, not {fps:g}; resample first")
            if m.translations is not None:
                raise MotionError(f"clip {m.name!r} animates joint translations; databases hold rotations only")
        lengths = np.array([m.num_frames for m in motions])
        stops = np.cumsum(lengths)
        names = [m.name or f"clip{i}" for i, m in enumerate(motions)]
        return cls(sk, np.concatenate([m.root_pos for m in motions]),
                   np.concatenate([m.local_rot for m in motions]), fps, stops - lengths, stops, names,
                   tags if tags is not None else [()] * len(motions))

    def __len__(self) -> int:
        return len(self.names)

    @property
    def num_frames(self) -> int:
        return len(self.local_rot)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise UnknownNameError(f"no clip named {name!r}; clips: {', '.join(self.names)}") from None

    def clip(self, key: int | str) -> Motion:
        """One clip as a :class:`Motion` (by index or name)."""
        k = self.index(key) if isinstance(key, str) else int(key)
        a, b = self.starts[k], self.stops[k]
        return Motion(self.skeleton, self.root_pos[a:b], self.local_rot[a:b], self.fps, None, self.names[k])

    def clip_of_frame(self, rows) -> np.ndarray:
        """Clip index of global frame rows ``(...)``."""
        return np.searchsorted(self.stops, np.asarray(rows), side="right")

    def with_tag(self, tag: str) -> list[int]:
        return [k for k, t in enumerate(self.tags) if tag in t]

    def save(self, path) -> None:
        """Write to ``path`` (``.npz``) atomically."""
        sk = self.skeleton
        meta = {"format": FORMAT, "joint_names": list(sk.names), "fps": self.fps, "names": list(self.names),
                "tags": [list(t) for t in self.tags]}
        with atomic_path(path, suffix=".npz") as tmp:
            np.savez_compressed(tmp, meta=np.array(json.dumps(meta)), parents=sk.parents, offsets=sk.offsets,
                                end_parents=sk.end_parents, end_offsets=sk.end_offsets, root_pos=self.root_pos,
                                local_rot=self.local_rot, starts=self.starts, stops=self.stops)

    @classmethod
    def load(cls, path) -> "ClipDatabase":
        """Read a database written by :meth:`save`."""
        try:
            with np.load(Path(path), allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                if meta.get("format") != FORMAT:
                    raise FileFormatError(f"not a kinodyn clip database (format {meta.get('format')!r})", path)
                sk = Skeleton(tuple(meta["joint_names"]), z["parents"], z["offsets"], z["end_parents"],
                              z["end_offsets"])
                return cls(sk, z["root_pos"], z["local_rot"], meta["fps"], z["starts"], z["stops"],
                           meta["names"], [tuple(t) for t in meta["tags"]])
        except (KeyError, ValueError, OSError, json.JSONDecodeError) as e:
            if isinstance(e, FileFormatError):
                raise
            raise FileFormatError(f"cannot read clip database: {e}", path) from None
