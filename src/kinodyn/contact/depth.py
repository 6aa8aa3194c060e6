"""Global penetration depth of two non-convex objects from their convex pairs (equation 1, Algorithm 1).

Schmidl and Lin, "Estimating the global penetration depth": for two overlapping objects with convex
pairs of depth ``pd_i`` and normal ``n_i`` (out of B into A),

    PD_g = sum(pd_i^2 n_i) / |sum(pd_i)|                                      (1)

translating A by ``PD_g`` (or A by ``PD_g / 2`` and B by ``-PD_g / 2``) removes the overlap, exactly for
one convex pair and approximately, then iteratively, for several. When the normals cancel (figure 4b,
an object wedged between two faces) ``PD_g`` is short although the pieces overlap deeply; Algorithm 1
then interpolates between the last non-overlapping state and the current one (:func:`interpolate_back`),
moving the object back toward where it came from until the overlap is gone.

Shapes: ``P`` convex pairs; vectors ``(3,)`` in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinodyn.contact.collide import Contacts
from kinodyn.errors import ParameterError

__all__ = ["CANCEL_RATIO", "GlobalDepth", "global_depth", "interpolate_back", "pair_depths"]

#: ``|PD_g| / max(pd_i)`` below which the normals count as cancelling (figure 4b) and Algorithm 1's
#: interpolation is used instead of translation.
CANCEL_RATIO = 0.25


@dataclass(frozen=True)
class GlobalDepth:
    """Global penetration depth of one object pair.

    Attributes:
        vector: ``(3,)`` ``PD_g`` of equation 1 (translate A by it to leave B).
        depth: ``|PD_g|`` (m).
        max_depth: deepest convex pair (m).
        count: number of overlapping convex pairs.
        cancelling: True when the normals cancel (``depth < CANCEL_RATIO * max_depth``, figure 4b).
        point: ``(3,)`` mean of the pairs' contact points (equation 2's end effector).
    """

    vector: np.ndarray
    depth: float
    max_depth: float
    count: int
    cancelling: bool
    point: np.ndarray


def global_depth(depth, normal, point=None, cancel_ratio: float = CANCEL_RATIO) -> GlobalDepth:
    """Equation 1 on convex pairs ``depth (P,)``, ``normal (P, 3)`` (out of B into A), ``point (P, 3)``."""
    d = np.asarray(depth, dtype=np.float64).reshape(-1)
    n = np.asarray(normal, dtype=np.float64).reshape(-1, 3)
    if len(d) != len(n):
        raise ParameterError(f"depth and normal must have the same length, got {len(d)} and {len(n)}")
    p = np.zeros((len(d), 3)) if point is None else np.asarray(point, dtype=np.float64).reshape(-1, 3)
    if len(d) == 0:
        return GlobalDepth(np.zeros(3), 0.0, 0.0, 0, False, np.zeros(3))
    total = abs(d.sum())
    v = (d[:, None] ** 2 * n).sum(axis=0) / max(total, 1e-300)
    ln = float(np.linalg.norm(v))
    dmax = float(d.max())
    return GlobalDepth(v, ln, dmax, len(d), bool(ln < cancel_ratio * dmax), p.mean(axis=0))


def pair_depths(contacts: Contacts, cancel_ratio: float = CANCEL_RATIO) -> dict[tuple[int, int], GlobalDepth]:
    """:func:`global_depth` of every overlapping object pair ``(a, b)`` in ``contacts``."""
    out = {}
    if not len(contacts):
        return out
    key = contacts.object_a * (1 << 32) + contacts.object_b
    uniq, inv = np.unique(key, return_inverse=True)
    for u, k in enumerate(uniq.tolist()):
        rows = inv == u
        out[(k >> 32, k & 0xFFFFFFFF)] = global_depth(contacts.depth[rows], contacts.normal[rows],
                                                      contacts.point[rows], cancel_ratio)
    return out


def interpolate_back(overlaps, start: float = 0.0, stop: float = 1.0, iterations: int = 20,
                     tolerance: float = 0.0) -> float:
    """Algorithm 1, step 4: the largest ``t`` in ``[start, stop]`` whose state does not overlap, where
    ``t = 0`` is the last cached non-overlapping state and ``t = 1`` the current (overlapping) one, by
    bisection on ``overlaps(t) -> deepest overlap (m)`` (overlap at most ``tolerance`` counts as none).

    The result moves the object back along its own path, so it never jumps: it lies between where the
    object was and where it is asked to be.
    """
    lo, hi = float(start), float(stop)
    if overlaps(hi) <= tolerance:
        return hi
    for _ in range(int(iterations)):
        mid = 0.5 * (lo + hi)
        if overlaps(mid) <= tolerance:
            lo = mid
        else:
            hi = mid
    return lo
