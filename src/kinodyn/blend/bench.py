"""Benchmark of support-phase synchronized blending (``kinodyn bench blend``).

Measures, on the built-in clips:

- ``sync_us_per_update``: Python cost of one synchronization update (a character entering a new step:
  section 5.1 sync of the frontier, 5.2 durations, 5.3 warp segments), measured over a crowd whose
  characters keep starting and stopping actions.
- ``mix_us_per_character_frame``: cost per character and frame of the whole mixer step (updates,
  time warps, weights, sampling, blending, support constraints) with 3 actions contributing to every
  character; ``characters_at_60fps`` is how many such characters one core mixes at 60 frames per
  second, timed at that count (:func:`characters_at_60fps`).
- the four-arm evaluation (:mod:`kinodyn.blend.evaluate`) of the built-in figure 12/13 script and of the
  real-clip scripts (:mod:`kinodyn.blend.realclips`, when the motion capture is present): ``sliding_ratio``
  (sync + lock over lock alone), ``sliding_ratio_sync_only`` (sync over plain), ``sliding_cm_s_synced``,
  ``lock_p95_cm``, ``lock_max_cm``, ``lock_p95_ratio``, ``pelvis_acc_ratio``, ``root_decel_ratio``
  (real-clip scripts prefixed by their name); beside them, the plain and sync arms' sliding split into
  its causes (:func:`kinodyn.blend.evaluate.sliding_causes`: ``sync_sliding_own_cm_s``,
  ``sync_sliding_warp_cm_s``, ``sync_sliding_weights_cm_s``, ``sync_sliding_root_cm_s``,
  ``sync_sliding_pose_cm_s``, ``sync_sliding_transition_cm_s``, ``sync_share_transition``, ...).

Everything runs in this process on one thread (numba kernels included); absolute times are noisy, the
ratio against the unsynchronized baseline measured in the same run is the robust figure.
"""

from __future__ import annotations

import time

import numpy as np

from kinodyn.bench import BenchResult, one_numba_thread

__all__ = ["add_sliding", "characters_at_60fps", "crowd_benchmark", "run", "sliding_benchmark"]


def _library():
    from kinodyn.blend.library import builtin

    return builtin(["idle", "walk", "run", "punch", "kick", "jump"])


def crowd_benchmark(n: int, seconds: float, synchronize: bool = True, seed: int = 0, library=None) -> dict:
    """Mix ``n`` characters for ``seconds`` at 60 fps; every character plays walk, run and a faster walk
    at one priority (three contributing actions) and restarts one of them now and then.

    Returns timings: ``frame_ms`` (mean per frame), ``us_per_char_frame``, ``updates`` (step entries),
    ``us_per_update`` (Python time of the updates), ``frames``.
    """
    from kinodyn.blend.character import Character
    from kinodyn.blend.mixer import BlendConfig, Mixer

    lib = library or _library()
    rng = np.random.default_rng(seed)
    mx = Mixer(lib, n, BlendConfig(synchronize=synchronize, max_actions=5))
    dt = 1.0 / 60.0
    for i in range(n):
        mx.start("walk", character=i, priority=1, speed=float(rng.uniform(0.85, 1.15)), key="walk")
        mx.start("run", character=i, priority=1, speed=float(rng.uniform(0.9, 1.1)), key="run")
        mx.start("walk", character=i, priority=1, speed=1.3, key="fast")
    for _ in range(30):  # everyone started and ramped in
        mx.step(dt)
    upd = {"t": 0.0, "n": 0}
    orig = Character.advance

    def timed(self, t):
        t0 = time.perf_counter()
        orig(self, t)
        upd["t"] += time.perf_counter() - t0
        upd["n"] += 1

    Character.advance = timed
    try:
        frames = int(round(seconds * 60))
        restart = rng.integers(0, 120, n)  # each character restarts its run every ~2 s, staggered
        t0 = time.perf_counter()
        for f in range(frames):
            due = np.nonzero((restart + f) % 120 == 0)[0]
            for i in due:
                acts = mx.chars[i].actions
                if "run" in acts and acts["run"].t_off is None:
                    mx.stop("run", character=i)
                elif "run" not in acts:
                    mx.start("run", character=i, priority=1, key="run")
            mx.step(dt)
        el = time.perf_counter() - t0
    finally:
        Character.advance = orig
    w = [len(c.actions) for c in mx.chars]
    return {"frame_ms": 1e3 * el / frames, "us_per_char_frame": 1e6 * el / frames / n, "frames": frames,
            "updates": upd["n"], "us_per_update": 1e6 * upd["t"] / max(upd["n"], 1),
            "updates_per_char_s": upd["n"] / (n * frames * dt), "mean_actions": float(np.mean(w))}


def characters_at_60fps(library, seconds: float, start: int = 200, budget_ms: float = 1e3 / 60.0,
                        tries: int = 6) -> dict:
    """The most characters mixed within a 60 fps frame budget, *measured at that count*: a first crowd of
    ``start`` characters gives an estimate, then crowds of the estimated size are timed. The counts found
    to fit and to overrun bracket the next try (each try's own cost per character gives the estimate,
    the bracket's geometric middle when the estimate falls outside it), so a try that overruns on a
    loaded machine narrows the search instead of ending it. Stops when the bracket is within 2 %.
    Returns ``{"characters": n, "frame_ms": ..., "us_per_char_frame": ...}`` of the largest count
    measured to fit (0 when none did)."""
    r = crowd_benchmark(start, seconds, True, library=library)
    fit = {"characters": start, **r} if r["frame_ms"] <= budget_ms else {"characters": 0, **r}
    over = None if r["frame_ms"] <= budget_ms else start
    n = max(int(start * budget_ms / r["frame_ms"]), 1)
    for _ in range(tries):
        lo = fit["characters"]
        if over is not None:
            if over <= 1.02 * lo + 1:
                break
            if not lo < n < over:
                n = int(np.sqrt(max(lo, 1) * over))
        if n <= lo:
            break
        r = crowd_benchmark(n, seconds, True, library=library)
        if r["frame_ms"] <= budget_ms:
            fit = {"characters": n, **r}
            n = int(n * min(budget_ms / r["frame_ms"], 1.2))
        else:
            over = n
            n = int(n * 0.97 * budget_ms / r["frame_ms"])
    return fit


def sliding_benchmark(mocap=None) -> dict:
    """The four-arm evaluation (:func:`kinodyn.blend.evaluate.evaluate`) of the built-in figure 12/13
    script and of every real-clip script (:mod:`kinodyn.blend.realclips`) whose files are present."""
    from kinodyn.blend import realclips
    from kinodyn.blend.evaluate import evaluate
    from kinodyn.blend.transitions import transition_script

    out = {"builtin": evaluate(transition_script())}
    for name, script in realclips.scripts(mocap).items():
        out[name] = evaluate(script)
    return out


#: The benchmark's headline keys of each script's evaluation (:func:`kinodyn.blend.evaluate.headline`).
HEADLINE = ("sliding_ratio", "sliding_ratio_sync_only", "sliding_cm_s_synced", "lock_p95_cm", "lock_max_cm",
            "lock_p95_ratio", "pelvis_acc_ratio", "root_decel_ratio")
_UNITS = {"sliding_cm_s_synced": "cm/s", "lock_p95_cm": "cm", "lock_max_cm": "cm"}


def add_sliding(res: BenchResult, figs: dict) -> None:
    """Add the four-arm figures of every script (:func:`sliding_benchmark`) to ``res``: the headline keys
    as metrics, each arm's figures and the plain and sync arms' sliding causes as baseline figures."""
    for script, f in figs.items():
        prefix = "" if script == "builtin" else f"{script}_"
        for k in HEADLINE:
            res.add(prefix + k, f[k], _UNITS.get(k, "x"))
        for arm, a in f["arms"].items():
            for k in ("sliding_cm_s", "detected_sliding_cm_s", "lock_p95_cm", "lock_max_cm", "err_frames",
                      "pelvis_acc", "root_decel", "lowest_foot_cm", "warp_rate_min", "warp_rate_max"):
                res.baseline[f"{prefix}{arm}_{k}"] = a[k]
        for arm in ("plain", "sync"):
            for k, v in f["arms"][arm]["causes"].items():
                if k.startswith(("sliding_", "share_")) and k != "sliding_cm_s":
                    res.baseline[f"{prefix}{arm}_{k}"] = v
        res.baseline[f"{prefix}source_pelvis_acc"] = f["arms"]["sync_lock"]["pelvis_acc_source"]
        res.baseline[f"{prefix}source_root_decel"] = f["arms"]["sync_lock"]["root_decel_source"]


def run(quick: bool = False, progress=None) -> BenchResult:
    """The blend benchmark on one thread (the compiled kernels' thread count is restored after)."""
    with one_numba_thread():
        return _run(quick)


def _run(quick: bool) -> BenchResult:
    res = BenchResult("blend")
    lib = _library()
    n = 200 if quick else 1000
    seconds = 1.0 if quick else 4.0
    crowd_benchmark(8, 0.2, library=lib)  # compile and warm caches
    sync = crowd_benchmark(n, seconds, True, library=lib)
    base = crowd_benchmark(n, seconds, False, library=lib)
    res.add("sync_us_per_update", sync["us_per_update"], "us")
    res.add("sync_updates_per_character_s", sync["updates_per_char_s"], "1/s")
    res.add("mix_us_per_character_frame", sync["us_per_char_frame"], "us")
    res.add("benchmark_characters", n, "characters")
    res.add("actions_per_character", sync["mean_actions"], "actions")
    res.baseline["mix_us_per_character_frame_unsynchronized"] = base["us_per_char_frame"]
    fit = characters_at_60fps(lib, 0.5 if quick else 2.0)
    res.add("characters_at_60fps", fit["characters"], "characters")
    res.add("frame_ms_at_characters_at_60fps", fit["frame_ms"], "ms")
    figs = sliding_benchmark()
    add_sliding(res, figs)
    res.add("err_frames_synced", figs["builtin"]["arms"]["sync_lock"]["err_frames"], "frames")
    res.notes["sliding"] = ("four arms on the same script (plain, sync, lock, sync_lock: synchronization and the "
                            "foot lock on or off, everything else equal); sliding is the horizontal speed of the "
                            "lowest foot point over the frames where the heaviest action's source clip has that "
                            "foot down (contacts detected on the sources, mapped through the mixer's record); "
                            "sliding_ratio = lock / sync_lock, sliding_ratio_sync_only = plain / sync, "
                            "lock_p95_ratio = lock / sync_lock of the held feet's distance from the blended pose; "
                            "keys without a prefix are the built-in figure 12/13 script")
    res.notes["sliding_causes"] = ("<arm>_sliding_<cause>_cm_s (plain and sync arms) add up to <arm>_sliding_cm_s: "
                                   "own = the source clip's own foot speed at the frames played, warp = the time "
                                   "warp's change of it, weights = weight shifting between clips whose feet stand at "
                                   "different places from the root, root = the blended root moving unlike the "
                                   "source's, pose = the rest of the blended pose moving the foot; <arm>_sliding_<group>_cm_s "
                                   "and <arm>_share_<group> split the same sum and the planted foot-frames into alone "
                                   "(one action has 95% of the weight), transition and swing (transition frames where "
                                   "another weighted action has that foot up)")
    res.notes["speed"] = (f"{n} characters, 3 actions each at one priority, one thread; updates are the "
                          "Python step entries (sync + durations + warp); characters_at_60fps is measured at "
                          "that count")
    return res
