"""Scalar quaternion and vector kernels for compiled (numba) loops.

The one set of scalar helpers that kinodyn's numba kernels use (the leg IK of the foot lock, the
support constraints), so that no kernel writes the quaternion algebra out again. Forward kinematics
(:mod:`kinodyn.kinematics`) is the one exception: its link is written once for numpy and numba alike,
so that small motions are posed without importing numba. They take and return plain floats (tuples), are inlined into their callers and follow the
conventions of :mod:`kinodyn.math.quat`: quaternions ``(w, x, y, z)``, ``R(q) v`` the rotation of a
column vector. The array versions (numpy, batch-first) are in :mod:`kinodyn.math.quat`; compiled kernels
that keep one quaternion in a ``(4,)`` array use :mod:`kinodyn.math.array_kernels`.

Each kernel keeps the exact operation order its callers had, so compiled results do not change by
a rounding.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["acos_clipped", "axis_angle", "qmul", "qrot", "qrot_add", "qrot_inv", "unit"]


@numba.njit(cache=True, inline="always")
def qmul(a0, a1, a2, a3, b0, b1, b2, b3):  # pragma: no cover - compiled
    """Hamilton product ``a * b`` of two quaternions given by their components."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1, a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@numba.njit(cache=True, inline="always")
def qrot(w, x, y, z, vx, vy, vz):  # pragma: no cover - compiled
    """``R(q) v`` for a unit quaternion ``q = (w, x, y, z)``: ``v + 2w (u x v) + u x 2(u x v)``."""
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz), vz + w * tz + (x * ty - y * tx))


@numba.njit(cache=True, inline="always")
def qrot_add(px, py, pz, w, x, y, z, vx, vy, vz):  # pragma: no cover - compiled
    """``p + R(q) v``, summed left to right (``p + v + 2w (u x v) + ...``) as forward kinematics does."""
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (px + vx + w * tx + (y * tz - z * ty), py + vy + w * ty + (z * tx - x * tz),
            pz + vz + w * tz + (x * ty - y * tx))


@numba.njit(cache=True, inline="always")
def qrot_inv(q0, q1, q2, q3, x, y, z):  # pragma: no cover - compiled
    """``R(q)^T v`` for a unit quaternion: the rotation by ``q``'s conjugate."""
    u1, u2, u3 = -q1, -q2, -q3
    t1 = 2.0 * (u2 * z - u3 * y)
    t2 = 2.0 * (u3 * x - u1 * z)
    t3 = 2.0 * (u1 * y - u2 * x)
    return (x + q0 * t1 + (u2 * t3 - u3 * t2), y + q0 * t2 + (u3 * t1 - u1 * t3),
            z + q0 * t3 + (u1 * t2 - u2 * t1))


@numba.njit(cache=True, inline="always")
def axis_angle(x, y, z, ang):  # pragma: no cover - compiled
    """Quaternion of a rotation by ``ang`` radians about the axis ``(x, y, z)`` (any length; the
    identity when it is shorter than 1e-12)."""
    n = np.sqrt(x * x + y * y + z * z)
    if n < 1e-12:
        return 1.0, 0.0, 0.0, 0.0
    s = np.sin(0.5 * ang) / n
    return np.cos(0.5 * ang), x * s, y * s, z * s


@numba.njit(cache=True, inline="always")
def unit(x, y, z):  # pragma: no cover - compiled
    """``(x, y, z) / n`` and ``n``, the vector's length (the vector unchanged when ``n < 1e-9``)."""
    n = np.sqrt(x * x + y * y + z * z)
    if n < 1e-9:
        return x, y, z, n
    return x / n, y / n, z / n, n


@numba.njit(cache=True, inline="always")
def acos_clipped(x):  # pragma: no cover - compiled
    """``arccos`` of ``x`` clipped to ``[-1, 1]``."""
    return np.arccos(min(1.0, max(-1.0, x)))
