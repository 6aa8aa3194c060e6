"""Small array helpers shared by the frozen data types."""

from __future__ import annotations

import numpy as np

__all__ = ["median", "percentile", "readonly"]


def readonly(a, dtype=np.float64) -> np.ndarray:
    """A read-only copy of ``a`` as ``dtype`` (frozen dataclasses hold these, as dm_control does)."""
    a = np.array(a, dtype=dtype, copy=True)
    a.setflags(write=False)
    return a


def percentile(x, q: float) -> float:
    """``np.percentile(x, q)`` (linear interpolation) of a 1-D array, without importing ``numpy.ma``
    (which ``np.percentile`` and ``np.median`` do, a tenth of numpy's import time)."""
    x = np.sort(np.asarray(x, dtype=np.float64).ravel())
    if x.size == 0:
        return float("nan")
    pos = q / 100.0 * (x.size - 1)
    lo = int(np.floor(pos))
    hi = min(lo + 1, x.size - 1)
    t = pos - lo
    a, b = x[lo], x[hi]
    return float(b - (b - a) * (1.0 - t) if t >= 0.5 else a + (b - a) * t)  # numpy's lerp


def median(x) -> float:
    """``np.median(x)`` of a 1-D array, without importing ``numpy.ma``."""
    x = np.sort(np.asarray(x, dtype=np.float64).ravel())
    n = x.size
    if n == 0:
        return float("nan")
    return float(x[n // 2]) if n % 2 else float(np.mean(x[n // 2 - 1: n // 2 + 1]))
