"""Demo part ``blend``: the transitions of the paper's figures 12 and 13 on the built-in clips.

A walk, a run, a walk at another speed (figure 12), then a fighting move (a kick), another walk and a
jump (figure 13), blended four ways (synchronization and the foot lock on or off, :mod:`kinodyn.blend.evaluate`). Writes
under ``out/blend``: the blends with the foot lock with and without synchronization (BVH), the
support-phase bars (figure 9), the time warps (figure 10), the feet's height and speed in both, and
``sliding.json`` with the four-arm figures.
"""

from __future__ import annotations

import json
from pathlib import Path

from kinodyn.blend.transitions import transition_script

__all__ = ["demo", "transition_script"]


def demo(out: Path) -> list[str]:
    from kinodyn.blend import plots
    from kinodyn.blend.evaluate import evaluate, source_contacts
    from kinodyn.contacts import intervals
    from kinodyn.io import save
    from kinodyn.io.atomic import atomic_write_bytes

    d = Path(out) / "blend"
    d.mkdir(parents=True, exist_ok=True)
    script = transition_script()
    results: dict = {}
    figs = evaluate(script, results=results)
    syn, uns = results["sync_lock"], results["lock"]   # the same foot lock, with and without synchronization
    save(d / "fig12_synced.bvh", syn.motion)
    save(d / "fig12_unsynced.bvh", uns.motion)
    plots.plot_phases(syn, d / "fig12_phases.png", compare=uns,
                      title="Figures 9/12/13: support phases of the actions, of the synchronized blend and "
                            "of the blend without synchronization")
    plots.plot_timewarp(syn, d / "fig12_timewarp.png")
    mask = syn.transition_mask()
    spans = [(a / syn.motion.fps, b / syn.motion.fps) for a, b in intervals(mask)]
    plots.plot_feet({"synchronized": syn.motion, "not synchronized": uns.motion}, d / "fig12_feet.png",
                    labels={"synchronized": source_contacts(syn), "not synchronized": source_contacts(uns)},
                    spans=spans)
    atomic_write_bytes(d / "sliding.json", (json.dumps(figs, indent=2) + "\n").encode())
    a = figs["arms"]
    delays = [f"{k} +{b - s:.2f} s" for k, (s, b) in a["sync_lock"]["starts"].items() if b is not None and b - s > 1e-6]
    return [
        f"figure 12/13 script: {syn.motion.num_frames} frames, {len(syn.starts)} actions -> {d}/fig12_*.bvh "
        "(foot lock on, with and without synchronization)",
        "foot sliding on the source clips' contacts, cm/s: " + ", ".join(f"{k} {v['sliding_cm_s']:.2f}" for k, v in a.items())
        + f" (synchronization with the lock x{figs['sliding_ratio']:.2f}, alone x{figs['sliding_ratio_sync_only']:.2f})",
        f"held feet from the blended pose, p95/max cm: lock {a['lock']['lock_p95_cm']:.1f}/{a['lock']['lock_max_cm']:.1f}, "
        f"sync+lock {a['sync_lock']['lock_p95_cm']:.1f}/{a['sync_lock']['lock_max_cm']:.1f}",
        f"frames mixing a right and a left single support: {a['sync_lock']['err_frames']} synchronized, "
        f"{a['lock']['err_frames']} not; peak pelvis acceleration x{figs['pelvis_acc_ratio']:.2f} the sources'",
        f"starts delayed to a compatible step boundary: {', '.join(delays) or 'none'}",
        f"plots: {d}/fig12_phases.png, fig12_timewarp.png, fig12_feet.png; figures in {d}/sliding.json",
    ]
