"""Explain plots of a response: the alignment error surface (the paper's colour plate) and the timeline of
the four stages (figure 2). Uses matplotlib (the ``viz`` extra), imported inside the functions."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinodyn.io.atomic import atomic_path
from kinodyn.plotting import style

__all__ = ["STAGE_COLORS", "error_surface", "timeline"]

STAGE_NAMES = ("motion data", "simulation", "transition", "clip")
#: Colours of the stages (motion data, simulation, transition, clip): the viewer's, from
#: :data:`kinodyn.plotting.style.STAGE_COLORS`.
STAGE_COLORS = tuple(style.STAGE_COLORS[n] for n in STAGE_NAMES)


def _save(fig, path) -> Path:
    path = Path(path)
    with atomic_path(path, suffix=path.suffix) as tmp:
        fig.savefig(tmp, dpi=110, format=path.suffix.lstrip(".") or "png")
    return path


def error_surface(surface: np.ndarray, path, title: str = "", fast=None, best=None, offset: int = 0,
                  searched_from: int | None = None) -> Path:
    """Plot an ``(S, M)`` error surface D over (simulation frame, clip frame) to ``path`` (PNG).

    Args:
        fast: optional ``(sim_frame, clip_frame)`` of the fast alignment, marked with a cross.
        best: optional ``(sim_frame, clip_frame)`` of the exhaustive optimum, marked with a circle.
        offset: simulation frame of the surface's first row.
        searched_from: optional first simulation frame the searches may choose (earlier rows fall inside
            the shortest transition); the rows before it are greyed out.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    s, m = surface.shape
    im = ax.imshow(surface, origin="lower", aspect="auto", cmap="viridis",
                   extent=(-0.5, m - 0.5, offset - 0.5, offset + s - 0.5))
    fig.colorbar(im, ax=ax, label="window error D")
    if searched_from is not None and searched_from > offset:
        ax.axhspan(offset - 0.5, min(searched_from, offset + s) - 0.5, color="white", alpha=0.6, lw=0,
                   label="shorter than the shortest transition")
    if best is not None:
        ax.plot(best[1], best[0], "o", mfc="none", mec="white", ms=10, label="exhaustive optimum")
    if fast is not None:
        ax.plot(fast[1], fast[0], "x", color="red", ms=9, label="fast alignment")
    if best is not None or fast is not None or searched_from is not None:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=3, fontsize=8, facecolor="0.55",
                  labelcolor="white", edgecolor="none")
    ax.set_xlabel("clip frame")
    ax.set_ylabel("simulation frame (from the choice)")
    ax.set_title(title or "alignment error")
    fig.tight_layout()
    out = _save(fig, path)
    plt.close(fig)
    return out


def timeline(stages, fps: float, path, title: str = "", impact_time: float | None = None) -> Path:
    """Plot the four stages of a response (:class:`kinodyn.response.pipeline.Stages`) on a time axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 2.4))
    for k, (a, b) in enumerate((stages.motion, stages.simulation, stages.transition, stages.clip)):
        ax.barh(0, (b - a) / fps, left=a / fps, color=STAGE_COLORS[k], label=STAGE_NAMES[k])
    if impact_time is not None:
        ax.axvline(impact_time, color="black", lw=1)
        ax.text(impact_time, 0.45, " impact", fontsize=8, va="bottom")
    ax.set_yticks([])
    ax.set_xlabel("time (s)")
    ax.set_title(title or "response stages", pad=26)
    ax.legend(ncol=4, fontsize=8, loc="lower center", bbox_to_anchor=(0.5, 1.12), frameon=False)
    fig.tight_layout()
    out = _save(fig, path)
    plt.close(fig)
    return out
