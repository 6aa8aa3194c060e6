"""Meshes of scene objects: reading (trimesh), checking, convex decomposition (CoACD), a disk cache.

The paper assumes a convex decomposition of every object ("Estimating the global penetration depth").
A triangle mesh (OBJ, STL, PLY, GLB, anything trimesh reads) is checked (triangles present, finite
vertices, a closed two-manifold surface) and split into convex pieces by CoACD (Wei et al. 2022,
approximate convex decomposition); each piece becomes a ``hull`` :class:`~kinodyn.contact.setting.Piece`.
Decompositions take seconds, so they are cached on disk as ``.npz`` files named by a hash of the
mesh's vertices, faces and the decomposition parameters (``$KINODYN_CACHE`` or ``~/.cache/kinodyn``).

Shapes: ``V`` vertices ``(V, 3)``, ``T`` triangles ``(T, 3)`` int. Metres.
"""

from __future__ import annotations

import hashlib
import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinodyn.contact.setting import Piece, hull
from kinodyn.errors import FileFormatError, ParameterError

__all__ = [
    "DecompositionConfig",
    "cache_dir",
    "check_mesh",
    "decompose",
    "load_mesh",
    "mesh_pieces",
    "prism",
]

ERR_EMPTY = "mesh {name}: has no triangles (an empty mesh cannot be decomposed into convex pieces)"
ERR_NAN = "mesh {name}: vertex {k} is not finite ({v}); every vertex coordinate must be a finite number"
ERR_FACE = "mesh {name}: triangle {k} refers to vertex {v}, but the mesh has {n} vertices"
ERR_MANIFOLD = ("mesh {name}: not a closed two-manifold surface ({bad} edges are not shared by exactly two "
                "triangles); convex decomposition needs a closed, watertight mesh")


@dataclass(frozen=True)
class DecompositionConfig:
    """CoACD parameters (defaults: CoACD's concavity threshold 0.05, a fixed seed for repeatability).

    Attributes:
        threshold: concavity threshold of CoACD (smaller: more pieces, closer to the mesh).
        max_pieces: upper bound on the number of pieces (-1: no bound).
        seed: CoACD's random seed.
        resolution: CoACD's sampling resolution (5000: cuts within 0.1 mm on a 1 m bracket; CoACD's
            default 2000 leaves 0.7 mm).
        snap: piece vertices closer than this fraction of the mesh's diagonal to the mesh surface are
            moved onto it (CoACD's hulls stray from the surface by about a millimetre per metre).
    """

    threshold: float = 0.05
    max_pieces: int = -1
    seed: int = 0
    resolution: int = 5000
    snap: float = 0.005

    def __post_init__(self):
        if not (0.0 < self.threshold <= 1.0):
            raise ParameterError(f"threshold must be in (0, 1], got {self.threshold}")


def check_mesh(vertices, faces, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """Check a triangle mesh; return ``(vertices (V, 3) float64, faces (T, 3) int64)``.

    Raises:
        FileFormatError: no triangles, a non-finite vertex, a face index out of range, or a surface that
            is not a closed two-manifold (every edge shared by exactly two triangles).
    """
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces).reshape(-1, 3)
    if len(f) == 0:
        raise FileFormatError(ERR_EMPTY.format(name=name))
    bad = np.nonzero(~np.all(np.isfinite(v), axis=1))[0]
    if len(bad):
        raise FileFormatError(ERR_NAN.format(name=name, k=int(bad[0]), v=v[bad[0]].tolist()))
    f = f.astype(np.int64)
    if f.min() < 0 or f.max() >= len(v):
        k = int(np.nonzero((f < 0).any(1) | (f >= len(v)).any(1))[0][0])
        raise FileFormatError(ERR_FACE.format(name=name, k=k, v=f[k].tolist(), n=len(v)))
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    nbad = int(np.count_nonzero(counts != 2))
    if nbad:
        raise FileFormatError(ERR_MANIFOLD.format(name=name, bad=nbad))
    return v, f


def load_mesh(path, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Read a mesh file with trimesh (scenes are merged into one mesh) and check it.

    Returns ``(vertices (V, 3), faces (T, 3))`` scaled by ``scale``.
    """
    import trimesh

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such mesh file")
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as e:  # noqa: BLE001 - trimesh raises many kinds for bad files
        raise FileFormatError(f"cannot read mesh: {e}", path) from None
    if not hasattr(mesh, "faces"):
        raise FileFormatError(ERR_EMPTY.format(name=path.name), path)
    # trimesh merges duplicate vertices only when processing; do it here so seams do not count as holes
    v, f = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    if len(f) and np.all(np.isfinite(v)):
        m = trimesh.Trimesh(v, f, process=True, validate=False)
        v, f = np.asarray(m.vertices, float), np.asarray(m.faces)
    return check_mesh(v * float(scale), f, name=path.name)


def cache_dir() -> Path:
    """Folder of cached decompositions (``$KINODYN_CACHE/coacd`` or ``~/.cache/kinodyn/coacd``)."""
    root = os.environ.get("KINODYN_CACHE") or Path.home() / ".cache" / "kinodyn"
    return Path(root) / "coacd"


def _key(v: np.ndarray, f: np.ndarray, cfg: DecompositionConfig) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(v, np.float64).tobytes())
    h.update(np.ascontiguousarray(f, np.int64).tobytes())
    h.update(f"coacd-snap2:{cfg.threshold}:{cfg.max_pieces}:{cfg.seed}:{cfg.resolution}:{cfg.snap}".encode())
    return h.hexdigest()[:32]


def decompose(vertices, faces, config: DecompositionConfig | None = None, name: str = "mesh",
              use_cache: bool = True) -> list[np.ndarray]:
    """Convex pieces of a closed mesh by CoACD, cached on disk by mesh hash.

    Args:
        vertices: ``(V, 3)``; faces: ``(T, 3)`` (checked by :func:`check_mesh`).

    Returns:
        one ``(Vi, 3)`` vertex array per convex piece (the piece is their convex hull).
    """
    cfg = config or DecompositionConfig()
    v, f = check_mesh(vertices, faces, name)
    path = cache_dir() / f"{_key(v, f, cfg)}.npz"
    if use_cache and path.exists():
        with np.load(path, allow_pickle=False) as z:
            return [z[f"piece{i}"] for i in range(int(z["count"]))]
    import coacd

    coacd.set_log_level("error")
    parts = coacd.run_coacd(coacd.Mesh(v, f), threshold=cfg.threshold, max_convex_hull=cfg.max_pieces,
                            seed=cfg.seed, preprocess_mode="off", resolution=cfg.resolution)
    pieces = [_snap(np.asarray(p[0], dtype=np.float64), v, f, cfg.snap) for p in parts if len(p[0]) >= 4]
    if use_cache:
        from kinodyn.io.atomic import atomic_write_bytes

        buf = io.BytesIO()
        np.savez(buf, count=len(pieces), **{f"piece{i}": p for i, p in enumerate(pieces)})
        atomic_write_bytes(path, buf.getvalue())
    return pieces


def _snap(piece: np.ndarray, v: np.ndarray, f: np.ndarray, fraction: float) -> np.ndarray:
    """Move the vertices of ``piece (Vp, 3)`` within ``fraction`` of the diagonal of the mesh ``v, f``
    from one of its vertices onto that vertex (CoACD cuts near, not through, the mesh's corners), else
    within that distance of its surface onto the nearest surface point."""
    from trimesh.triangles import closest_point

    tol = fraction * float(np.linalg.norm(np.ptp(v, axis=0)))
    dv = np.linalg.norm(piece[:, None] - v[None], axis=2)
    kv = dv.argmin(axis=1)
    tri = v[f]
    n, t = len(piece), len(tri)
    cp = closest_point(np.tile(tri, (n, 1, 1)), np.repeat(piece, t, axis=0)).reshape(n, t, 3)
    ds = np.linalg.norm(cp - piece[:, None], axis=2)
    ks = ds.argmin(axis=1)
    rows = np.arange(n)
    out = np.where((ds[rows, ks] < tol)[:, None], cp[rows, ks], piece)
    return np.where((dv[rows, kv] < tol)[:, None], v[kv], out)


def mesh_pieces(vertices, faces, config: DecompositionConfig | None = None, name: str = "mesh") -> list[Piece]:
    """The convex ``hull`` pieces of a mesh (see :func:`decompose`)."""
    return [hull(p) for p in decompose(vertices, faces, config, name)]


def _ears(p: np.ndarray) -> list[tuple[int, int, int]]:
    """Triangles of the simple counter-clockwise polygon ``p (N, 2)`` by ear clipping."""
    idx = list(range(len(p)))
    out = []

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    guard = 0
    while len(idx) > 3 and guard < 10 * len(p) ** 2:
        guard += 1
        for k in range(len(idx)):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            a, b, c = p[i0], p[i1], p[i2]
            if cross(a, b, c) <= 1e-12:
                continue  # reflex or flat corner
            inside = any(cross(a, b, p[j]) >= 0 and cross(b, c, p[j]) >= 0 and cross(c, a, p[j]) >= 0
                         for j in idx if j not in (i0, i1, i2))
            if not inside:
                out.append((i0, i1, i2))
                idx.pop(k)
                break
        else:
            raise ParameterError("polygon must be simple (no self-intersections)")
    out.append(tuple(idx))
    return out


def prism(polygon, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed prism: the simple polygon ``polygon (N, 2)`` in the x-z plane (either winding), extruded
    along y from ``-depth/2`` to ``depth/2`` (an L-shaped bracket, steps, a U-shaped niche). Returns
    ``(vertices (2N, 3), faces (4N - 4, 3))`` wound outward."""
    p = np.asarray(polygon, dtype=np.float64)
    n = len(p)
    if p.ndim != 2 or p.shape[1] != 2 or n < 3:
        raise ParameterError(f"polygon must have shape (N >= 3, 2), got {p.shape}")
    area = 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])
    if area < 0:
        p = p[::-1]
    v = np.concatenate([np.c_[p[:, 0], np.full(n, -depth / 2), p[:, 1]],
                        np.c_[p[:, 0], np.full(n, depth / 2), p[:, 1]]])
    faces = []
    for a, b, c in _ears(p):  # polygon counter-clockwise in (x, z) seen from -y: cap at -y faces -y
        faces += [[a, b, c], [n + a, n + c, n + b]]
    for k in range(n):
        a, b = k, (k + 1) % n
        faces += [[a, n + b, b], [a, n + a, n + b]]
    return v, np.array(faces, dtype=np.int64)
