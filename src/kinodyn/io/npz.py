"""Motions in numpy ``.npz`` archives: arrays plus JSON metadata, never pickles."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from kinodyn.errors import FileFormatError
from kinodyn.io.atomic import atomic_path
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

__all__ = ["save_npz", "load_npz", "FORMAT"]

FORMAT = "kinodyn.motion/1"


def save_npz(path, motion: Motion) -> None:
    """Write ``motion`` to ``path`` (``.npz``), atomically."""
    sk = motion.skeleton
    meta = {"format": FORMAT, "names": list(sk.names), "fps": motion.fps, "name": motion.name}
    arrays = dict(parents=sk.parents, offsets=sk.offsets, end_parents=sk.end_parents, end_offsets=sk.end_offsets,
                  root_pos=motion.root_pos, local_rot=motion.local_rot, meta=np.array(json.dumps(meta)))
    if motion.translations is not None:
        arrays["translations"] = motion.translations
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez_compressed(tmp, **arrays)


def load_npz(path) -> Motion:
    """Read a motion written by :func:`save_npz` (``allow_pickle`` stays off)."""
    try:
        with np.load(Path(path), allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            if meta.get("format") != FORMAT:
                raise FileFormatError(f"not a kinodyn motion archive (format {meta.get('format')!r})", path)
            sk = Skeleton(tuple(meta["names"]), z["parents"], z["offsets"], z["end_parents"], z["end_offsets"])
            tr = z["translations"] if "translations" in z.files else None
            return Motion(sk, z["root_pos"], z["local_rot"], meta["fps"], tr, meta.get("name", ""))
    except (KeyError, ValueError, OSError, json.JSONDecodeError) as e:
        if isinstance(e, FileFormatError):
            raise
        raise FileFormatError(f"cannot read motion archive: {e}", path) from None
