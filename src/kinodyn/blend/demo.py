"""Demo part ``blend``: the transitions of the paper's figures 12 and 13 on the built-in clips.

A walk, a run, a walk at another speed (figure 12), then a fighting move (a kick), another walk and a
jump (figure 13), blended with and without support-phase synchronization. Writes under ``out/blend``:
the two BVH files, the support-phase bars (figure 9), the time warps (figure 10), the feet's height
and speed in both blends, and ``sliding.json`` with the foot-sliding figures.
"""

from __future__ import annotations

import json
from pathlib import Path

from kinodyn.blend.transitions import blend_stats, sliding_figures, transition_script

__all__ = ["blend_stats", "demo", "sliding_figures", "transition_script"]


def demo(out: Path) -> list[str]:
    from kinodyn.blend import plots
    from kinodyn.blend.script import intended_contacts
    from kinodyn.contacts import intervals
    from kinodyn.io import save
    from kinodyn.io.atomic import atomic_write_bytes

    d = Path(out) / "blend"
    d.mkdir(parents=True, exist_ok=True)
    script = transition_script()
    results: dict = {}
    figs = sliding_figures(script, results=results)
    syn, uns = results["synced"], results["unsynced"]
    save(d / "fig12_synced.bvh", syn.motion)
    save(d / "fig12_unsynced.bvh", uns.motion)
    plots.plot_phases(syn, d / "fig12_phases.png", compare=uns,
                      title="Figures 9/12/13: support phases of the actions, of the synchronized blend and "
                            "of the blend without synchronization")
    plots.plot_timewarp(syn, d / "fig12_timewarp.png")
    mask = syn.transition_mask()
    spans = [(a / syn.motion.fps, b / syn.motion.fps) for a, b in intervals(mask)]
    plots.plot_feet({"synchronized": syn.motion, "not synchronized": uns.motion}, d / "fig12_feet.png",
                    labels={"synchronized": intended_contacts(syn), "not synchronized": intended_contacts(uns)},
                    spans=spans)
    atomic_write_bytes(d / "sliding.json", (json.dumps(figs, indent=2) + "\n").encode())
    s, u = figs["synced"], figs["unsynced"]
    delays = [f"{k} +{b - a:.2f} s" for k, (a, b) in s["starts"].items() if b is not None and b - a > 1e-6]
    return [
        f"figure 12/13 script: {syn.motion.num_frames} frames, {len(syn.starts)} actions -> {d}/fig12_*.bvh",
        f"foot sliding synchronized {s['sliding_cm_s']:.2f} cm/s vs not synchronized {u['sliding_cm_s']:.2f} cm/s "
        f"(x{figs['sliding_ratio']:.1f}); in transitions {s['transition_sliding_cm_s']:.1f} vs "
        f"{u['transition_sliding_cm_s']:.1f} cm/s (x{figs['sliding_ratio_transitions']:.1f})",
        f"frames mixing a right and a left single support: {s['err_frames']} synchronized, {u['err_frames']} not",
        f"starts delayed to a compatible step boundary: {', '.join(delays) or 'none'}",
        f"ablations: synchronized without constraints {figs['synced_plain']['sliding_cm_s']:.2f} cm/s, "
        f"constraints without synchronization {figs['unsynced_constrained']['sliding_cm_s']:.2f} cm/s",
        f"plots: {d}/fig12_phases.png, fig12_timewarp.png, fig12_feet.png; figures in {d}/sliding.json",
    ]

