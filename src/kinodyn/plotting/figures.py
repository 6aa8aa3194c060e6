"""Plots (matplotlib) in one style: the building blocks the capability reports use.

* :func:`phase_timeline`: bars of coloured time spans (support phases, actions, blend weights) with
  optional event ticks; :func:`support_bars` builds it from foot contacts.
* :func:`error_surface`: a scalar field over two parameters (a search's error over time offset and
  heading) as a heat map with contour lines and the minimum (or any point) marked.
* :func:`scatter_map`: 2-D points (an embedding of scenes, crowd positions) coloured by value or
  category, with highlighted points ringed and labelled.
* :func:`time_series`: curves over time with optional shaded spans.
* :func:`save`: one figure to PNG and SVG at once, atomically; :func:`write_figure` one file with
  explicit ``savefig`` settings (for figures drawn in their own style); :func:`pyplot` for figures
  made with pyplot, without a display.

Every function returns a :class:`matplotlib.figure.Figure` made without pyplot (no global state, no
display needed) or draws into the ``ax`` it is given. Colours come from :mod:`kinodyn.plotting.style`;
support phases are drawn in the colours of :data:`kinodyn.phases.PHASE_COLORS`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.io.atomic import atomic_path
from kinodyn.plotting import style

__all__ = [
    "PLOT_FORMATS",
    "RC",
    "error_surface",
    "figure",
    "phase_timeline",
    "pyplot",
    "save",
    "scatter_map",
    "support_bars",
    "time_series",
    "write_figure",
]

PLOT_FORMATS = ("png", "svg")

#: matplotlib settings of every kinodyn plot.
RC = {
    "figure.dpi": 100, "savefig.dpi": 150, "savefig.bbox": "tight", "font.size": 9, "axes.titlesize": 10,
    "axes.labelsize": 9, "axes.spines.top": False, "axes.spines.right": False, "axes.grid": True,
    "grid.color": "#d9dde3", "grid.linewidth": 0.6, "axes.edgecolor": "#6b7480", "axes.axisbelow": True,
    "legend.frameon": False, "legend.fontsize": 8, "xtick.labelsize": 8, "ytick.labelsize": 8,
    "svg.fonttype": "none", "image.cmap": "viridis",
}


@contextlib.contextmanager
def _style():
    import matplotlib as mpl
    from cycler import cycler

    with mpl.rc_context({**RC, "axes.prop_cycle": cycler(color=list(style.PALETTE))}):
        yield


def figure(width: float = 7.0, height: float = 3.0, nrows: int = 1, ncols: int = 1, **kw):
    """A new ``(Figure, axes)`` in the kinodyn style (inches; axes squeezed as in ``plt.subplots``)."""
    from matplotlib.figure import Figure

    with _style():
        fig = Figure(figsize=(width, height), layout="constrained")
        axes = fig.subplots(nrows, ncols, **kw)
    return fig, axes


def _ax(ax, width, height):
    if ax is None:
        return figure(width, height)
    return ax.figure, ax


def phase_timeline(tracks: Sequence[tuple[str, Sequence[tuple[float, float, str]]]], *, duration=None,
                   colors: Mapping[str, str] | None = None, events: Sequence[tuple[float, str]] = (),
                   title: str = "", xlabel: str = "time (s)", ax=None, width: float = 7.0):
    """Bars of coloured spans, one row per track, top to bottom.

    Args:
        tracks: ``(name, spans)`` with spans ``(t0, t1, label)`` in seconds.
        duration: x range end (default: the last span end).
        colors: label -> colour; unlisted labels use :data:`style.PHASE_COLORS`, then the palette in order.
        events: ``(time, label)`` vertical ticks across all rows (impacts, transitions).
        title, xlabel: text.
        ax: draw into these axes instead of a new figure.
    """
    if not tracks:
        raise ParameterError("tracks is empty: nothing to plot")
    fig, ax = _ax(ax, width, 0.45 * len(tracks) + 1.0)
    with _style():
        lut = dict(style.PHASE_COLORS)
        lut.update({k: style.color(v) for k, v in (colors or {}).items()})
        extra = iter(style.PALETTE)
        used = {}
        end = 0.0
        for row, (name, spans) in enumerate(tracks):
            y = len(tracks) - 1 - row
            for a, b, lab in spans:
                if lab not in lut:
                    lut[lab] = next(extra, "#888888")
                ax.broken_barh([(a, b - a)], (y - 0.38, 0.76), facecolors=lut[lab], edgecolor="white",
                               linewidth=0.3)
                used[lab] = lut[lab]
                end = max(end, b)
        for t, lab in events:
            ax.axvline(t, color=style.IMPACT_COLOR, lw=1.2)
            if lab:
                ax.text(t, len(tracks) - 0.45, f" {lab}", color=style.IMPACT_COLOR, fontsize=7, va="bottom")
        ax.set_yticks(range(len(tracks)))
        ax.set_yticklabels([n for n, _ in reversed(tracks)])
        ax.set_ylim(-0.6, len(tracks) - 0.4 + (0.35 if any(lab for _, lab in events) else 0))
        ax.set_xlim(0, duration if duration is not None else max(end, 1e-6))
        ax.set_xlabel(xlabel)
        ax.grid(axis="y", visible=False)
        if title:
            ax.set_title(title, loc="left")
        from matplotlib.patches import Patch

        ax.legend(handles=[Patch(color=c, label=lab) for lab, c in used.items()], loc="upper left",
                  bbox_to_anchor=(1.0, 1.0), fontsize=7, handlelength=1.0)
    return fig


def support_bars(contacts: Mapping[str, np.ndarray], fps: float, **kw):
    """Support-phase bars (LS / RS / DS / flight) from foot contacts ``name -> (F, 2) bool`` at ``fps``.

    Keyword arguments go to :func:`phase_timeline`.
    """
    from kinodyn.phases import contact_spans

    tracks = [(name, contact_spans(lab, fps, names=style.PHASE_LABELS)) for name, lab in contacts.items()]
    kw.setdefault("title", "support phases")
    return phase_timeline(tracks, **kw)


def error_surface(x, y, z, *, xlabel: str = "x", ylabel: str = "y", zlabel: str = "error",
                  mark="min", log: bool = False, levels: int = 8, title: str = "", ax=None,
                  width: float = 5.0, height: float = 4.0):
    """A scalar field ``z (len(y), len(x))`` over a grid as a heat map with contours.

    Args:
        x, y: ``(Nx,)`` and ``(Ny,)`` grid coordinates (ascending).
        z: ``(Ny, Nx)`` values; NaN cells are left blank.
        mark: ``"min"`` to ring the smallest value, ``(x, y)`` to ring that point, ``None`` for none.
        log: colour by log10 of z (positive values).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    if z.shape != (len(y), len(x)):
        raise ParameterError(f"z must have shape (len(y), len(x)) = ({len(y)}, {len(x)}), got {z.shape}")
    if not np.isfinite(z).any():
        raise ParameterError("z has no finite value")
    fig, ax = _ax(ax, width, height)
    with _style():
        zz = np.log10(np.where(z > 0, z, np.nan)) if log else z
        im = ax.pcolormesh(x, y, zz, shading="auto", cmap="viridis")
        if levels and np.isfinite(zz).sum() > 4 and len(x) > 1 and len(y) > 1:
            with np.errstate(invalid="ignore"):
                ax.contour(x, y, zz, levels=levels, colors="white", linewidths=0.5, alpha=0.7)
        cb = fig.colorbar(im, ax=ax)
        cb.set_label(f"log10 {zlabel}" if log else zlabel)
        pt = None
        if isinstance(mark, str) and mark == "min":
            i, j = np.unravel_index(np.nanargmin(z), z.shape)
            pt = (x[j], y[i], f"min {z[i, j]:.3g}")
        elif mark is not None:
            pt = (float(mark[0]), float(mark[1]), "")
        if pt:
            ax.scatter([pt[0]], [pt[1]], s=90, facecolors="none", edgecolors=style.IMPACT_COLOR, linewidths=1.8,
                       zorder=5)
            if pt[2]:
                ax.annotate(pt[2], (pt[0], pt[1]), xytext=(6, 6), textcoords="offset points", color="white",
                            fontsize=8)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(False)
        if title:
            ax.set_title(title, loc="left")
    return fig


def scatter_map(points, *, values=None, categories=None, highlight: Sequence[int] = (),
                labels: Sequence[str] | None = None, xlabel: str = "", ylabel: str = "", title: str = "",
                value_label: str = "", equal: bool = True, ax=None, width: float = 5.0, height: float = 4.5):
    """2-D points with highlighted ones ringed and labelled.

    Args:
        points: ``(N, 2)``.
        values: optional ``(N,)`` numbers for a colour scale (e.g. a ranking score).
        categories: optional ``(N,)`` labels, one palette colour each (ignored when ``values`` is given).
        highlight: indices to ring (e.g. the top-ranked scenes); labelled with ``labels`` when given.
        labels: optional ``(N,)`` point names.
        equal: same scale on both axes (maps, embeddings).
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ParameterError(f"points must have shape (N, 2), got {p.shape}")
    n = len(p)
    hl = [int(i) for i in highlight]
    if any(not 0 <= i < n for i in hl):
        raise ParameterError(f"highlight indices must be in 0..{n - 1}, got {hl}")
    if labels is not None and len(labels) != n:
        raise ParameterError(f"labels must have {n} entries, got {len(labels)}")
    fig, ax = _ax(ax, width, height)
    with _style():
        if values is not None:
            v = np.asarray(values, dtype=np.float64)
            if v.shape != (n,):
                raise ParameterError(f"values must have shape ({n},), got {v.shape}")
            sc = ax.scatter(p[:, 0], p[:, 1], c=v, s=22, cmap="viridis", edgecolors="white", linewidths=0.4)
            cb = fig.colorbar(sc, ax=ax)
            if value_label:
                cb.set_label(value_label)
        elif categories is not None:
            cats = list(dict.fromkeys(categories))
            for k, c in enumerate(cats):
                m = np.array([x == c for x in categories])
                ax.scatter(p[m, 0], p[m, 1], s=22, color=style.PALETTE[k % len(style.PALETTE)], label=str(c),
                           edgecolors="white", linewidths=0.4)
            ax.legend(loc="best")
        else:
            ax.scatter(p[:, 0], p[:, 1], s=22, color=style.PALETTE[0], edgecolors="white", linewidths=0.4)
        if hl:
            ax.scatter(p[hl, 0], p[hl, 1], s=140, facecolors="none", edgecolors=style.IMPACT_COLOR, linewidths=1.8,
                       zorder=5)
            for rank, i in enumerate(hl):
                text = labels[i] if labels is not None else f"#{rank + 1}"
                ax.annotate(text, (p[i, 0], p[i, 1]), xytext=(7, 5), textcoords="offset points", fontsize=8,
                            color="#1d2430")
        if equal:
            ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        if title:
            ax.set_title(title, loc="left")
    return fig


def time_series(t, series: Mapping[str, np.ndarray], *, spans: Sequence[tuple[float, float, str]] = (),
                xlabel: str = "time (s)", ylabel: str = "", title: str = "", ax=None, width: float = 7.0,
                height: float = 3.0):
    """Curves ``name -> (T,)`` over ``t (T,)`` with optional shaded spans ``(t0, t1, label)``."""
    t = np.asarray(t, dtype=np.float64)
    fig, ax = _ax(ax, width, height)
    with _style():
        for k, (a, b, lab) in enumerate(spans):
            ax.axvspan(a, b, color=style.PHASE_COLORS.get(lab, style.PALETTE[k % len(style.PALETTE)]), alpha=0.18,
                       lw=0)
        for k, (name, y) in enumerate(series.items()):
            y = np.asarray(y, dtype=np.float64)
            if y.shape != t.shape:
                raise ParameterError(f"series {name!r} must have shape {t.shape}, got {y.shape}")
            ax.plot(t, y, color=style.PALETTE[k % len(style.PALETTE)], lw=1.4, label=name)
        if len(series) > 1:
            ax.legend(loc="best")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        if title:
            ax.set_title(title, loc="left")
    return fig


def save(fig, path, formats: Sequence[str] = PLOT_FORMATS) -> list[Path]:
    """Write ``fig`` to ``path`` in each format (``out/plot`` -> ``out/plot.png``, ``out/plot.svg``);
    a suffix on ``path`` naming a format writes that one only. Returns the paths written."""
    p = Path(path)
    if p.suffix.lower().lstrip(".") in PLOT_FORMATS:
        formats = (p.suffix.lower().lstrip("."),)
        p = p.with_suffix("")
    bad = [f for f in formats if f not in PLOT_FORMATS]
    if bad:
        raise ParameterError(f"plot formats must be among {', '.join(PLOT_FORMATS)}, got {bad[0]!r}")
    with _style():
        return [write_figure(fig, p.with_name(p.name + "." + f), format=f) for f in formats]


def write_figure(fig, path, **savefig) -> Path:
    """Write ``fig`` to ``path`` atomically with ``fig.savefig(..., **savefig)``; returns the path."""
    path = Path(path)
    with atomic_path(path, suffix=path.suffix) as tmp:
        fig.savefig(tmp, **savefig)
    return path


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (no display needed), for figures drawn with pyplot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
