"""Interpolation of sampled signals: linear / slerp resampling and Catmull-Rom (cubic Hermite) splines.

Times are seconds; samples are batch-first arrays whose first axis is time.
"""

from __future__ import annotations

import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.math import quat

__all__ = ["sample_indices", "lerp_frames", "slerp_frames", "catmull_rom"]


def sample_indices(n: int, src_fps: float, times) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bracketing frame indices ``i0, i1 (T,)`` and weights ``alpha (T,)`` for ``times (T,)`` seconds.

    Times outside ``[0, (n - 1) / src_fps]`` are clamped to the ends.
    """
    if n < 1:
        raise ParameterError(f"need at least one frame to sample, got {n}")
    f = np.clip(np.asarray(times, dtype=np.float64) * src_fps, 0.0, n - 1)
    i0 = np.floor(f).astype(np.int64)
    i0 = np.minimum(i0, n - 1)
    i1 = np.minimum(i0 + 1, n - 1)
    return i0, i1, f - i0


def lerp_frames(x, src_fps: float, times) -> np.ndarray:
    """Linearly interpolate ``x (F, ...)`` sampled at ``src_fps`` at ``times (T,)``; returns ``(T, ...)``."""
    x = np.asarray(x, dtype=np.float64)
    i0, i1, a = sample_indices(len(x), src_fps, times)
    a = a.reshape((-1,) + (1,) * (x.ndim - 1))
    return (1.0 - a) * x[i0] + a * x[i1]


def slerp_frames(q, src_fps: float, times) -> np.ndarray:
    """Slerp rotations ``q (F, ..., 4)`` sampled at ``src_fps`` at ``times (T,)``; returns ``(T, ..., 4)``."""
    q = np.asarray(q, dtype=np.float64)
    i0, i1, a = sample_indices(len(q), src_fps, times)
    a = a.reshape((-1,) + (1,) * (q.ndim - 2))
    return quat.slerp(q[i0], q[i1], a)


def catmull_rom(key_times, key_values, times, ends: str = "one-sided") -> np.ndarray:
    """Cardinal (Catmull-Rom) spline through keys, evaluated at ``times``.

    Args:
        key_times: strictly increasing ``(K,)`` seconds.
        key_values: ``(K, ...)`` values.
        times: ``(T,)`` seconds; clamped to the key range.
        ends: ``"one-sided"`` (tangent from the neighbouring key) or ``"zero"`` (ease in and out).

    Returns:
        ``(T, ...)``: C1-continuous interpolation; tangents are centred differences with one-sided
        differences at the ends (non-uniform knots handled by the standard finite-difference form).
    """
    kt = np.asarray(key_times, dtype=np.float64)
    kv = np.asarray(key_values, dtype=np.float64)
    if kt.ndim != 1 or len(kt) != len(kv):
        raise ParameterError(f"key_times must be (K,) matching key_values {kv.shape}, got {kt.shape}")
    if len(kt) == 1:
        return np.repeat(kv[:1], len(np.atleast_1d(times)), axis=0)
    if np.any(np.diff(kt) <= 0):
        raise ParameterError("key_times must be strictly increasing")
    t = np.clip(np.asarray(times, dtype=np.float64), kt[0], kt[-1])
    tang = np.empty_like(kv)
    tang[1:-1] = (kv[2:] - kv[:-2]) / (kt[2:] - kt[:-2]).reshape((-1,) + (1,) * (kv.ndim - 1))
    tang[0] = (kv[1] - kv[0]) / (kt[1] - kt[0])
    tang[-1] = (kv[-1] - kv[-2]) / (kt[-1] - kt[-2])
    if ends == "zero":
        tang[0] = 0.0
        tang[-1] = 0.0
    elif ends != "one-sided":
        raise ParameterError(f"ends must be 'one-sided' or 'zero', got {ends!r}")
    i = np.clip(np.searchsorted(kt, t, side="right") - 1, 0, len(kt) - 2)
    h = kt[i + 1] - kt[i]
    s = (t - kt[i]) / h
    shape = (-1,) + (1,) * (kv.ndim - 1)
    s = s.reshape(shape)
    h = h.reshape(shape)
    s2, s3 = s * s, s * s * s
    h00 = 2 * s3 - 3 * s2 + 1
    h10 = s3 - 2 * s2 + s
    h01 = -2 * s3 + 3 * s2
    h11 = s3 - s2
    return h00 * kv[i] + h10 * h * tang[i] + h01 * kv[i + 1] + h11 * h * tang[i + 1]
