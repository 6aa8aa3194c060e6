"""Pictures of contact scenes: rendered frames (matplotlib 3-D) and the frame-time plots (figures 7, 8).

Every convex piece is drawn as a shaded triangle mesh: fixed objects grey, simulated ones orange, the
driven avatar and hand blue, avatar segments that still overlap a fixed object red. PNG files are
written atomically. Matplotlib is imported here only.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinodyn.contact.setting import Piece
from kinodyn.math import quat

__all__ = ["frame_time_plot", "piece_mesh", "render_frame", "render_frames"]

_COLOURS = {"fixed": (0.72, 0.72, 0.70), "simulated": (0.95, 0.55, 0.15), "driven": (0.35, 0.55, 0.9)}


def _sphere(n: int = 8, m: int = 12) -> tuple[np.ndarray, np.ndarray]:
    th = np.linspace(0, np.pi, n + 1)
    ph = np.linspace(0, 2 * np.pi, m, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    f = []
    for i in range(n):
        for j in range(m):
            a, b = i * m + j, i * m + (j + 1) % m
            f += [[a, b, a + m], [b, b + m, a + m]]
    return v, np.array(f)


def piece_mesh(piece: Piece) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of a piece in its object's frame: vertices ``(V, 3)``, faces ``(T, 3)``."""
    if piece.shape == "hull":
        from scipy.spatial import ConvexHull

        h = ConvexHull(piece.vertices)
        v, f = piece.vertices, h.simplices
    elif piece.shape == "box":
        c = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
        v = c * np.asarray(piece.size)
        f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                      [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    else:
        v, f = _sphere()
        s = piece.size
        if piece.shape == "sphere":
            v = v * s[0]
        elif piece.shape == "ellipsoid":
            v = v * np.asarray(s)
        else:  # capsule: hemispheres moved apart by the half length
            v = v * s[0] + np.where(v[:, 2:] >= 0, 1.0, -1.0) * np.array([0.0, 0.0, s[1]])
    return quat.mul_vec(piece.quat, v) + piece.pos, f


def render_frame(ax, objects, pos, quats, kinds, red=(), pieces_override=None) -> None:
    """Draw ``objects`` at ``pos (N, 3)``, ``quats (N, 4)`` on a 3-D axes; objects in ``red`` are drawn
    red; ``pieces_override`` maps an object index to its current pieces (an articulated hand)."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    tris, cols = [], []
    for k, obj in enumerate(objects):
        base = np.array(_COLOURS[kinds[k]] if k not in red else (0.9, 0.15, 0.1))
        alpha = 0.25 if kinds[k] == "fixed" else 1.0
        for piece in (pieces_override or {}).get(k, obj.pieces):
            v, f = piece_mesh(piece)
            w = quat.mul_vec(quats[k], v) + pos[k]
            t = w[f]
            n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
            shade = 0.55 + 0.45 * np.abs(n @ light)
            tris.append(t)
            rgb = np.clip(base[None] * shade[:, None], 0, 1)
            cols.append(np.concatenate([rgb, np.full((len(rgb), 1), alpha)], axis=1))
    ax.add_collection3d(Poly3DCollection(np.concatenate(tris), facecolors=np.concatenate(cols), linewidths=0))


def render_frames(scene, result, out, count: int = 6, around=None, radius: float = 1.6,
                  azim: float = -135.0) -> list[Path]:
    """Render ``count`` frames of a run as PNG files in ``out``; the view centres on the avatar's root
    (or the hand) unless ``around (3,)`` is given."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from kinodyn.contact import motions
    from kinodyn.contact.simulate import ContactSimulation
    from kinodyn.io.atomic import atomic_path

    names = list(result.names)
    sim = ContactSimulation(scene)
    objects = sim.world.objects
    kinds = [o.kind for o in objects]
    hand = names.index("hand") if "hand" in names else None
    frames = np.linspace(0, len(result.pos) - 1, count).round().astype(int)
    pen = result.frames["penetration_mm"]
    written = []
    for i, f in enumerate(frames):
        fig = plt.figure(figsize=(6.4, 4.8), dpi=100)
        ax = fig.add_subplot(projection="3d")
        override = {}
        if hand is not None:
            _, flex, index, _ = sim.hand_track
            override[hand] = motions.hand_pieces(flex[min(f, len(flex) - 1)], index[min(f, len(flex) - 1)])
        centre = np.asarray(around) if around is not None else (
            result.pos[f, hand] if hand is not None else result.pos[f, sim.first] if sim.avatar else np.zeros(3))
        lo, hi = sim.world.lo, sim.world.hi  # boxes of the fixed objects (they never move)
        gap = [np.linalg.norm(np.maximum(0, np.maximum(lo[g] - centre, centre - hi[g])), axis=1).min()
               for g in (sim.world.pieces_of(k) for k in range(len(objects)))]
        near = [k for k in range(len(objects)) if kinds[k] != "fixed" or gap[k] < radius]
        sub = [objects[k] for k in near]
        local = {near.index(hand): override[hand]} if override else None
        render_frame(ax, sub, result.pos[f, near], result.quat[f, near], [kinds[k] for k in near],
                     pieces_override=local)
        ax.set_xlim(centre[0] - radius, centre[0] + radius)
        ax.set_ylim(centre[1] - radius, centre[1] + radius)
        ax.set_zlim(max(centre[2] - radius, -0.1), centre[2] + radius)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=18, azim=azim)
        ax.set_title(f"{scene.name} frame {f} ({f / result.fps:.2f} s), overlap {pen[f]:.2f} mm", fontsize=9)
        path = Path(out) / f"{scene.name}_{i:02d}_f{f:04d}.png"
        with atomic_path(path, suffix=".png") as tmp:
            fig.savefig(tmp, format="png")
        plt.close(fig)
        written.append(path)
    return written


def frame_time_plot(results, path) -> Path:
    """Frame time against frame of each run (figures 7 and 8), as one PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from kinodyn.io.atomic import atomic_path

    fig, ax = plt.subplots(figsize=(7, 3), dpi=100)
    for r in results:
        ax.plot(r.frames["frame_ms"], lw=0.8, label=r.scene)
    ax.set_xlabel("frame")
    ax.set_ylabel("frame time, CPU (ms)")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png")
    plt.close(fig)
    return Path(path)
