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
- **sliding by cause** (:func:`sliding_causes`): that sliding split into contributions that add up to
  it exactly, each measured against the source clip of the heaviest action at the clip time played:
  ``own`` (the source foot's own sliding there: real capture slides), ``warp`` (the clip played off its
  speed by the time warp), ``weights`` (weight moving between clips whose feet stand at different places
  from the root), ``root`` (the blended root moving unlike the source's root), ``pose`` (the rest of the
  blended pose moving the foot relative to the root unlike the source); and by frames: one action
  alone, transitions, and of those the ``swing`` frames (another weighted action has that foot up).
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

__all__ = ["ARMS", "CAUSES", "GROUPS", "SourceContacts", "causes_table", "evaluate", "headline", "lock_events",
           "measure", "sliding_causes", "source_contacts", "source_peaks"]

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
        from kinodyn.kinematics import linear_velocity

        cfg = config or contacts.ContactConfig()
        self.labels, self.foot_velocity, self.root_velocity, self.heading, self.foot_offset = [], [], [], [], []
        for k in range(len(store)):
            m = store.motion(k)
            c = contacts.detect(m, cfg)
            self.labels.append(c.as_array())
            self.foot_velocity.append(np.stack([c.lowest_velocity[s][:, :2] for s in contacts.SIDES], axis=1))
            self.root_velocity.append(linear_velocity(m.root_pos, m.fps)[:, :2])
            pts = contacts.foot_points(m)
            self.foot_offset.append([pts[s][..., :2] - m.root_pos[:, None, :2] for s in contacts.SIDES])
            self.heading.append(np.unwrap(m.ground()[:, 2]))
        self.store = store

    def _frames(self, clip: int, tau) -> np.ndarray:
        """``(F,)`` fractional frames of clip ``clip`` at clip times ``tau (F,)`` (cyclic clips wrap, others clamp)."""
        st = self.store
        dur = float(st.durations[clip])
        tau = np.asarray(tau, dtype=np.float64)
        u = np.mod(tau, dur) if st.is_cyclic[clip] else np.clip(tau, 0.0, dur)
        return np.clip(u * st.fps[clip], 0.0, len(self.labels[clip]) - 1)

    def at(self, clip: int, tau) -> np.ndarray:
        """``(F, 2)`` labels of clip ``clip`` at clip times ``tau (F,)`` (the nearest frame's)."""
        return self.labels[clip][np.rint(self._frames(clip, tau)).astype(np.int64)]

    def sample(self, values, clip: int, tau) -> np.ndarray:
        """Per-frame ``values (F_k, ...)`` of clip ``clip`` interpolated at clip times ``tau (F,)``, as the
        mixer samples the clip (between the two frames around each time)."""
        x = self._frames(clip, tau)
        i0 = np.minimum(np.floor(x).astype(np.int64), len(values) - 1)
        i1 = np.minimum(i0 + 1, len(values) - 1)
        a = (x - i0).reshape((-1,) + (1,) * (np.ndim(values) - 1))
        return values[i0] * (1.0 - a) + values[i1] * a


def _played(result) -> tuple[list, np.ndarray, np.ndarray, np.ndarray]:
    """The recorded actions of ``result``: their keys, ``(A, F)`` action times and weights (NaN, 0 where
    absent), and the ``(F,)`` neutral weight."""
    rec = result.recording.arrays()
    n = result.motion.num_frames
    keys = [k for k in result.actions if k in rec]
    h = np.array([rec[k][0][:n] for k in keys]).reshape(len(keys), n)
    w = np.array([rec[k][1][:n] for k in keys]).reshape(len(keys), n)
    return keys, h, w, np.array(rec["neutral"][:n], dtype=np.float64)


def _dominant(w, wn) -> np.ndarray:
    """``(F,)`` index of the action with the most weight in each frame, -1 where the neutral pose has at
    least as much (the first of equal actions wins)."""
    if not len(w):
        return np.full(len(wn), -1)
    best = np.argmax(w, axis=0)
    return np.where(w[best, np.arange(len(wn))] > wn, best, -1)


def source_contacts(result, sources: SourceContacts | None = None) -> dict:
    """``{side: (F,) bool}``: frames where the source clip of the heaviest action (or the neutral pose)
    has that foot down, mapped through the record of ``result`` (a :class:`~kinodyn.blend.script.BlendResult`)."""
    src = sources or SourceContacts(result.library)
    keys, h, w, wn = _played(result)
    dom = _dominant(np.where(np.isfinite(h), w, 0.0), wn)
    lab = np.ones((len(wn), 2), dtype=bool)
    for a, k in enumerate(keys):
        on = dom == a
        if on.any():
            act = result.actions[k]
            lab[on] = src.at(act.clip, h[a, on] * act.speed)
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


def _rotate(v, angle) -> np.ndarray:
    """Horizontal vectors ``v (..., 2)`` turned by ``angle (...)`` radians about +Z."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def _clip_rates(h, speed, fps: float) -> np.ndarray:
    """``(F,)`` clip seconds per second of an action played at action times ``h (F,)`` (the time warp
    times its speed); its nominal ``speed`` where a neighbouring frame is missing."""
    r = np.full(len(h), np.nan)
    if len(h) > 1:
        r = np.gradient(h, 1.0 / fps) * speed
    return np.where(np.isfinite(r), r, speed)


#: The chain of counterfactual foot velocities of :func:`sliding_causes`, in order.
CAUSES = ("own", "warp", "weights", "root", "pose")
#: Frame groups of :func:`sliding_causes`.
GROUPS = ("alone", "transition", "swing")
#: Share of the total weight over which one action plays alone.
ALONE_WEIGHT = 0.95


def _offsets(src: SourceContacts, clip: int, tau, point, turn) -> np.ndarray:
    """``(F, 2, 2)`` horizontal offsets from the root of foot points ``point (F, 2)`` (left, right) of clip
    ``clip`` at clip times ``tau (F,)``, turned by ``turn (F,)``."""
    rows = np.arange(len(tau))
    out = [src.sample(src.foot_offset[clip][s], clip, tau)[rows, point[:, s]] for s in range(2)]
    return _rotate(np.stack(out, axis=1), turn[:, None])


def _source_side(result, src: SourceContacts, keys, h, dom, head, point):
    """What the sources bring at each frame, turned into the blend's heading: the heaviest action's
    lowest-point and root velocities per clip second ``(F, 2, 2)``, ``(F, 2)``, its clip rate and nominal
    speed ``(F,)``, the ``(K + 1, F, 2, 2)`` offsets from the root of the foot point ``point (F, 2)``
    (the blend's lowest) of every action and (last) the neutral pose (NaN where an action is not
    playing), and ``(K, F, 2)`` which feet each action's source has down."""
    from kinodyn.blend.library import neutral_source, sequences

    n = len(dom)
    foot, root, rate, nominal = np.zeros((n, 2, 2)), np.zeros((n, 2)), np.zeros(n), np.zeros(n)
    offset = np.full((len(keys) + 1, n, 2, 2), np.nan)
    down = np.ones((len(keys), n, 2), dtype=bool)
    nc, nt = neutral_source(result.library, sequences(result.library), result.script.neutral)
    offset[-1] = _offsets(src, nc, np.full(n, nt), point, head - src.sample(src.heading[nc], nc, np.full(n, nt)))
    for j, k in enumerate(keys):
        act = result.actions[k]
        live = np.isfinite(h[j])
        tau = h[j, live] * act.speed
        down[j, live] = src.at(act.clip, tau)
        turn = head[live] - src.sample(src.heading[act.clip], act.clip, tau)
        offset[j, live] = _offsets(src, act.clip, tau, point[live], turn)
        on = (dom == j)[live]
        if on.any():
            at = np.nonzero(live)[0][on]
            foot[at] = _rotate(src.sample(src.foot_velocity[act.clip], act.clip, tau[on]), turn[on, None])
            root[at] = _rotate(src.sample(src.root_velocity[act.clip], act.clip, tau[on]), turn[on])
            rate[at] = _clip_rates(h[j], act.speed, result.motion.fps)[at]
            nominal[at] = act.speed
    return foot, root, rate, nominal, offset, down


def sliding_causes(result, sources: SourceContacts | None = None) -> dict:
    """The sliding on source contacts (:func:`source_contacts`) split into measured causes that add up to it.

    Every planted foot-frame ``i`` (``N`` of them) has the blend's horizontal velocity ``U_i`` of the
    foot's lowest point; the sliding is ``sum |U_i| / N``. Counterfactual velocities lead from the
    heaviest action's source clip (sampled as the mixer samples it, turned into the blend's heading) to
    ``U_i``, each step changing one thing:

    - ``A``: the source's own lowest-point velocity at that clip time, at the action's nominal speed;
    - ``B``: the same at the clip rate actually played (the time warp's rate times the speed);
    - ``C``: ``B`` plus the weight shifts between feet at different places: ``sum_j dŵ_j/dt (o_j - o)``
      over the actions and the neutral pose, ``ŵ`` the weights over their total and ``o`` where a
      source puts the blend's lowest foot point relative to its root (``o`` the heaviest's): how far a
      linear mix of the sources' feet would move the foot while the weights ramp;
    - ``D``: ``C`` with the source's root velocity replaced by the blend's (the mix of the actions' root
      displacements and the support correction of ``root_motion="support"``: negative where it takes
      back the weight shifts or a clip's own sliding);
    - ``U``: the blend itself (the rest of how the blended pose moves the foot under the root unlike the
      source: other clips' moving feet, the rotation blend, and in the arms with the lock, the lock).

    ``own = |A|``, ``warp = |B| - |A|``, ``weights = |C| - |B|``, ``root = |D| - |C|``, ``pose = |U| - |D|``
    (each summed and divided by ``N``, cm/s): they add up to the sliding exactly; a negative one cancels
    sliding another brings. Where the neutral pose is heaviest its source is still (``A = B = 0``).
    The same sum is split by frames: ``alone`` (one weight is at least :data:`ALONE_WEIGHT` of the
    total), ``transition`` (the rest) and, of those, ``swing`` (another action with at least
    :data:`WARP_WEIGHT` of the weight has that foot up in its source). Returns
    ``{"sliding_<cause>_cm_s", "sliding_<group>_cm_s", "sliding_<group>_<cause>_cm_s", "share_<group>"
    (of the foot-frames), "sliding_cm_s", "planted_frames"}``.
    """
    from kinodyn import contacts
    from kinodyn.kinematics import linear_velocity

    src = sources or SourceContacts(result.library)
    m = result.motion
    det = contacts.detect(m, contacts.ContactConfig(floor=0.0))
    u = np.stack([det.lowest_velocity[s][:, :2] for s in contacts.SIDES], axis=1)  # (F, 2, 2)
    keys, h, w, wn = _played(result)
    w = np.where(np.isfinite(h), w, 0.0)
    dom = _dominant(w, wn)
    pts = contacts.foot_points(m)
    point = np.stack([pts[s][..., 2].argmin(axis=1) for s in contacts.SIDES], axis=1)  # ``det``'s lowest
    foot, root, rate, nominal, offset, down = _source_side(result, src, keys, h, dom, m.ground()[:, 2], point)
    total_w = np.maximum(w.sum(axis=0) + wn, 1e-12)
    shares = np.concatenate([w, wn[None]]) / total_w
    dshare = np.gradient(shares, 1.0 / m.fps, axis=1) if m.num_frames > 1 else np.zeros_like(shares)
    apart = np.nan_to_num(offset - offset[dom, np.arange(len(dom))][None])  # from the heaviest's foot
    a = foot * nominal[:, None, None]
    b = foot * rate[:, None, None]
    c = b + (dshare[..., None, None] * apart).sum(axis=0)
    d = c + (linear_velocity(m.root_pos, m.fps)[:, :2] - root * rate[:, None])[:, None, :]
    speeds = [np.linalg.norm(v, axis=-1) for v in (a, b, c, d, u)]  # (F, 2) each
    terms = dict(zip(CAUSES, [speeds[0]] + [speeds[i] - speeds[i - 1] for i in range(1, len(speeds))]))
    lab = source_contacts(result, src)
    planted = np.stack([lab[s] for s in contacts.SIDES], axis=1)
    alone = np.maximum(w.max(axis=0, initial=0.0), wn) >= ALONE_WEIGHT * total_w
    others = (w >= WARP_WEIGHT * total_w) & (np.arange(len(keys))[:, None] != dom[None])
    swing = (others[..., None] & ~down).any(axis=0) & ~alone[:, None]  # (F, 2)
    groups = {"alone": planted & alone[:, None], "transition": planted & ~alone[:, None], "swing": planted & swing}
    count = max(int(planted.sum()), 1)
    out = {f"sliding_{k}_cm_s": 100.0 * float(t[planted].sum()) / count for k, t in terms.items()}
    for g, sel in groups.items():
        out[f"sliding_{g}_cm_s"] = 100.0 * float(speeds[-1][sel].sum()) / count
        out[f"share_{g}"] = float(sel.sum()) / count
        out.update({f"sliding_{g}_{k}_cm_s": 100.0 * float(t[sel].sum()) / count for k, t in terms.items()})
    out["sliding_cm_s"] = 100.0 * float(speeds[-1][planted].sum()) / count
    out["planted_frames"] = int(planted.sum())
    return out


def measure(result, sources: SourceContacts | None = None) -> dict:
    """Every figure of one blended script (see the module docstring)."""
    from kinodyn import contacts
    from kinodyn.phases import ERR

    m = result.motion
    det = contacts.detect(m, contacts.ContactConfig(floor=0.0))
    speed = {s: np.linalg.norm(det.lowest_velocity[s][:, :2], axis=1) for s in contacts.SIDES}
    sources = sources or SourceContacts(result.library)
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
        "causes": sliding_causes(result, sources),
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
    return "\n".join(lines + [causes_table(figs)])


def causes_table(figs: dict) -> str:
    """The sliding of every arm split into its causes (:func:`sliding_causes`): contributions in cm/s that
    add up to ``slide``, by cause and by frame group, the transitions' by cause, and each group's share of
    the planted foot-frames."""
    cols = ([(f"sliding_{c}_cm_s", c) for c in CAUSES] + [(f"sliding_{g}_cm_s", g[:5]) for g in GROUPS]
            + [(f"sliding_transition_{c}_cm_s", f"tr_{c[:4]}") for c in CAUSES]
            + [(f"share_{g}", f"%{g[:5]}") for g in GROUPS])
    lines = [("sliding by cause (cm/s, adding up to slide): own = the source clip's own, warp = the time warp, "
              "weights = weight shifting between feet at different places, root = root motion unlike the "
              "source's, pose = the rest of the blended pose's foot motion; "
              "by frames: alone, transition, swing (another weighted action has the foot up)"),
             f"{'arm':<10}{'slide':>8}" + "".join(f"{c:>8}" for _, c in cols)]
    for arm, f in figs["arms"].items():
        c = f["causes"]
        lines.append(f"{arm:<10}{c['sliding_cm_s']:8.2f}" + "".join(
            f"{100 * c[k]:8.1f}" if k.startswith("share") else f"{c[k]:8.2f}" for k, _ in cols))
    return "\n".join(lines)
