"""Small array helpers shared by the frozen data types."""

from __future__ import annotations

import numpy as np

__all__ = ["readonly"]


def readonly(a, dtype=np.float64) -> np.ndarray:
    """A read-only copy of ``a`` as ``dtype`` (frozen dataclasses hold these, as dm_control does)."""
    a = np.array(a, dtype=dtype, copy=True)
    a.setflags(write=False)
    return a
