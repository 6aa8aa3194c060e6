"""Compiled joint-limit projections for CCD: hinge ranges, reach cones with twist limits.

Wilhelms and Van Gelder, "Fast and easy reach-cone joint limits" (2001), as used by Schmidl and Lin
("joints that are a collection of planar joint components use reach cones ... and a projection of a
limb that has left a reach cone back to the nearest location inside of the reach cone"). The cone of
a ball joint bounds the direction ``d = R(q) d0`` of its bone (``d0`` the rest direction, in the
parent's frame). It is a polygon in the azimuthal equidistant chart around ``d0`` (chart point
``theta (cos phi, sin phi)`` with ``theta`` the angle from ``d0`` and ``phi`` the azimuth from the
chart's x axis), star-shaped about the origin, so cones wider than a hemisphere (the shoulder) work.
A direction outside is moved to the nearest point of the polygon in that chart. The twist about
``d0`` is then limited so that the whole rotation stays within the joint's ``max_angle``
(``cos(angle/2) = cos(swing/2) cos(twist/2)``), so :func:`kinodyn.limits.violations` agrees.

Everything here is numba-compiled scalar code for the CCD kernel. Rotations ``(w, x, y, z)``.
"""

from __future__ import annotations

import numba
import numpy as np

from kinodyn.math.array_kernels import qaxis, qbetween, qmul, qrot

__all__ = ["KIND_BALL", "KIND_FIXED", "KIND_HINGE", "cone_contains", "project_joint"]

KIND_BALL, KIND_HINGE, KIND_FIXED = 0, 1, 2


@numba.njit(cache=True)
def _chart(d, axes):  # pragma: no cover - compiled
    """Chart point ``(2,)`` of unit direction ``d`` for cone axes ``(3, 3)`` (rest, x, y)."""
    c = min(1.0, max(-1.0, d[0] * axes[0, 0] + d[1] * axes[0, 1] + d[2] * axes[0, 2]))
    theta = np.arccos(c)
    x = d[0] * axes[1, 0] + d[1] * axes[1, 1] + d[2] * axes[1, 2]
    y = d[0] * axes[2, 0] + d[1] * axes[2, 1] + d[2] * axes[2, 2]
    r = np.sqrt(x * x + y * y)
    p = np.zeros(2)
    if r > 1e-12:
        p[0] = theta * x / r
        p[1] = theta * y / r
    return p


@numba.njit(cache=True)
def _unchart(p, axes):  # pragma: no cover - compiled
    theta = np.sqrt(p[0] ** 2 + p[1] ** 2)
    d = np.cos(theta) * axes[0]
    if theta > 1e-12:
        d = d + np.sin(theta) * (p[0] / theta * axes[1] + p[1] / theta * axes[2])
    return d


@numba.njit(cache=True)
def _inside(p, poly):  # pragma: no cover - compiled
    """Point ``p (2,)`` inside the star-shaped polygon ``poly (K, 2)`` (star centre at the origin)."""
    k = poly.shape[0]
    for i in range(k):
        a, b = poly[i], poly[(i + 1) % k]
        # the wedge from the origin between a and b containing p
        ca = a[0] * p[1] - a[1] * p[0]
        cb = p[0] * b[1] - p[1] * b[0]
        if ca >= 0.0 and cb >= 0.0:
            # inside when p is on the origin's side of the edge a-b
            e = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
            return e >= -1e-12
    return True


@numba.njit(cache=True)
def _nearest_on_polygon(p, poly):  # pragma: no cover - compiled
    k = poly.shape[0]
    best = np.zeros(2)
    bd = 1e300
    for i in range(k):
        a, b = poly[i], poly[(i + 1) % k]
        ab0, ab1 = b[0] - a[0], b[1] - a[1]
        t = ((p[0] - a[0]) * ab0 + (p[1] - a[1]) * ab1) / max(ab0 * ab0 + ab1 * ab1, 1e-300)
        t = min(1.0, max(0.0, t))
        q0, q1 = a[0] + t * ab0, a[1] + t * ab1
        dd = (q0 - p[0]) ** 2 + (q1 - p[1]) ** 2
        if dd < bd:
            bd = dd
            best[0], best[1] = q0, q1
    return best * (1.0 - 1e-9)


@numba.njit(cache=True)
def cone_contains(q, axes, poly):  # pragma: no cover - compiled
    """True when the bone direction of rotation ``q (4,)`` lies in the reach cone ``axes, poly``."""
    return _inside(_chart(qrot(q, axes[0]), axes), poly)


# long kernel: one joint's whole projection (hinge, cone, twist) in one compiled pass
@numba.njit(cache=True)
def project_joint(q, kind, axis, lower, upper, max_angle, axes, poly):  # pragma: no cover - compiled
    """Project local rotation ``q (4,)`` into its joint's limits.

    Hinge (``kind`` 1): keep the rotation about ``axis (3,)``, clipped to ``[lower, upper]``. Ball
    (``kind`` 0): bone direction into the reach cone (``axes (3, 3)``, ``poly (K, 2)``), then the twist
    about the rest direction limited so that the total angle is at most ``max_angle``. Fixed (2): the
    rotation shortened to ``max_angle``.
    """
    if q[0] < 0.0:
        q = -q
    if kind == KIND_HINGE:
        s = q[1] * axis[0] + q[2] * axis[1] + q[3] * axis[2]
        theta = 2.0 * np.arctan2(s, q[0])
        return qaxis(axis, min(upper, max(lower, theta)))
    if kind == KIND_FIXED:
        ang = 2.0 * np.arccos(min(1.0, q[0]))
        if ang <= max_angle:
            return q
        n = np.sqrt(q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
        return qaxis(q[1:] / n, max_angle)
    d0 = axes[0]
    d = qrot(q, d0)
    swing = qbetween(d0, d)
    p = _chart(d, axes)
    if not _inside(p, poly):
        swing = qbetween(d0, _unchart(_nearest_on_polygon(p, poly), axes))
    # twist = swing^-1 q, about d0
    sc = swing.copy()
    sc[1:] = -sc[1:]
    tw = qmul(sc, q)
    tw_s = tw[1] * d0[0] + tw[2] * d0[1] + tw[3] * d0[2]
    beta = 2.0 * np.arctan2(tw_s, tw[0])
    if beta > np.pi:
        beta -= 2.0 * np.pi
    elif beta < -np.pi:
        beta += 2.0 * np.pi
    cos_half_swing = max(swing[0], 1e-12)
    bound = np.cos(0.5 * max_angle) / cos_half_swing
    bmax = 2.0 * np.arccos(min(1.0, bound)) * (1.0 - 1e-9) if bound < 1.0 else 0.0
    beta = min(bmax, max(-bmax, beta))
    return qmul(swing, qaxis(d0, beta))
