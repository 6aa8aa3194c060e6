"""Ground transforms: a position on the floor plus a heading about the up (+Z) axis.

A ground transform is either a triple ``(x, y, heading)`` in the last axis of an array ``(..., 3)`` or
the equivalent homogeneous matrix ``(..., 3, 3)`` acting on column vectors ``(x, y, 1)``. Every
capability that places a character on the floor (root alignment, facing frames, scene layout, crowds)
uses these functions, so there is one definition of "where a character stands and where it faces".
Angles are radians; headings are wrapped to ``[-pi, pi)``.
"""

from __future__ import annotations

import numpy as np

from kinodyn.math import quat

__all__ = [
    "wrap_angle", "to_matrix", "from_matrix", "compose", "inverse", "relative", "apply", "apply_vector",
    "from_root", "to_quat_pos",
]


def wrap_angle(a) -> np.ndarray:
    """Angles wrapped to ``[-pi, pi)``."""
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi


def to_matrix(g) -> np.ndarray:
    """Homogeneous matrices ``(..., 3, 3)`` from triples ``(..., 3)``."""
    g = np.asarray(g, dtype=np.float64)
    c, s = np.cos(g[..., 2]), np.sin(g[..., 2])
    m = np.zeros(g.shape[:-1] + (3, 3))
    m[..., 0, 0], m[..., 0, 1], m[..., 0, 2] = c, -s, g[..., 0]
    m[..., 1, 0], m[..., 1, 1], m[..., 1, 2] = s, c, g[..., 1]
    m[..., 2, 2] = 1.0
    return m


def from_matrix(m) -> np.ndarray:
    """Triples ``(..., 3)`` from homogeneous matrices ``(..., 3, 3)``."""
    m = np.asarray(m, dtype=np.float64)
    return np.stack([m[..., 0, 2], m[..., 1, 2], np.arctan2(m[..., 1, 0], m[..., 0, 0])], axis=-1)


def compose(a, b) -> np.ndarray:
    """``a`` then ``b`` expressed in ``a``'s frame: the triple of ``to_matrix(a) @ to_matrix(b)``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack(
        [a[..., 0] + c * b[..., 0] - s * b[..., 1], a[..., 1] + s * b[..., 0] + c * b[..., 1],
         wrap_angle(a[..., 2] + b[..., 2])],
        axis=-1,
    )


def inverse(g) -> np.ndarray:
    """Inverse ground transforms ``(..., 3)``."""
    g = np.asarray(g, dtype=np.float64)
    c, s = np.cos(g[..., 2]), np.sin(g[..., 2])
    return np.stack([-(c * g[..., 0] + s * g[..., 1]), s * g[..., 0] - c * g[..., 1], wrap_angle(-g[..., 2])],
                    axis=-1)


def relative(a, b) -> np.ndarray:
    """``b`` seen from ``a``: ``compose(inverse(a), b)``."""
    return compose(inverse(a), b)


def apply(g, p) -> np.ndarray:
    """Transform points ``(..., 2)`` or ``(..., 3)`` (z kept) by ground transforms ``(..., 3)``."""
    g = np.asarray(g, dtype=np.float64)
    p = np.asarray(p, dtype=np.float64)
    out = apply_vector(g, p)
    out[..., 0] += g[..., 0]
    out[..., 1] += g[..., 1]
    return out


def apply_vector(g, v) -> np.ndarray:
    """Rotate vectors ``(..., 2)`` or ``(..., 3)`` by the heading of ``g`` (no translation)."""
    g = np.asarray(g, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    c, s = np.cos(g[..., 2]), np.sin(g[..., 2])
    out = np.array(v, dtype=np.float64, copy=True) * np.ones(np.broadcast_shapes(g.shape[:-1], v.shape[:-1]) + (1,))
    out[..., 0] = c * v[..., 0] - s * v[..., 1]
    out[..., 1] = s * v[..., 0] + c * v[..., 1]
    return out


def from_root(root_pos, root_rot, forward=None) -> np.ndarray:
    """Ground transforms ``(..., 3)`` of a character root: floor position and heading.

    Args:
        root_pos: ``(..., 3)`` root positions.
        root_rot: ``(..., 4)`` root rotations.
        forward: optional local forward axis for :func:`kinodyn.math.quat.heading`.
    """
    root_pos = np.asarray(root_pos, dtype=np.float64)
    h = quat.heading(root_rot, forward)
    return np.stack([root_pos[..., 0], root_pos[..., 1], wrap_angle(h)], axis=-1)


def to_quat_pos(g) -> tuple[np.ndarray, np.ndarray]:
    """Rotation about +Z ``(..., 4)`` and floor position ``(..., 3)`` (z = 0) of ground transforms."""
    g = np.asarray(g, dtype=np.float64)
    pos = np.zeros(g.shape[:-1] + (3,))
    pos[..., :2] = g[..., :2]
    return quat.from_heading(g[..., 2]), pos
