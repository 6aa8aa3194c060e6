"""Benchmark of support-phase synchronized blending (``kinodyn bench blend``).

Measures, on the built-in clips:

- ``sync_us_per_update``: Python cost of one synchronization update (a character entering a new step:
  section 5.1 sync of the frontier, 5.2 durations, 5.3 warp segments), measured over a crowd whose
  characters keep starting and stopping actions.
- ``mix_us_per_character_frame``: cost per character and frame of the whole mixer step (updates,
  time warps, weights, sampling, blending, support constraints) with 3 actions contributing to every
  character; ``characters_at_60fps`` is how many such characters one core mixes at 60 frames per
  second (the frame budget divided by that cost, measured at ``N`` characters).
- the foot sliding of the figure 12/13 script (:mod:`kinodyn.blend.transitions`) with and without
  synchronization: ``sliding_ratio`` (unsynchronized over synchronized), ``sliding_cm_s_synced``.

Everything runs in this process on one thread (numba kernels included); absolute times are noisy, the
ratio against the unsynchronized baseline measured in the same run is the robust figure.
"""

from __future__ import annotations

import time

import numpy as np

from kinodyn.bench import BenchResult

__all__ = ["crowd_benchmark", "run", "sliding_benchmark"]


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


def sliding_benchmark() -> dict:
    """Foot sliding of the figure 12/13 script with and without synchronization (see the demo)."""
    from kinodyn.blend.transitions import sliding_figures, transition_script

    return sliding_figures(transition_script())


def run(quick: bool = False, progress=None) -> BenchResult:
    """The blend benchmark on one thread (the compiled kernels' thread count is restored after)."""
    import numba

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        return _run(quick)
    finally:
        numba.set_num_threads(threads)


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
    res.add("characters_at_60fps", (1e6 / 60.0) / sync["us_per_char_frame"], "characters")
    res.add("benchmark_characters", n, "characters")
    res.add("actions_per_character", sync["mean_actions"], "actions")
    res.baseline["mix_us_per_character_frame_unsynchronized"] = base["us_per_char_frame"]
    res.baseline["characters_at_60fps_unsynchronized"] = (1e6 / 60.0) / base["us_per_char_frame"]
    sl = sliding_benchmark()
    res.add("sliding_cm_s_synced", sl["synced"]["sliding_cm_s"], "cm/s")
    res.add("sliding_cm_s_unsynced", sl["unsynced"]["sliding_cm_s"], "cm/s")
    res.add("sliding_ratio", sl["sliding_ratio"], "x")
    res.add("sliding_ratio_transitions", sl["sliding_ratio_transitions"], "x")
    res.add("sliding_ratio_detected_contacts", sl["sliding_ratio_detected"], "x")
    res.add("err_frames_synced", sl["synced"]["err_frames"], "frames")
    res.add("err_frames_unsynced", sl["unsynced"]["err_frames"], "frames")
    res.baseline["sliding_cm_s_unsynced"] = sl["unsynced"]["sliding_cm_s"]
    res.baseline["sliding_cm_s_synced_without_constraints"] = sl["synced_plain"]["sliding_cm_s"]
    res.baseline["sliding_cm_s_unsynced_with_constraints"] = sl["unsynced_constrained"]["sliding_cm_s"]
    res.notes["sliding"] = ("horizontal speed of the lowest foot point while the actions' support phases put "
                            "that foot down (weighted vote); synced = synchronization with support "
                            "constraints, unsynced = the plain blend of the same script")
    res.notes["speed"] = (f"{n} characters, 3 actions each at one priority, one thread; updates are the "
                          "Python step entries (sync + durations + warp)")
    return res
