"""Objects of a contact scene: materials (Table 1), convex pieces, fixed, simulated and driven objects.

Schmidl and Lin, "Real-time physically-based interaction between avatars and virtual environments",
section *Preliminaries*: every object is rigid and is *fixed* (locked in place), *simulated* (moves
under physics) or *driven* (follows a user's tracker, here a motion clip). Each object is a union of
convex pieces (primitives or convex hulls of mesh pieces, see :mod:`kinodyn.contact.meshes`) and has a
material whose pair coefficients come from Table 1.

Conventions: Z up, metres, kilograms; rotations ``(w, x, y, z)``. A piece's pose is in its object's
frame; an object's pose is in the world.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kinodyn._arrays import readonly
from kinodyn.errors import ParameterError, UnknownNameError

__all__ = [
    "KINDS",
    "MATERIALS",
    "SHAPES",
    "Piece",
    "SceneObject",
    "box",
    "capsule",
    "coefficients",
    "ellipsoid",
    "hull",
    "piece_inertia",
    "sphere",
]

#: Materials of Table 1.
MATERIALS = ("wood", "human", "metal")
#: Table 1: (restitution, friction) per pair of materials.
_TABLE1 = {
    ("wood", "wood"): (0.3, 0.3), ("wood", "human"): (0.2, 0.2), ("wood", "metal"): (0.2, 0.1),
    ("human", "human"): (0.1, 0.1), ("human", "metal"): (0.2, 0.1), ("metal", "metal"): (0.3, 0.1),
}
#: Object kinds (section Preliminaries).
KINDS = ("fixed", "simulated", "driven")
#: Convex piece shapes and the meaning of their ``size``: box half sizes (3), sphere radius (1),
#: capsule radius and half length along local z (2), ellipsoid radii (3), hull extent (1, vertices given).
SHAPES = {"box": 3, "sphere": 1, "capsule": 2, "ellipsoid": 3, "hull": 1}


def coefficients(a: str, b: str) -> tuple[float, float]:
    """``(restitution, friction)`` of materials ``a`` and ``b`` (Table 1; symmetric)."""
    for m in (a, b):
        if m not in MATERIALS:
            raise UnknownNameError(f"unknown material {m!r}; materials: {', '.join(MATERIALS)}")
    return _TABLE1.get((a, b)) or _TABLE1[(b, a)]


@dataclass(frozen=True)
class Piece:
    """One convex piece of an object.

    Attributes:
        shape: a key of :data:`SHAPES`.
        size: shape parameters (see :data:`SHAPES`), metres.
        pos: ``(3,)`` position in the object's frame.
        quat: ``(4,)`` rotation in the object's frame.
        vertices: ``(V, 3)`` hull vertices in the piece frame (``hull`` only, else empty).
    """

    shape: str
    size: tuple[float, ...]
    pos: np.ndarray = field(default_factory=lambda: np.zeros(3))
    quat: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    vertices: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self):
        if self.shape not in SHAPES:
            raise UnknownNameError(f"unknown piece shape {self.shape!r}; shapes: {', '.join(SHAPES)}")
        size = tuple(float(s) for s in np.atleast_1d(self.size))
        if len(size) != SHAPES[self.shape] or not all(np.isfinite(size)) or any(s <= 0 for s in size):
            raise ParameterError(f"{self.shape} size must be {SHAPES[self.shape]} positive numbers, got {size}")
        object.__setattr__(self, "size", size)
        pos, q = np.asarray(self.pos, float), np.asarray(self.quat, float)
        if pos.shape != (3,) or q.shape != (4,) or not np.all(np.isfinite(pos)) or not np.all(np.isfinite(q)):
            raise ParameterError(f"piece pos must be 3 and quat 4 finite numbers, got {pos.shape}, {q.shape}")
        object.__setattr__(self, "pos", readonly(pos))
        object.__setattr__(self, "quat", readonly(q / np.linalg.norm(q)))
        v = np.asarray(self.vertices, float).reshape(-1, 3)
        if self.shape == "hull" and (len(v) < 4 or not np.all(np.isfinite(v))):
            raise ParameterError(f"a hull piece needs at least 4 finite vertices, got {len(v)}")
        object.__setattr__(self, "vertices", readonly(v))

    def volume(self) -> float:
        """Volume of the piece (m^3); hulls by their convex hull."""
        s = self.size
        if self.shape == "box":
            return 8.0 * s[0] * s[1] * s[2]
        if self.shape == "sphere":
            return 4.0 / 3.0 * np.pi * s[0] ** 3
        if self.shape == "capsule":
            return 4.0 / 3.0 * np.pi * s[0] ** 3 + np.pi * s[0] ** 2 * 2.0 * s[1]
        if self.shape == "ellipsoid":
            return 4.0 / 3.0 * np.pi * s[0] * s[1] * s[2]
        from scipy.spatial import ConvexHull

        return float(ConvexHull(self.vertices).volume)


def box(half, pos=(0, 0, 0), quat=(1, 0, 0, 0)) -> Piece:
    """A box piece with half sizes ``half (3,)``."""
    return Piece("box", tuple(half), np.asarray(pos, float), np.asarray(quat, float))


def sphere(radius, pos=(0, 0, 0)) -> Piece:
    """A sphere piece."""
    return Piece("sphere", (radius,), np.asarray(pos, float))


def capsule(radius, half_length, pos=(0, 0, 0), quat=(1, 0, 0, 0)) -> Piece:
    """A capsule piece along its local z axis."""
    return Piece("capsule", (radius, half_length), np.asarray(pos, float), np.asarray(quat, float))


def ellipsoid(radii, pos=(0, 0, 0), quat=(1, 0, 0, 0)) -> Piece:
    """An ellipsoid piece with semi-axes ``radii (3,)``."""
    return Piece("ellipsoid", tuple(radii), np.asarray(pos, float), np.asarray(quat, float))


def hull(vertices, pos=(0, 0, 0), quat=(1, 0, 0, 0)) -> Piece:
    """A convex hull piece of ``vertices (V, 3)``."""
    v = np.asarray(vertices, float)
    ext = np.ptp(v, axis=0) if len(v) else np.zeros(3)
    return Piece("hull", (max(float(ext.max()), 1e-9),), np.asarray(pos, float), np.asarray(quat, float), v)


def piece_inertia(piece: Piece, mass: float) -> np.ndarray:
    """``(3,)`` principal inertia of a solid piece of ``mass`` about its own centre (box, sphere,
    ellipsoid exact; capsule as a cylinder plus caps; hull by its bounding box)."""
    s = piece.size
    if piece.shape == "sphere":
        return np.full(3, 0.4 * mass * s[0] ** 2)
    if piece.shape == "ellipsoid":
        a, b, c = s
        return 0.2 * mass * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    if piece.shape == "capsule":
        r, h = s
        ix = mass * (3 * r * r + 4 * h * h) / 12.0 + mass * 0.25 * r * r
        return np.array([ix, ix, 0.5 * mass * r * r])
    half = np.asarray(s) if piece.shape == "box" else np.ptp(piece.vertices, axis=0) / 2.0
    x, y, z = half ** 2
    return mass / 3.0 * np.array([y + z, x + z, x + y])


@dataclass(frozen=True)
class SceneObject:
    """A rigid object of the scene.

    Attributes:
        name: unique name.
        kind: ``"fixed"``, ``"simulated"`` or ``"driven"``.
        material: a key of :data:`MATERIALS`.
        pieces: its convex pieces.
        pos: ``(3,)`` initial position of the object's frame.
        quat: ``(4,)`` initial orientation.
        mass: kilograms (simulated and driven objects; fixed objects are immovable).
        velocity: ``(3,)`` initial linear velocity of a simulated object (m/s).
        group: objects of one group never collide with each other (the segments of one avatar use
            their own filter instead); ``""`` for none.
    """

    name: str
    kind: str
    material: str
    pieces: tuple[Piece, ...]
    pos: np.ndarray = field(default_factory=lambda: np.zeros(3))
    quat: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    mass: float = 1.0
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    group: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ParameterError(f"object {self.name!r}: kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.material not in MATERIALS:
            raise UnknownNameError(f"object {self.name!r}: unknown material {self.material!r}; materials: "
                                   f"{', '.join(MATERIALS)}")
        if not self.pieces:
            raise ParameterError(f"object {self.name!r}: needs at least one convex piece, got none")
        if not (np.isfinite(self.mass) and self.mass > 0):
            raise ParameterError(f"object {self.name!r}: mass must be a positive number of kg, got {self.mass}")
        object.__setattr__(self, "pieces", tuple(self.pieces))
        for key, n in (("pos", 3), ("quat", 4), ("velocity", 3)):
            a = np.asarray(getattr(self, key), float)
            if a.shape != (n,) or not np.all(np.isfinite(a)):
                raise ParameterError(f"object {self.name!r}: {key} must be {n} finite numbers, got {a.tolist()}")
            object.__setattr__(self, key, readonly(a / np.linalg.norm(a) if key == "quat" else a))

    def inertia(self) -> np.ndarray:
        """``(3, 3)`` inertia tensor about the object's origin, in its frame, from its pieces (mass shared
        by volume; the origin is taken as the centre of mass, as for every built-in simulated object)."""
        from kinodyn.math import quat as q

        vols = np.array([p.volume() for p in self.pieces])
        out = np.zeros((3, 3))
        for p, m in zip(self.pieces, self.mass * vols / vols.sum()):
            r = q.to_matrix(p.quat)
            out += r @ np.diag(piece_inertia(p, m)) @ r.T
            d = p.pos
            out += m * (d @ d * np.eye(3) - np.outer(d, d))
        return out
