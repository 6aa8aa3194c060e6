"""Stick-figure pictures of crowd motion: the impact contact sheet and a crowd snapshot (matplotlib).

The figures draw the posed skeletons as lines (left side red, right blue, spine black); the impact
sheet shows each reaction of section 6 seen from its own side at several moments, fading from the
hit to the end. Images are written atomically as PNG.
"""

from __future__ import annotations

import numpy as np

from kinodyn.math import quat

__all__ = ["contact_sheet", "crowd_snapshot"]


def _bones(skeleton):
    return [(skeleton.parents[j], j, "#c0392b" if "Left" in n else ("#2e6fd1" if "Right" in n else "#222222"))
            for j, n in enumerate(skeleton.names) if j > 0]


def _positions(skeleton, root_pos, local_rot):
    lp = np.broadcast_to(np.asarray(skeleton.offsets), local_rot.shape[:-1] + (3,)).copy()
    lp[..., 0, :] = root_pos
    return quat.fk(np.asarray(local_rot, np.float64), lp, skeleton.parents)[1]


def _save(fig, path) -> None:
    import matplotlib.pyplot as plt

    from kinodyn.io.atomic import atomic_path

    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=fig.dpi)
    plt.close(fig)


def contact_sheet(path, imp, skeleton, samples: int = 6, title: str = "") -> None:
    """A grid of the reactions ``imp`` (:class:`~kinodyn.crowd.impacts.ImpactSet`), each drawn in its
    character's frame at the hit, seen from its left side, at ``samples`` moments."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from kinodyn.crowd.impacts import ANGLES, HEIGHTS, STRENGTHS

    r, f = imp.root_pos.shape[:2]
    cols = 9
    rows = int(np.ceil(r / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(cols * 1.9, rows * 1.75), dpi=80)
    t = np.linspace(0, f - 1, samples).round().astype(int)
    pos = _positions(skeleton, imp.root_pos[:, t], imp.local_rot[:, t])
    facing = quat.heading(imp.local_rot[:, 0, 0].astype(np.float64), forward=[1.0, 0.0, 0.0])
    inv = quat.from_heading(-facing)[:, None, None, :]
    rel = quat.mul_vec(inv, pos - pos[:, :1, :1] * np.array([1.0, 1.0, 0.0]))
    for i, ax in enumerate(np.ravel(axes)):
        ax.set_axis_off()
        if i >= r:
            continue
        for k in range(samples):
            a = 0.25 + 0.75 * k / max(1, samples - 1)
            for p, j, c in _bones(skeleton):
                ax.plot(rel[i, k, [p, j], 0], rel[i, k, [p, j], 2], color=c, alpha=a, lw=1.1)
        ax.axhline(0.0, color="#999999", lw=0.6)
        ax.set_xlim(-2.2, 2.2)
        ax.set_ylim(-0.05, 1.6)
        ax.set_aspect("equal")
        lab = imp.labels[i]
        ax.set_title(f"pos {ANGLES[lab[0]]:+.0f} dir {ANGLES[lab[1]]:+.0f} h {HEIGHTS[lab[2]]:.1f} "
                     f"{STRENGTHS[lab[3]]}", fontsize=6.5)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    _save(fig, path)


def crowd_snapshot(path, skeleton, root_pos, local_rot, modes=None, title: str = "") -> None:
    """Every character of one frame, from above-front (``root_pos (N, 3)``, ``local_rot (N, J, 4)``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pos = _positions(skeleton, root_pos, local_rot)  # (N, J, 3)
    fig = plt.figure(figsize=(9, 6), dpi=90)
    ax = fig.add_subplot(projection="3d")
    for i in range(len(pos)):
        for p, j, c in _bones(skeleton):
            ax.plot(pos[i, [p, j], 0], pos[i, [p, j], 1], pos[i, [p, j], 2], color=c, lw=0.8)
    lo, hi = pos[..., :2].min(axis=(0, 1)), pos[..., :2].max(axis=(0, 1))
    ax.set_box_aspect((hi[0] - lo[0] + 0.5, hi[1] - lo[1] + 0.5, 1.8))
    ax.view_init(elev=28, azim=-60)
    ax.set_zlim(0, 1.8)
    if title:
        ax.set_title(title, fontsize=9)
    _save(fig, path)
