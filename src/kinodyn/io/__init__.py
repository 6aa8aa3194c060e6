"""Reading and writing motion files: BVH, CMU ASF/AMC, kinodyn ``.npz``; all output is atomic."""

from __future__ import annotations

from pathlib import Path

from kinodyn.errors import FileFormatError
from kinodyn.io.tpose import drop_added_tpose, has_added_tpose, skip_added_tpose
from kinodyn.motion import Motion

__all__ = ["load", "save", "has_added_tpose", "drop_added_tpose", "skip_added_tpose"]


def load(path, **kwargs) -> Motion:
    """Read a motion by file ending: ``.bvh``, ``.amc`` (skeleton from ``asf=`` or a ``.asf`` beside it),
    ``.npz``. Keyword arguments go to the format's reader."""
    p = Path(path)
    ext = p.suffix.lower()
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    if ext == ".bvh":
        from kinodyn.io.bvh import read_bvh

        return read_bvh(p, **kwargs)
    if ext == ".amc":
        from kinodyn.io.amc import read_amc

        return read_amc(p, **kwargs)
    if ext == ".npz":
        from kinodyn.io.npz import load_npz

        return load_npz(p)
    raise FileFormatError(f"unknown motion file type {ext!r} (expected .bvh, .amc or .npz)", p)


def save(path, motion: Motion, **kwargs) -> None:
    """Write a motion by file ending: ``.bvh`` or ``.npz``."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext == ".bvh":
        from kinodyn.io.bvh import write_bvh

        write_bvh(p, motion, **kwargs)
    elif ext == ".npz":
        from kinodyn.io.npz import save_npz

        save_npz(p, motion)
    else:
        raise FileFormatError(f"cannot write motion files of type {ext!r} (expected .bvh or .npz)", p)
