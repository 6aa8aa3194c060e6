"""Motions in numpy ``.npz`` archives: arrays plus JSON metadata, never pickles."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from kinodyn.errors import FileFormatError
from kinodyn.io.atomic import atomic_path
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

__all__ = ["save_npz", "load_npz", "holds_other_arrays", "FORMAT", "NOT_A_MOTION_ARCHIVE"]

FORMAT = "kinodyn.motion/1"
NOT_A_MOTION_ARCHIVE = "not a kinodyn motion archive"


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


def holds_other_arrays(path) -> bool:
    """True when ``path`` is a readable ``.npz`` archive that is not a motion: kinodyn's other archives
    (a scene's object trajectories, a crowd recording). False for a motion archive and for a file that
    cannot be read as an archive at all (:func:`load_npz` names what is wrong with that one)."""
    try:
        with np.load(Path(path), allow_pickle=False) as z:
            return not {"meta", "local_rot", "root_pos"} <= set(z.files)
    except (OSError, EOFError, ValueError, zipfile.BadZipFile, AttributeError):
        return False


def load_npz(path) -> Motion:
    """Read a motion written by :func:`save_npz` (``allow_pickle`` stays off).

    Raises:
        FileFormatError: naming ``path``, for an empty file, one that is not a zip archive of arrays
            (random bytes, a pickle, a lone ``.npy``), or an archive without kinodyn's arrays.
    """
    try:
        z = np.load(Path(path), allow_pickle=False)
    except (EOFError, ValueError, zipfile.BadZipFile) as e:
        # numpy's own messages suggest allow_pickle=True, which kinodyn never does with user files
        what = "the file is empty" if isinstance(e, EOFError) or not Path(path).stat().st_size else \
            "not a zip archive of arrays"
        raise FileFormatError(f"{NOT_A_MOTION_ARCHIVE} ({what})", path) from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise FileFormatError(f"{NOT_A_MOTION_ARCHIVE} (a single array, not an archive)", path)
    try:
        with z:
            meta = json.loads(str(z["meta"]))
            if not isinstance(meta, dict) or meta.get("format") != FORMAT:
                got = meta.get("format") if isinstance(meta, dict) else meta
                raise FileFormatError(f"not a kinodyn motion archive (format {got!r})", path)
            sk = Skeleton(tuple(meta["names"]), z["parents"], z["offsets"], z["end_parents"], z["end_offsets"])
            tr = z["translations"] if "translations" in z.files else None
            return Motion(sk, z["root_pos"], z["local_rot"], meta["fps"], tr, meta.get("name", ""))
    except (KeyError, ValueError, TypeError, OSError, EOFError, zipfile.BadZipFile) as e:
        if isinstance(e, FileFormatError):
            raise
        raise FileFormatError(f"cannot read motion archive: {e}", path) from None
