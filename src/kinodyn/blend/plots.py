"""Figures of the synchronization: support-phase bars (figure 9), time warps (figure 10), foot tracks.

Drawn with :func:`kinodyn.plotting.pyplot` (matplotlib imported on first use, optional dependency
``kinodyn[viz]``) in the phase colours of :data:`kinodyn.phases.PHASE_COLORS`; every function writes
one PNG atomically (:func:`kinodyn.plotting.write_figure`) and returns its path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinodyn.phases import DS, ERR, FLIGHT, LS, PHASE_COLORS, RS, phase_name, time_spans
from kinodyn.plotting import pyplot, write_figure

__all__ = ["PHASE_COLORS", "action_phase_track", "plot_feet", "plot_phases", "plot_timewarp"]


def _save(fig, path) -> Path:
    path = write_figure(fig, path, format="png", dpi=110, bbox_inches="tight")
    pyplot().close(fig)
    return path


def _runs(t, codes, valid):
    """Contiguous runs ``(t0, t1, code)`` of ``codes`` where ``valid``; a frame lasts the median step of ``t``."""
    dt = float(np.median(np.diff(t))) if len(codes) > 1 else 1.0
    return time_spans(codes, t, np.asarray(t) + dt, valid)


def action_phase_track(result, key, threshold: float = 1e-3):
    """Per-frame phase code ``(F,)`` of one action of a :class:`~kinodyn.blend.script.BlendResult` and the
    frames where it plays with weight above ``threshold`` ``(F,)``."""
    rec = result.recording.arrays()
    h, w = rec[key]
    act = result.actions[key]
    on = (w > threshold) & np.isfinite(h)
    codes = np.zeros(len(h), dtype=np.int8)
    codes[on] = act.seq.phase_at(h[on])
    return codes, on


def plot_phases(result, path, title: str | None = None, compare=None) -> Path:
    """Support-phase bars of every action and of the result (figure 9), weights underneath.

    Args:
        result: a :class:`~kinodyn.blend.script.BlendResult`.
        path: PNG file to write.
        compare: optionally the unsynchronized result of the same script, drawn as a last bar.
    """
    plt = pyplot()
    from matplotlib.patches import Patch

    rec = result.recording.arrays()
    t = rec["t"]
    keys = [k for k in rec if k not in ("t", "neutral")]
    rows = [(k, *action_phase_track(result, k)) for k in keys]
    res = result.frame_phases()
    rows.append(("result (synchronized)" if result.synchronized else "result", res,
                 np.ones(len(res), bool)))
    if compare is not None:
        rows.append(("without synchronization", compare.frame_phases(), np.ones(len(t), bool)))
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(12, 1.0 + 0.45 * len(rows) + 2.2), sharex=True,
                                  gridspec_kw={"height_ratios": [len(rows), 3]})
    for y, (label, codes, on) in enumerate(rows[::-1]):
        for t0, t1, c in _runs(t, codes, on):
            ax.broken_barh([(t0, t1 - t0)], (y - 0.35, 0.7), color=PHASE_COLORS[c], linewidth=0)
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels([r[0] for r in rows[::-1]])
    ax.axhline(len(rows) - len(keys) - 0.5, color="k", lw=0.8)
    ax.legend(handles=[Patch(color=PHASE_COLORS[int(p)], label=phase_name(p)) for p in (RS, LS, DS, FLIGHT, ERR)],
              loc="upper center", ncol=5, bbox_to_anchor=(0.5, 1.02 + 0.6 / len(rows)), frameon=False)
    ax.set_title(title or "Support phases of the actions and of the blend", pad=24)
    for k in keys:
        ax2.plot(t, rec[k][1], label=k)
    ax2.plot(t, rec["neutral"], "k:", label="neutral pose")
    ax2.set_ylabel("weight")
    ax2.set_xlabel("time (s)")
    ax2.set_ylim(-0.02, 1.02)
    ax2.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8, frameon=False)
    return _save(fig, path)


def plot_timewarp(result, path, keys=None, title: str | None = None) -> Path:
    """Each action's time warp: knots, the piecewise-linear warp and the cardinal spline actually played
    (figure 10), with the action's speed ``dH/dt`` underneath (continuous for the spline)."""
    plt = pyplot()

    timing = result.timing
    if timing is None:
        raise ValueError("the result was not synchronized: there is no time warp to plot")
    keys = [k for k in (keys or list(timing)) if k in timing and timing[k].segments]
    fig, axes = plt.subplots(2, 1, figsize=(12, 7), sharex=True)
    for i, k in enumerate(keys):
        tm = timing[k]
        col = f"C{i % 10}"
        segs = tm.segments
        kt = np.array([s.t0 for s in segs] + [segs[-1].t1])
        kh = np.array([s.coef[0] for s in segs] + [_poly(segs[-1].coef, segs[-1].t1 - segs[-1].t0)])
        h0 = kh[0]
        axes[0].plot(kt, kh - h0, "o--", color=col, ms=3, lw=0.8, alpha=0.7)
        tt, hh, vv = [], [], []
        for s in segs:
            u = np.linspace(0.0, s.t1 - s.t0, 12)
            tt.append(s.t0 + u)
            hh.append(_poly(s.coef, u))
            vv.append(s.coef[1] + 2 * s.coef[2] * u + 3 * s.coef[3] * u * u)
        tt, hh, vv = np.concatenate(tt), np.concatenate(hh), np.concatenate(vv)
        axes[0].plot(tt, hh - h0, "-", color=col, lw=1.6, label=f"{k}")
        sec = np.diff(kh) / np.diff(kt)
        axes[1].step(kt[:-1], sec, where="post", color=col, lw=0.8, ls="--", alpha=0.7)
        axes[1].plot(tt, vv, "-", color=col, lw=1.6)
    axes[0].set_ylabel("action time - start (s)")
    axes[0].set_title(title or "Time warps: piecewise linear (dashed, knots) and cardinal spline (solid)")
    axes[0].legend(fontsize=8, frameon=False)
    axes[1].set_ylabel("speed dH/dt")
    axes[1].set_xlabel("real time (s)")
    return _save(fig, path)


def _poly(c, u):
    return ((c[3] * u + c[2]) * u + c[1]) * u + c[0]


def plot_feet(motions: dict, path, labels: dict | None = None, title: str | None = None, spans=None) -> Path:
    """Foot height and horizontal speed of the lowest foot point, for several blends of one script.

    Args:
        motions: ``{label: Motion}``.
        path: PNG file.
        labels: optional ``{label: {side: (F,) bool}}`` contact frames to shade.
        spans: optional ``[(t0, t1)]`` transition intervals to shade.
    """
    plt = pyplot()

    from kinodyn import contacts

    fig, axes = plt.subplots(4, 1, figsize=(12, 9), sharex=True)
    for i, (name, m) in enumerate(motions.items()):
        c = contacts.detect(m, contacts.ContactConfig(floor=0.0))
        t = m.times()
        for j, side in enumerate(("left", "right")):
            ax_h, ax_v = axes[2 * j], axes[2 * j + 1]
            ax_h.plot(t, c.lowest[side][:, 2], color=f"C{i}", lw=1, label=name)
            sp = np.linalg.norm(c.lowest_velocity[side][:, :2], axis=-1)
            ax_v.plot(t, sp, color=f"C{i}", lw=1, label=name)
            if labels and name in labels:
                lab = labels[name][side]
                ax_v.fill_between(t, 0, np.where(lab, sp, np.nan), color=f"C{i}", alpha=0.25, lw=0)
            ax_h.set_ylabel(f"{side} foot\nheight (m)")
            ax_v.set_ylabel(f"{side} foot\nspeed (m/s)")
            ax_v.set_ylim(0, 4)
    for ax in axes:
        for t0, t1 in (spans or []):
            ax.axvspan(t0, t1, color="0.9", zorder=-1)
    axes[0].legend(fontsize=8, frameon=False, ncol=len(motions))
    axes[0].set_title(title or "Feet: height and horizontal speed (shaded: frames that should be planted)")
    axes[-1].set_xlabel("time (s)")
    return _save(fig, path)
