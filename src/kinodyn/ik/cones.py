"""Compiled joint-limit projections for CCD: hinge ranges, reach cones with twist limits.

Wilhelms and Van Gelder, "Fast and easy reach-cone joint limits" (2001), as used by Schmidl and Lin
("joints that are a collection of planar joint components use reach cones ... and a projection of a
limb that has left a reach cone back to the nearest location inside of the reach cone"). The cone of
a ball joint bounds the direction ``d = R(q) d0`` of its bone (``d0`` the rest direction, in the
parent's frame). It is a polygon in the azimuthal equidistant chart around the cone's centre ``c``
(chart point ``theta (cos phi, sin phi)`` with ``theta`` the angle from ``c`` and ``phi`` the azimuth
from the chart's x axis, forward), star-shaped about the origin, so cones wider than a hemisphere (the
shoulder) work. A direction outside is moved to the nearest point of the polygon in that chart. The
twist about ``d0`` is then limited so that the whole rotation stays within the joint's ``max_angle``
(``cos(angle/2) = cos(swing/2) cos(twist/2)``), so :func:`kinodyn.limits.violations` agrees.

The cones are anatomical (:func:`reach_cones`): the shoulder's, hip's and neck's are centred on the
bone's neutral direction (upper arm and thigh hanging down, neck up) with radii per anatomical
direction (forward, out, back, in), whatever the skeleton's rest pose. For the built-in skeleton
(arms down) the centre is the rest direction; for a T-pose skeleton (CMU) the rest direction of the
upper arm lies 90 degrees out from the centre, inside the cone, so the same arm motion meets the same
cone on both. Every vertex is also kept within ``max_angle`` of the rest direction, the range
:mod:`kinodyn.limits` measures from the rest pose.

The projections are numba-compiled scalar code for the CCD kernel. Rotations ``(w, x, y, z)``; cone
axes ``(4, 3)``: rest direction ``d0``, centre ``c``, chart x and chart y (toward the joint's side).
"""

from __future__ import annotations

import numba
import numpy as np

from kinodyn.math.array_kernels import qaxis, qbetween, qmul, qrot

__all__ = ["CONE_NEUTRAL", "CONE_SHAPES", "CONE_VERTICES", "KIND_BALL", "KIND_FIXED", "KIND_HINGE",
           "cone_boundary", "cone_contains", "project_joint", "reach_cones"]

KIND_BALL, KIND_HINGE, KIND_FIXED = 0, 1, 2

#: Number of vertices of every reach cone polygon.
CONE_VERTICES = 8
_DEG = np.pi / 180.0
#: Reach-cone radii (deg from the cone's centre) at the azimuths forward, forward-out, out, back-out,
#: back, back-in, in, forward-in, by joint type of :data:`kinodyn.limits.JOINT_TYPES`; each is capped so
#: that the vertex lies within that joint's ``max_angle`` of the rest direction. Types not listed get a
#: circle of ``max_angle`` about the rest direction.
CONE_SHAPES = {
    "upper_arm": (175, 175, 175, 90, 60, 40, 35, 120),
    "thigh": (120, 90, 60, 35, 30, 25, 25, 80),
    "neck": (55, 50, 45, 45, 45, 45, 45, 50),
    "head": (55, 50, 45, 45, 45, 45, 45, 50),
}
#: The neutral bone direction (the cone's centre, in the parent's rest frame: Z up, facing +X) of the
#: shaped cones: the upper arm and thigh hang down, the neck and head point up.
CONE_NEUTRAL = {"upper_arm": (0.0, 0.0, -1.0), "thigh": (0.0, 0.0, -1.0), "neck": (0.0, 0.0, 1.0),
                "head": (0.0, 0.0, 1.0)}
_FORWARD = np.array([1.0, 0.0, 0.0])


@numba.njit(cache=True)
def _chart(d, axes):  # pragma: no cover - compiled
    """Chart point ``(2,)`` of unit direction ``d`` for cone axes ``(4, 3)`` (rest, centre, x, y)."""
    c = min(1.0, max(-1.0, d[0] * axes[1, 0] + d[1] * axes[1, 1] + d[2] * axes[1, 2]))
    theta = np.arccos(c)
    x = d[0] * axes[2, 0] + d[1] * axes[2, 1] + d[2] * axes[2, 2]
    y = d[0] * axes[3, 0] + d[1] * axes[3, 1] + d[2] * axes[3, 2]
    r = np.sqrt(x * x + y * y)
    p = np.zeros(2)
    if r > 1e-12:
        p[0] = theta * x / r
        p[1] = theta * y / r
    return p


@numba.njit(cache=True)
def _unchart(p, axes):  # pragma: no cover - compiled
    theta = np.sqrt(p[0] ** 2 + p[1] ** 2)
    d = np.cos(theta) * axes[1]
    if theta > 1e-12:
        d = d + np.sin(theta) * (p[0] / theta * axes[2] + p[1] / theta * axes[3])
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
    (``kind`` 0): bone direction into the reach cone (``axes (4, 3)``, ``poly (K, 2)``), then the twist
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


def cone_boundary(tname: str, max_angle: float) -> np.ndarray:
    """Radii ``(K,)`` (rad) of the reach cone of a joint type about its centre, capped at ``max_angle``
    (the cap that holds when the centre is the rest direction)."""
    deg = np.array(CONE_SHAPES.get(tname, (max_angle / _DEG,) * CONE_VERTICES), dtype=np.float64)
    return np.minimum(deg * _DEG, max_angle * 0.999)


def _chart_axes(c: np.ndarray, left: bool) -> tuple[np.ndarray, np.ndarray]:
    """Chart x (forward, or up for a bone along the facing direction) and y (toward the joint's side:
    +Y on the left) perpendicular to the centre ``c``."""
    e1 = _FORWARD - (_FORWARD @ c) * c
    if np.linalg.norm(e1) < 0.3:  # bone along the facing direction (feet): chart x is up
        e1 = np.array([0.0, 0.0, 1.0]) - c[2] * c
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(c, e1)
    e2 *= np.sign(e2[1] * (1.0 if left else -1.0)) or 1.0
    return e1, e2


def _within_rest(c, e1, e2, d0, radii, max_angle: float, samples: int = 64) -> np.ndarray:
    """Radii ``(K,)`` shortened so that the arc from ``c`` to each vertex stays within ``max_angle`` (with
    the margin of :func:`cone_boundary`) of the rest direction ``d0``."""
    az = np.arange(len(radii)) * 2.0 * np.pi / len(radii)
    out = np.array(radii, dtype=np.float64)
    for k, (a, r) in enumerate(zip(az, radii)):
        t = np.linspace(0.0, r, samples + 1)
        dirs = np.cos(t)[:, None] * c + np.sin(t)[:, None] * (np.cos(a) * e1 + np.sin(a) * e2)
        bad = np.nonzero(dirs @ d0 < np.cos(max_angle * 0.999))[0]
        if len(bad):
            out[k] = t[max(bad[0] - 1, 0)]
    return out


def _cone(tname: str, max_angle: float, d0: np.ndarray, left: bool) -> tuple[np.ndarray, np.ndarray]:
    """Axes ``(4, 3)`` and polygon ``(K, 2)`` of one joint's reach cone (see the module docstring)."""
    r = cone_boundary(tname, max_angle)
    az = np.arange(CONE_VERTICES) * 2.0 * np.pi / CONE_VERTICES
    c = d0
    n = np.asarray(CONE_NEUTRAL.get(tname, d0), dtype=np.float64)
    off = np.arccos(np.clip(n @ d0, -1.0, 1.0))  # the rest direction's angle from the neutral one
    if 1e-6 < off < 0.9 * max_angle:
        e1, e2 = _chart_axes(n, left)
        shaped = np.deg2rad(np.array(CONE_SHAPES[tname], dtype=np.float64))
        poly = np.stack([shaped * np.cos(az), shaped * np.sin(az)], axis=1)
        if _inside(_chart(d0, np.stack([d0, n, e1, e2])), poly):  # else: a rest pose outside the cone
            c, r = n, _within_rest(n, e1, e2, d0, shaped, max_angle)
    e1, e2 = _chart_axes(c, left)
    return np.stack([d0, c, e1, e2]), np.stack([r * np.cos(az), r * np.sin(az)], axis=1)


def reach_cones(skeleton, limits) -> tuple[np.ndarray, np.ndarray]:
    """Reach cones of every joint of ``skeleton`` with ``limits`` (:func:`kinodyn.limits.limits_for`).

    Returns:
        axes ``(J, 4, 3)`` (rest bone direction, centre, chart x, chart y) and polygons ``(J, K, 2)``
        in the azimuthal chart (rad). Hinges get a circle of 180 degrees (their limits are the range).
    """
    from kinodyn.limits import bone_direction

    rest = skeleton.rest_positions()
    axes = np.zeros((skeleton.num_joints, 4, 3))
    pts = np.zeros((skeleton.num_joints, CONE_VERTICES, 2))
    for j, lim in enumerate(limits):
        max_angle = lim.max_angle if lim.kind in ("ball", "fixed") else np.pi
        axes[j], pts[j] = _cone(lim.name, max_angle, bone_direction(skeleton, j), bool(rest[j, 1] >= -1e-9))
    return axes, pts
