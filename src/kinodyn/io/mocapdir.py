"""Where kinodyn finds a folder of motion capture that is not part of the package.

Benchmarks, the real-clip blending scripts and the scenes that play captured motion read files from one
folder laid out like the CMU set (``locomotion/``, ``reactions/``...). It is looked up in this order:
the folder the caller names, ``$KINODYN_MOCAP``, then ``shared/mocap`` beside the repository checkout
(for a source checkout) or beside the working directory.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["ENV", "find"]

#: the environment variable naming the motion-capture folder
ENV = "KINODYN_MOCAP"


def find(folder: str | os.PathLike | None = None) -> Path | None:
    """The motion-capture folder, or None when there is none.

    Args:
        folder: a folder the caller names; when given it is the only candidate.

    Returns:
        The folder (resolved) when it exists: ``folder``, else ``$KINODYN_MOCAP``, else ``shared/mocap``
        beside the checkout (``src/kinodyn/io`` three levels up) or beside the working directory. A named
        folder or variable that is not a folder gives None, never a guess elsewhere.
    """
    if folder is None and os.environ.get(ENV):
        folder = os.environ[ENV]
    if folder is not None:
        path = Path(folder).expanduser()
        return path.resolve() if path.is_dir() else None
    here = Path(__file__).resolve()
    candidates = [Path.cwd().parent / "shared" / "mocap"]
    if len(here.parents) > 4:
        candidates.insert(0, here.parents[4] / "shared" / "mocap")
    return next((c.resolve() for c in candidates if c.is_dir()), None)
