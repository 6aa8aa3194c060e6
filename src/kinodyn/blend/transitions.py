"""The transitions of the paper's figures 12 and 13 on the built-in clips, and their foot sliding.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, section 6 (figures 12 and 13): a walk,
a run, a walk at another speed, then a fighting move (a kick), another walk and a jump, blended with and
without synchronization. :func:`sliding_figures` measures the foot sliding of each variant with a
measure neither side defines (the actions' own support phases, and contacts detected on the result);
the demo part and the benchmark both report it.
"""

from __future__ import annotations

__all__ = ["blend_stats", "sliding_figures", "transition_script"]


def transition_script():
    """The figure 12/13 script (the same as ``examples/blend_fig12.yaml``)."""
    from kinodyn.blend.script import parse_script

    return parse_script({
        "name": "blend_fig12", "fps": 60, "synchronize": True, "nk": 5, "ramp_in": 0.5, "ramp_out": 0.5,
        "actions": [
            {"clip": "walk", "start": 0.0, "stop": 3.0, "priority": 1},
            {"clip": "run", "start": 2.8, "stop": 6.0, "priority": 1},
            {"clip": "walk", "start": 5.8, "stop": 8.5, "priority": 1, "speed": 1.25, "key": "fast_walk"},
            {"clip": "kick", "start": 8.2, "priority": 2},
            {"clip": "walk", "start": 9.6, "stop": 12.0, "priority": 1, "key": "walk_again"},
            {"clip": "jump", "start": 11.8, "priority": 2},
        ]})


def blend_stats(result) -> dict:
    """Foot sliding and support-phase conflicts of one blended script (see
    :func:`kinodyn.blend.script.sliding_report`)."""
    from kinodyn import contacts
    from kinodyn.phases import ERR
    from kinodyn.blend.script import sliding_report

    whole = sliding_report(result)
    trans = sliding_report(result, frames=result.transition_mask())
    m = result.motion
    det = contacts.sliding(m, contacts.detect(m, contacts.ContactConfig(floor=0.0)))
    return {"sliding_cm_s": whole.cm_per_s, "sliding_p95_cm_s": 100 * whole.p95,
            "planted_frames": whole.contact_frames, "transition_sliding_cm_s": trans.cm_per_s,
            "transition_planted_frames": trans.contact_frames, "detected_sliding_cm_s": det.cm_per_s,
            "detected_contact_frames": det.contact_frames, "err_frames": int((result.frame_phases() == ERR).sum()),
            "frames": m.num_frames,
            "starts": {str(k): [round(a, 4), None if b is None else round(b, 4)] for k, (a, b) in result.starts.items()}}


def sliding_figures(script, library=None, results: dict | None = None) -> dict:
    """Blend ``script`` four ways and compare foot sliding.

    ``synced`` (the default: synchronization with support constraints), ``unsynced`` (the plain blend,
    the paper's baseline), and two ablations: ``synced_plain`` (synchronization without constraints) and
    ``unsynced_constrained`` (the same constraints enforced on the unsynchronized blend). Pass a dict as
    ``results`` to receive the four :class:`~kinodyn.blend.script.BlendResult` objects.
    """
    from kinodyn.blend.mixer import BlendConfig
    from kinodyn.blend.script import build_library, run_script
    from kinodyn.blend.sync import SyncConfig

    lib = library or build_library(script)
    out = {}
    variants = {"synced": (True, "auto"), "unsynced": (False, "auto"), "synced_plain": (True, "off"),
                "unsynced_constrained": (False, "on")}
    for name, (sync, cons) in variants.items():
        cfg = BlendConfig(synchronize=sync, constraints=cons, sync=SyncConfig(nk=script.nk),
                          ramp_in=script.ramp_in, ramp_out=script.ramp_out)
        r = run_script(script, library=lib, config=cfg)
        if results is not None:
            results[name] = r
        out[name] = blend_stats(r)

    def ratio(a, b):
        return float(a / b) if b > 0 else float("inf")

    s, u = out["synced"], out["unsynced"]
    out["sliding_ratio"] = ratio(u["sliding_cm_s"], s["sliding_cm_s"])
    out["sliding_ratio_transitions"] = ratio(u["transition_sliding_cm_s"], s["transition_sliding_cm_s"])
    out["sliding_ratio_detected"] = ratio(u["detected_sliding_cm_s"], s["detected_sliding_cm_s"])
    out["measure"] = ("sliding: mean horizontal speed of the lowest foot point over the frames where the "
                      "actions' support phases put that foot down (weighted vote); transitions: the frames "
                      "where two or more actions have weight; detected: kinodyn.contacts.sliding with "
                      "contacts detected on the result (height and speed thresholds)")
    return out
