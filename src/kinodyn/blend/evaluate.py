"""One blending evaluation: synchronization and the foot lock, each on and off, measured like with like.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, section 6: synchronizing the support
phases should keep the feet from sliding. To tell what synchronization itself does from what the support
constraints after blending (:mod:`kinodyn.blend.footlock`) do, :func:`evaluate` plays one script four
ways, everything else equal (:data:`ARMS`): ``plain`` (neither), ``sync`` (synchronization only),
``lock`` (the foot lock only) and ``sync_lock`` (both). Every arm is measured with rules that none of
them defines:

- **sliding on source contacts**: contacts are detected on each *source clip*
  (:func:`kinodyn.contacts.detect`) and mapped onto the blend through the mixer's record (each action's
  clip time at each frame); a foot counts as planted in a frame when the source of the action with the
  most weight there (the neutral pose: both feet) has it down. This is neither the lock's weighted vote
  of support phases nor the synchronizer's sequences. The figure is the mean horizontal speed of the
  foot's lowest point over those frames (cm/s), also over the transitions only.
- **sliding on detected contacts**: :func:`kinodyn.contacts.sliding` on contacts detected on the
  result (it cannot see a foot sliding faster than the detector's speed threshold).
- **lock displacement**: how far the lock holds each held foot from where the blended pose puts it
  (:meth:`~kinodyn.blend.actions.Recording.lock_offsets`): mean, p95, max (cm); :func:`lock_events`
  says where (the spans beyond a threshold, the foot, the actions and their weights).
- **RS+LS frames**: frames where a right and a left single support of contributing actions meet.
- **pelvis acceleration**: peak norm of the root's second difference (m/s^2), against the sources'
  peak measured the same way at the script's frame rate and the action's speed; **root deceleration**:
  peak drop rate of the root's horizontal speed (smoothed over 0.1 s, m/s^2), likewise.
- **lowest foot point** (cm above the floor at 0) and the **time-warp rates** (action time per second)
  of every action while it carries at least 5 % of the weight.

The headline ratios compare arms that differ only in synchronization (:func:`headline`).

Shapes: ``F`` frames. Units: centimetres and cm/s in the reports, m/s^2 for accelerations.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ARMS", "SourceContacts", "evaluate", "headline", "lock_events", "measure", "source_contacts",
           "source_peaks"]

#: ``(name, synchronize, foot lock)`` of the four arms.
ARMS = (("plain", False, False), ("sync", True, False), ("lock", False, True), ("sync_lock", True, True))
#: Weight under which an action's time warp is not counted (it barely shows).
WARP_WEIGHT = 0.05
#: Seconds the root's horizontal speed is averaged over before its deceleration is taken.
DECEL_WINDOW = 0.1


class SourceContacts:
    """Foot contacts detected on every clip of a store: ``labels[k]`` is ``(F_k, 2)`` bool (left, right)."""

    def __init__(self, store, config=None):
        from kinodyn import contacts

        cfg = config or contacts.ContactConfig()
        self.labels = []
        for k in range(len(store)):
            c = contacts.detect(store.motion(k), cfg)
            self.labels.append(c.as_array())
        self.store = store

    def at(self, clip: int, tau) -> np.ndarray:
        """``(F, 2)`` labels of clip ``clip`` at clip times ``tau (F,)`` (cyclic clips wrap, others clamp)."""
        st = self.store
        lab = self.labels[clip]
        dur = float(st.durations[clip])
        tau = np.asarray(tau, dtype=np.float64)
        u = np.mod(tau, dur) if st.is_cyclic[clip] else np.clip(tau, 0.0, dur)
        i = np.clip(np.rint(u * st.fps[clip]).astype(np.int64), 0, len(lab) - 1)
        return lab[i]


def source_contacts(result, sources: SourceContacts | None = None) -> dict:
    """``{side: (F,) bool}``: frames where the source clip of the heaviest action (or the neutral pose)
    has that foot down, mapped through the record of ``result`` (a :class:`~kinodyn.blend.script.BlendResult`)."""
    src = sources or SourceContacts(result.library)
    rec = result.recording.arrays()
    n = result.motion.num_frames
    best = np.array(rec["neutral"][:n], dtype=np.float64)
    lab = np.ones((n, 2), dtype=bool)
    for k, act in result.actions.items():
        if k not in rec:
            continue
        h, w = rec[k]
        h, w = h[:n], w[:n]
        on = np.isfinite(h) & (w > best)
        if not on.any():
            continue
        lab[on] = src.at(act.clip, h[on] * act.speed)
        best = np.where(on, w, best)
    return {"left": lab[:, 0], "right": lab[:, 1]}


def source_peaks(result) -> dict:
    """Peak pelvis acceleration and horizontal root deceleration (m/s^2) of the clips ``result`` played,
    at the script's frame rate and each action's speed (accelerations scale with its square)."""
    st = result.library
    fps = result.motion.fps
    acc = dec = 0.0
    for act in result.actions.values():
        if act.t_on is None:
            continue
        m = st.motion(act.clip)
        if abs(m.fps - fps) > 1e-6:
            m = m.resample(fps)
        a, d = _root_peaks(m.root_pos, fps)
        acc = max(acc, a * act.speed ** 2)
        dec = max(dec, d * act.speed ** 2)
    return {"pelvis_acc": acc, "root_decel": dec}


def _root_peaks(p, fps: float) -> tuple[float, float]:
    """Peak acceleration norm and peak horizontal deceleration of a root path ``p (F, 3)``."""
    if len(p) < 3:
        return 0.0, 0.0
    acc = float(np.linalg.norm(p[2:] - 2 * p[1:-1] + p[:-2], axis=1).max() * fps * fps)
    speed = np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1) * fps
    w = max(int(round(DECEL_WINDOW * fps)), 1)
    if len(speed) > w:
        speed = np.convolve(speed, np.ones(w) / w, mode="valid")
    dec = float(max(-(np.diff(speed).min()) * fps, 0.0)) if len(speed) > 1 else 0.0
    return acc, dec


def _sliding(speed, labels, frames=None) -> float:
    """Mean of ``speed {side: (F,)}`` over ``labels {side: (F,) bool}`` (and ``frames``), in cm/s."""
    vals = []
    for s in ("left", "right"):
        m = labels[s] if frames is None else labels[s] & frames
        vals.append(speed[s][m])
    v = np.concatenate(vals)
    return float(100.0 * v.mean()) if len(v) else 0.0


def measure(result, sources: SourceContacts | None = None) -> dict:
    """Every figure of one blended script (see the module docstring)."""
    from kinodyn import contacts
    from kinodyn.phases import ERR

    m = result.motion
    det = contacts.detect(m, contacts.ContactConfig(floor=0.0))
    speed = {s: np.linalg.norm(det.lowest_velocity[s][:, :2], axis=1) for s in contacts.SIDES}
    lab = source_contacts(result, sources)
    trans = result.transition_mask()
    off = result.recording.lock_offsets()[:m.num_frames]
    held = off[np.isfinite(off)] * 100.0
    pts = contacts.foot_points(m)
    acc, dec = _root_peaks(m.root_pos, m.fps)
    peaks = source_peaks(result)
    rates = []
    rec = result.recording.arrays()
    for k in result.actions:
        if k in rec:
            h, w = rec[k]
            ok = np.isfinite(h[1:]) & np.isfinite(h[:-1]) & (w[1:] >= WARP_WEIGHT) & (w[:-1] >= WARP_WEIGHT)
            rates.append(np.diff(h)[ok] * m.fps)
    rates = np.concatenate(rates) if rates else np.ones(1)
    return {
        "sliding_cm_s": _sliding(speed, lab),
        "transition_sliding_cm_s": _sliding(speed, lab, trans),
        "planted_frames": int(sum(lab[s].sum() for s in lab)),
        "detected_sliding_cm_s": contacts.sliding(m, det).cm_per_s,
        "lock_mean_cm": float(held.mean()) if len(held) else 0.0,
        "lock_p95_cm": float(np.percentile(held, 95)) if len(held) else 0.0,
        "lock_max_cm": float(held.max()) if len(held) else 0.0,
        "err_frames": int((result.frame_phases() == ERR).sum()),
        "pelvis_acc": acc, "pelvis_acc_source": peaks["pelvis_acc"],
        "root_decel": dec, "root_decel_source": peaks["root_decel"],
        "lowest_foot_cm": float(100.0 * min(p[..., 2].min() for p in pts.values())),
        "warp_rate_min": float(rates.min()) if len(rates) else 1.0,
        "warp_rate_max": float(rates.max()) if len(rates) else 1.0,
        "frames": int(m.num_frames),
        "starts": {str(k): [round(a, 4), None if b is None else round(b, 4)] for k, (a, b) in result.starts.items()},
    }


def lock_events(result, above_cm: float = 3.0) -> list[dict]:
    """Where the lock displaces held feet most: every span of frames where it holds a foot more than
    ``above_cm`` from where the blended pose puts it (:meth:`~kinodyn.blend.actions.Recording.lock_offsets`),
    worst first.

    Each event: ``t0``, ``t1`` (seconds, first and last frame), ``frames``, ``t_peak``, ``peak_cm``, the
    ``foot`` displaced most there (``"left"``/``"right"``), ``left_cm``, ``right_cm`` (NaN: not held),
    ``neutral`` (the neutral pose's weight) and ``weights`` (every action's weight over 1 %) at the peak.
    """
    rec = result.recording.arrays()
    n = result.motion.num_frames
    off = result.recording.lock_offsets()[:n] * 100.0
    worst = np.nan_to_num(off, nan=0.0).max(axis=1)
    edge = np.diff(np.concatenate([[0], (worst > above_cm).astype(np.int8), [0]]))
    t = rec["t"]
    events = []
    for a, b in zip(np.nonzero(edge == 1)[0], np.nonzero(edge == -1)[0]):   # one pass per event
        i = int(a + np.argmax(worst[a:b]))
        lr = np.nan_to_num(off[i], nan=-1.0)
        events.append({"t0": float(t[a]), "t1": float(t[b - 1]), "frames": int(b - a), "t_peak": float(t[i]),
                       "peak_cm": float(worst[i]), "foot": "left" if lr[0] >= lr[1] else "right",
                       "left_cm": float(off[i, 0]), "right_cm": float(off[i, 1]),
                       "neutral": float(rec["neutral"][i]),
                       "weights": {str(k): round(float(rec[k][1][i]), 3) for k in result.actions
                                   if k in rec and rec[k][1][i] > 0.01}})
    return sorted(events, key=lambda e: -e["peak_cm"])


def _ratio(a: float, b: float) -> float:
    return float(a / b) if b > 0 else float("inf")


def headline(arms: dict) -> dict:
    """The ratios between arms that differ in one thing only.

    ``sliding_ratio``: lock alone over sync + lock (what synchronization adds to the lock);
    ``sliding_ratio_sync_only``: plain over sync (what synchronization does alone); ``lock_p95_ratio``:
    the lock's p95 displacement without synchronization over with it; ``pelvis_acc_ratio`` and
    ``root_decel_ratio``: sync + lock over the sources' peaks.
    """
    s, l, p, so = arms["sync_lock"], arms["lock"], arms["plain"], arms["sync"]
    return {
        "sliding_ratio": _ratio(l["sliding_cm_s"], s["sliding_cm_s"]),
        "sliding_ratio_sync_only": _ratio(p["sliding_cm_s"], so["sliding_cm_s"]),
        "sliding_ratio_detected_sync_only": _ratio(p["detected_sliding_cm_s"], so["detected_sliding_cm_s"]),
        "sliding_cm_s_synced": s["sliding_cm_s"],
        "lock_p95_cm": s["lock_p95_cm"],
        "lock_max_cm": s["lock_max_cm"],
        "lock_p95_ratio": _ratio(l["lock_p95_cm"], s["lock_p95_cm"]),
        "pelvis_acc_ratio": _ratio(s["pelvis_acc"], s["pelvis_acc_source"]),
        "root_decel_ratio": _ratio(s["root_decel"], s["root_decel_source"]),
    }


def evaluate(script, library=None, results: dict | None = None, warp=None, **options) -> dict:
    """Play ``script`` in the four :data:`ARMS` and measure each (:func:`measure`).

    Args:
        script: a :class:`~kinodyn.blend.script.Script`.
        library: its :class:`~kinodyn.clips.ClipStore` (default: :func:`~kinodyn.blend.script.build_library`).
        results: a dict to receive the four :class:`~kinodyn.blend.script.BlendResult` objects by arm.
        warp: a :class:`~kinodyn.blend.timewarp.WarpConfig` for every arm (default: the mixer's).
        options: further :class:`~kinodyn.blend.mixer.BlendConfig` fields, the same in every arm (the
            arms still differ in synchronization and the lock only).

    Returns:
        ``{"arms": {arm: figures}, **headline(arms)}``.
    """
    from kinodyn.blend.mixer import BlendConfig
    from kinodyn.blend.script import build_library, run_script
    from kinodyn.blend.sync import SyncConfig

    lib = library or build_library(script)
    sources = SourceContacts(lib)
    arms = {}
    for name, sync, lock in ARMS:
        cfg = BlendConfig(synchronize=sync, constraints="on" if lock else "off", sync=SyncConfig(nk=script.nk),
                          ramp_in=script.ramp_in, ramp_out=script.ramp_out,
                          **({} if warp is None else {"warp": warp}), **options)
        r = run_script(script, library=lib, config=cfg)
        if results is not None:
            results[name] = r
        arms[name] = measure(r, sources)
    return {"arms": arms, **headline(arms)}


def table(figs: dict, label: str = "") -> str:
    """The four-arm table of :func:`evaluate`'s figures, as text."""
    cols = (("sliding_cm_s", "slide"), ("transition_sliding_cm_s", "trans"), ("detected_sliding_cm_s", "detect"),
            ("lock_mean_cm", "lk_mean"), ("lock_p95_cm", "lk_p95"), ("lock_max_cm", "lk_max"), ("err_frames", "RS+LS"),
            ("pelvis_acc", "acc"), ("root_decel", "decel"), ("lowest_foot_cm", "low_cm"), ("warp_rate_min", "wmin"),
            ("warp_rate_max", "wmax"))
    lines = [label] if label else []
    lines.append(f"{'arm':<10}" + "".join(f"{c:>9}" for _, c in cols))
    for arm, f in figs["arms"].items():
        lines.append(f"{arm:<10}" + "".join(f"{f[k]:9.2f}" for k, _ in cols))
    s = figs["arms"]["sync_lock"]
    lines.append(f"sources: acc {s['pelvis_acc_source']:.1f}, decel {s['root_decel_source']:.1f} m/s^2; "
                 + ", ".join(f"{k} {figs[k]:.2f}" for k in ("sliding_ratio", "sliding_ratio_sync_only", "lock_p95_ratio",
                                                           "pelvis_acc_ratio", "root_decel_ratio")))
    return "\n".join(lines)
