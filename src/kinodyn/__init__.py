"""kinodyn: physically interactive character animation.

Characters driven by motion data feel impacts and contacts through physics, react believably and
return to the data. The public API of the foundation is re-exported here; capability packages
(``kinodyn.physics``, ``kinodyn.blend``, ...) are imported on demand.

Conventions: Z up, metres, seconds, radians; rotations are unit quaternions ``(w, x, y, z)``.
"""

from kinodyn.errors import KinodynError
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton
from kinodyn.version import __version__

__all__ = ["Skeleton", "Motion", "KinodynError", "load", "save", "__version__"]


def load(path, **kwargs) -> Motion:
    """Read a motion file (``.bvh``, ``.amc`` with its ``.asf``, ``.npz``) into a :class:`Motion`."""
    from kinodyn.io import load as _load

    return _load(path, **kwargs)


def save(path, motion: Motion, **kwargs) -> None:
    """Write a motion (``.bvh`` or ``.npz``, chosen by the file ending), atomically."""
    from kinodyn.io import save as _save

    _save(path, motion, **kwargs)
