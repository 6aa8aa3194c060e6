"""Array-form quaternion and vector kernels for compiled (numba) loops.

The ``(4,)`` / ``(3,)`` array counterparts of the scalar kernels of :mod:`kinodyn.math.kernels`: the
reach-cone projection and CCD of :mod:`kinodyn.ik`, and contact's piece poses and impulses
(:mod:`kinodyn.contact`), keep their small quaternions and vectors in arrays, and these are the one
home of the algebra they share. Conventions of :mod:`kinodyn.math.quat`: quaternions ``(w, x, y, z)``,
``R(q) v`` the rotation of a column vector. Each returns a new array.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["cross3", "qaxis", "qbetween", "qmat", "qmul", "qrot"]


@numba.njit(cache=True)
def qmul(a, b):  # pragma: no cover - compiled
    """Quaternion product ``a * b`` of ``(4,)`` arrays."""
    out = np.empty(4)
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]
    return out


@numba.njit(cache=True)
def cross3(a, b):  # pragma: no cover - compiled
    """Cross product of two ``(3,)`` vectors (cheaper than ``np.cross`` for one pair)."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@numba.njit(cache=True)
def qmat(q):  # pragma: no cover - compiled
    """``(3, 3)`` rotation matrix of unit quaternion ``q (4,)``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    r = np.empty((3, 3))
    r[0, 0] = 1 - 2 * (y * y + z * z)
    r[0, 1] = 2 * (x * y - w * z)
    r[0, 2] = 2 * (x * z + w * y)
    r[1, 0] = 2 * (x * y + w * z)
    r[1, 1] = 1 - 2 * (x * x + z * z)
    r[1, 2] = 2 * (y * z - w * x)
    r[2, 0] = 2 * (x * z - w * y)
    r[2, 1] = 2 * (y * z + w * x)
    r[2, 2] = 1 - 2 * (x * x + y * y)
    return r


@numba.njit(cache=True)
def qrot(q, v):  # pragma: no cover - compiled
    """Rotate ``v (3,)`` by unit quaternion ``q (4,)``."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    out = np.empty(3)
    out[0] = v[0] + w * tx + (y * tz - z * ty)
    out[1] = v[1] + w * ty + (z * tx - x * tz)
    out[2] = v[2] + w * tz + (x * ty - y * tx)
    return out


@numba.njit(cache=True)
def qaxis(axis, angle):  # pragma: no cover - compiled
    """Rotation by ``angle`` about unit ``axis (3,)``."""
    s = np.sin(0.5 * angle)
    out = np.empty(4)
    out[0] = np.cos(0.5 * angle)
    out[1] = axis[0] * s
    out[2] = axis[1] * s
    out[3] = axis[2] * s
    return out


@numba.njit(cache=True)
def qbetween(u, v):  # pragma: no cover - compiled
    """Shortest-arc rotation from unit ``u (3,)`` to unit ``v (3,)`` (``u`` and ``v`` not opposite)."""
    c = u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
    out = np.empty(4)
    out[0] = 1.0 + c
    out[1] = u[1] * v[2] - u[2] * v[1]
    out[2] = u[2] * v[0] - u[0] * v[2]
    out[3] = u[0] * v[1] - u[1] * v[0]
    n = np.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2 + out[3] ** 2)
    if n < 1e-12:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return out / n
