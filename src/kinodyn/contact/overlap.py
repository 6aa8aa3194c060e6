"""Geometric overlap removal by translation, with the paper's priorities.

Schmidl and Lin, "Geometric and kinematic overlap avoidance": overlapping objects are pushed apart by
their global penetration depth (equation 1). A fixed object never moves; when a driven or simulated
object overlaps a fixed one only the former is displaced; when a driven and a simulated object overlap,
the driven one gives way first, and only if that does not remove the overlap (after half the iteration
budget) the simulated one moves too. Two simulated objects share the displacement. When the normals of
a pair cancel (figure 4b), the object is moved back along its path toward its last non-overlapping
position instead (Algorithm 1, step 4).

The world (:class:`~kinodyn.contact.collide.CollisionWorld`) is mutable; these functions move its
objects in place and say so. Metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinodyn.contact.collide import CollisionWorld
from kinodyn.contact.depth import interpolate_back, pair_depths

__all__ = ["PRIORITY", "OverlapConfig", "OverlapResult", "deepest", "remove_overlap"]

#: Who gives way first: lower moves first; fixed objects never move.
PRIORITY = {"driven": 0, "simulated": 1, "fixed": 2}


@dataclass(frozen=True)
class OverlapConfig:
    """Overlap removal settings.

    Attributes:
        tolerance: residual overlap that counts as none (m).
        max_iterations: translation rounds before giving up.
        skin: extra distance added to each push so that objects end just apart (m).
    """

    tolerance: float = 1e-4
    max_iterations: int = 12
    skin: float = 1e-5


@dataclass(frozen=True)
class OverlapResult:
    """What :func:`remove_overlap` did.

    Attributes:
        displacement: ``(K, 3)`` translation applied to each movable object.
        iterations: translation rounds used.
        fallback: names of the objects moved back by interpolation (Algorithm 1, step 4).
        residual: deepest overlap left (m).
        pairs: overlapping object pairs found in the first round.
    """

    displacement: np.ndarray
    iterations: int
    fallback: tuple[str, ...]
    residual: float
    pairs: int


def deepest(world: CollisionWorld, objects) -> float:
    """Deepest overlap (m) of ``objects`` with anything they may collide with (0 when none)."""
    c = world.contacts(objects)
    return float(c.depth.max()) if len(c) else 0.0


def _moves(world, a, b, it, cfg):
    """Share of the displacement for ``a`` and ``b`` (pair normal out of b into a)."""
    ka, kb = world.objects[a].kind, world.objects[b].kind
    pa, pb = PRIORITY[ka], PRIORITY[kb]
    if kb == "fixed":
        return 1.0, 0.0
    if ka == "fixed":
        return 0.0, 1.0
    if pa == pb:
        return 0.5, 0.5
    late = it >= cfg.max_iterations // 2  # the driven object alone could not clear the overlap
    if pa < pb:
        return (0.5, 0.5) if late else (1.0, 0.0)
    return (0.5, 0.5) if late else (0.0, 1.0)


def remove_overlap(world: CollisionWorld, movable, last_free, config: OverlapConfig | None = None) -> OverlapResult:
    """Translate the ``movable (K,)`` objects of ``world`` out of overlap, in place.

    Args:
        world: the collision world (object poses are changed).
        movable: indices of the objects that may move (driven and simulated rigid objects).
        last_free: ``(K, 3)`` last positions at which each was free of overlap (for the fallback).
    """
    cfg = config or OverlapConfig()
    movable = np.asarray(movable, dtype=np.int64)
    start = world.pos[movable].copy()
    index = {int(k): i for i, k in enumerate(movable)}
    fallback, first_pairs, it = [], 0, 0
    for it in range(1, cfg.max_iterations + 1):
        depths = pair_depths(world.contacts(movable))
        depths = {k: g for k, g in depths.items() if g.max_depth > cfg.tolerance}
        first_pairs = first_pairs or len(depths)
        if not depths:
            break
        push = np.zeros((len(movable), 3))
        for (a, b), g in depths.items():
            if g.cancelling:
                k = a if a in index else b
                if world.objects[k].name not in fallback:
                    _interpolate(world, k, last_free[index[k]], cfg)
                    fallback.append(world.objects[k].name)
                continue
            sa, sb = _moves(world, a, b, it, cfg)
            step = g.vector * (1.0 + cfg.skin / max(g.depth, 1e-12))
            if sa and a in index:
                push[index[a]] += sa * step
            if sb and b in index:
                push[index[b]] -= sb * step
        moved = np.nonzero(np.any(push != 0.0, axis=1))[0]
        if len(moved):
            world.set_poses(movable[moved], world.pos[movable[moved]] + push[moved], world.quat[movable[moved]])
        elif not fallback:
            break
    residual = deepest(world, movable) if len(movable) else 0.0
    return OverlapResult(world.pos[movable] - start, it, tuple(fallback), residual, first_pairs)


def _interpolate(world: CollisionWorld, k: int, free_pos, cfg: OverlapConfig) -> None:
    """Move object ``k`` back along the segment from ``free_pos`` to its current position until free."""
    cur = world.pos[k].copy()
    q = world.quat[k].copy()

    def overlap(t):
        world.set_poses([k], free_pos + t * (cur - free_pos), q)
        return deepest(world, [k])

    t = interpolate_back(overlap, tolerance=cfg.tolerance)
    world.set_poses([k], free_pos + t * (cur - free_pos), q)
