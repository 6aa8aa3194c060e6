"""Math used everywhere: quaternions (``quat``), ground transforms (``xform``), interpolation (``interp``)."""

from kinodyn.math import interp, quat, xform

__all__ = ["quat", "xform", "interp"]
