"""The skeleton: joint names, a parents array and rest offsets, as read-only arrays.

Conventions: Z up, metres. ``parents[0] == -1`` and ``parents[j] < j`` for every other joint, so a
single forward loop over joints visits parents before children. ``offsets[j]`` is joint ``j``'s position
in its parent's frame in the rest pose (the root's offset is kept for file round trips; the root's
position in a motion comes from ``Motion.root_pos``). End sites (BVH ``End Site``: bone tips with no
rotation of their own) are kept apart in ``end_parents`` / ``end_offsets`` so the joint count matches
the file's joints.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from kinodyn._arrays import readonly
from kinodyn.errors import SkeletonError, UnknownNameError
from kinodyn.roles import mirror_name

__all__ = ["Skeleton", "mirror_name"]


@dataclass(frozen=True, eq=False)
class Skeleton:
    """An articulated skeleton.

    Attributes:
        names: ``J`` unique joint names.
        parents: ``(J,)`` int parent indices, ``-1`` for the root, ``parents[j] < j``.
        offsets: ``(J, 3)`` rest offsets in metres, in the parent's frame.
        end_parents: ``(E,)`` joint index of each end site.
        end_offsets: ``(E, 3)`` end-site offsets in the parent's frame.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    end_parents: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    end_offsets: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self):
        names = tuple(str(n) for n in self.names)
        object.__setattr__(self, "names", names)
        parents = np.asarray(self.parents)
        offsets = np.asarray(self.offsets, dtype=np.float64)
        j = len(names)
        if j == 0:
            raise SkeletonError("a skeleton needs at least one joint, got 0")
        if len(set(names)) != j:
            dup = sorted({n for n in names if names.count(n) > 1})
            raise SkeletonError(f"joint names must be unique, repeated: {', '.join(dup)}")
        if parents.shape != (j,) or not np.issubdtype(parents.dtype, np.integer):
            raise SkeletonError(f"parents must be an int array of shape ({j},), got {parents.dtype} {parents.shape}")
        if offsets.shape != (j, 3):
            raise SkeletonError(f"offsets must have shape ({j}, 3), got {offsets.shape}")
        if not np.all(np.isfinite(offsets)):
            raise SkeletonError("offsets must be finite, found NaN or inf")
        if parents[0] != -1:
            raise SkeletonError(f"parents[0] must be -1 (the root), got {parents[0]}")
        bad = np.nonzero((parents[1:] < 0) | (parents[1:] >= np.arange(1, j)))[0]
        if len(bad):
            k = int(bad[0]) + 1
            raise SkeletonError(
                f"parents[j] must satisfy 0 <= parents[j] < j for j > 0; joint {k} ({names[k]!r}) has {parents[k]}")
        ep = np.asarray(self.end_parents)
        eo = np.asarray(self.end_offsets, dtype=np.float64)
        if eo.size == 0:
            eo = eo.reshape(0, 3)
        if eo.ndim != 2 or eo.shape[1] != 3:
            raise SkeletonError(f"end_offsets must have shape (E, 3), got {eo.shape}")
        if not np.all(np.isfinite(eo)):
            raise SkeletonError("end_offsets must be finite, found NaN or inf")
        if ep.shape != (len(eo),) or (len(ep) and not np.issubdtype(ep.dtype, np.integer)):
            raise SkeletonError(
                f"end_parents must be an int array of shape ({len(eo)},), got {ep.dtype} {ep.shape}")
        if len(ep) and (ep.min() < 0 or ep.max() >= j):
            raise SkeletonError(f"end_parents must index joints 0..{j - 1}")
        object.__setattr__(self, "parents", readonly(parents, np.int64))
        object.__setattr__(self, "offsets", readonly(offsets, np.float64))
        object.__setattr__(self, "end_parents", readonly(ep, np.int64))
        object.__setattr__(self, "end_offsets", readonly(eo, np.float64))

    # ------------------------------------------------------------------ basics
    @property
    def num_joints(self) -> int:
        return len(self.names)

    def __len__(self) -> int:
        return len(self.names)

    def __repr__(self) -> str:
        return f"Skeleton({self.num_joints} joints, root={self.names[0]!r}, height={self.height():.2f} m)"

    def __eq__(self, other) -> bool:
        return isinstance(other, Skeleton) and self.same_topology(other) and np.allclose(
            self.offsets, other.offsets, atol=1e-9) and np.array_equal(self.end_parents, other.end_parents) \
            and np.allclose(self.end_offsets, other.end_offsets, atol=1e-9)

    __hash__ = object.__hash__

    def same_topology(self, other: "Skeleton") -> bool:
        """Same joint names in the same order with the same parents."""
        return self.names == other.names and np.array_equal(self.parents, other.parents)

    def index(self, name: str) -> int:
        """Index of joint ``name``; raises :class:`UnknownNameError` listing the joints."""
        try:
            return self.names.index(name)
        except ValueError:
            raise UnknownNameError(f"no joint named {name!r}; joints are: {', '.join(self.names)}") from None

    def indices(self, names) -> np.ndarray:
        return np.array([self.index(n) for n in names], dtype=np.int64)

    def find(self, *patterns: str) -> list[int]:
        """Indices of joints whose name matches any regex (case-insensitive), in joint order."""
        regs = [re.compile(p, re.IGNORECASE) for p in patterns]
        return [i for i, n in enumerate(self.names) if any(r.search(n) for r in regs)]

    def children(self, j: int) -> np.ndarray:
        return np.nonzero(self.parents == j)[0]

    def subtree(self, j: int) -> np.ndarray:
        """Joint ``j`` and all its descendants, in joint order."""
        mask = np.zeros(self.num_joints, dtype=bool)
        mask[j] = True
        for k in range(j + 1, self.num_joints):
            mask[k] = mask[self.parents[k]]
        return np.nonzero(mask)[0]

    def bone_lengths(self) -> np.ndarray:
        """``(J,)`` length of each joint's offset (the bone from its parent); the root's is 0."""
        out = np.linalg.norm(self.offsets, axis=1)
        out[0] = 0.0
        return out

    def rest_positions(self) -> np.ndarray:
        """``(J, 3)`` joint positions of the rest pose with the root at the origin."""
        pos = np.zeros((self.num_joints, 3))
        for j in range(1, self.num_joints):
            pos[j] = pos[self.parents[j]] + self.offsets[j]
        return pos

    def height(self) -> float:
        """Vertical extent (m) of the rest pose, joints and end sites together."""
        pos = self.rest_positions()
        if len(self.end_parents):
            pos = np.concatenate([pos, pos[self.end_parents] + self.end_offsets])
        return float(np.ptp(pos[:, 2]))

    def replace(self, **changes) -> "Skeleton":
        kw = dict(names=self.names, parents=self.parents, offsets=self.offsets, end_parents=self.end_parents,
                  end_offsets=self.end_offsets)
        kw.update(changes)
        return Skeleton(**kw)

    def scaled(self, s: float) -> "Skeleton":
        """All offsets multiplied by ``s`` (unit change)."""
        return self.replace(offsets=self.offsets * s, end_offsets=self.end_offsets * s)

    # ------------------------------------------------------------------ mirroring
    def mirror_map(self) -> np.ndarray:
        """``(J,)`` index of each joint's opposite-side joint (itself on the midline)."""
        out = np.arange(self.num_joints)
        lookup = {n: i for i, n in enumerate(self.names)}
        for i, n in enumerate(self.names):
            m = mirror_name(n)
            if m != n and m in lookup:
                out[i] = lookup[m]
        return out

    def mirrored(self, axis: int = 1) -> "Skeleton":
        """The mirror image across the plane normal to ``axis`` (default Y, the lateral axis).

        Returns ``self`` when the skeleton is already symmetric (within 1e-6 m).
        """
        m = self.mirror_map()
        flip = np.ones(3)
        flip[axis] = -1.0
        offs = self.offsets[m] * flip
        # End sites follow their parent joint to the other side.
        end_off = self.end_offsets * flip
        end_par = m[self.end_parents] if len(self.end_parents) else self.end_parents
        if len(end_par):
            order = np.lexsort((np.arange(len(end_par)), end_par))
            end_par, end_off = end_par[order], end_off[order]
        cand = self.replace(offsets=offs, end_parents=end_par, end_offsets=end_off)
        if np.allclose(cand.offsets, self.offsets, atol=1e-6) and cand.end_parents.shape == self.end_parents.shape \
                and np.allclose(np.sort(cand.end_offsets, axis=0), np.sort(self.end_offsets, axis=0), atol=1e-6):
            return self
        return cand
