"""Physics benchmark: PD-tracked characters per second of wall time, and batched rollouts.

``kinodyn bench physics [--quick] --json FILE`` reports

* ``steps_per_s_1``, ``steps_per_s_8``, ``steps_per_s_32``: physics steps per second of one world holding
  1, 8 or 32 PD-tracked characters (:meth:`World.step` with its Python side: servo targets, contact
  watch, divergence checks, recording), each on one thread;
* ``rtf_1``, ``rtf_8``, ``rtf_32``: the matching real-time factors (simulated seconds per wall second) at
  60 output frames per second, and ``rtf_cpu_*`` per CPU second of this process (what one core of its
  own gives: on a machine shared with other jobs the wall figures are lower);
* ``realtime_characters``: the largest number of PD-tracked characters that one world simulates in real
  time (RTF >= 1) at 60 frames per second, found by measuring (a per-character cost line through the 8
  and 32 measurements gives the guess, then it is measured);
* ``realtime_characters_cpu``: the same by CPU time;
* ``realtime_characters_2worlds``: the same with the characters split over two worlds stepped on two
  threads (:func:`kinodyn.physics.world.step_parallel`), for characters that do not meet;
* ``rollout_steps_per_s``: physics steps per second of :func:`kinodyn.physics.rollout.rollout` over 64
  rollouts of 600 steps (one character and a ball) on 2 threads, and ``rollout_steps_per_s_1thread``.

Every timing is the best of two runs (one with ``--quick``): the machine may be shared with other jobs.

The scene: the built-in humanoid (21 bodies, 68 servo controls) plays the built-in walk kinematically
for 0.2 s, switches to dynamic and tracks the walk with the default inertia-scaled servos; without a
balance controller it stumbles and falls within a second or two, so the timed window covers walking,
falling and lying on the ground. Characters stand 3 m apart.

Baseline (same run): ``python_pd_steps_per_s_1``, one character whose PD torques are computed in Python
every step and applied as generalized forces, the alternative to the in-engine servos.
"""

from __future__ import annotations

import time

import numpy as np

from kinodyn.bench import BenchResult

__all__ = ["measure_world", "run", "tracked_world"]

FPS = 60.0
SPACING = 3.0


def tracked_world(n: int, body=None, walk=None, warmup: float = 0.2):
    """A world with ``n`` characters tracking the walk (dynamic after ``warmup`` seconds)."""
    from kinodyn.data import library
    from kinodyn.data.skeleton import humanoid
    from kinodyn.physics.body import build_body
    from kinodyn.physics.world import World

    body = build_body(humanoid()) if body is None else body
    walk = library.load("walk") if walk is None else walk
    w = World(fps=FPS)
    side = int(np.ceil(np.sqrt(n)))
    places = [(SPACING * (i % side), SPACING * (i // side), 0.0) for i in range(n)]
    chars = [w.add_character(body, at=p) for p in places]
    for i, (c, p) in enumerate(zip(chars, places)):
        c.play(walk, at=p, loop=True, start=(0.37 * i) % (walk.duration - 0.1))
    w.run(warmup)
    for c in chars:
        c.switch_to_dynamic()
    return w


def measure_world(worlds, seconds: float) -> tuple[float, float]:
    """(wall seconds, CPU seconds of this process) to simulate ``seconds`` of every world (in parallel
    on threads when several)."""
    from kinodyn.physics.world import step_parallel

    frames = round(seconds * FPS)
    for w in worlds:
        w.record = False
    t0, c0 = time.perf_counter(), time.process_time()
    if len(worlds) == 1:
        worlds[0].step(frames)
    else:
        step_parallel(worlds, frames, threads=len(worlds))
    return time.perf_counter() - t0, time.process_time() - c0


#: Each timing is the best of this many runs (the machine is shared; the least disturbed run counts).
REPEATS = 2


def _rtf(n: int, seconds: float, body, walk, nworlds: int = 1, repeats: int = REPEATS
         ) -> tuple[float, float, float]:
    """(steps per wall second, wall real-time factor, CPU real-time factor) of ``n`` characters split
    over ``nworlds`` worlds, best of ``repeats`` runs."""
    split = [n // nworlds + (1 if k < n % nworlds else 0) for k in range(nworlds)]
    best_wall = best_cpu = np.inf
    for _ in range(repeats):
        worlds = [tracked_world(k, body, walk) for k in split if k > 0]
        wall, cpu = measure_world(worlds, seconds)
        best_wall, best_cpu = min(best_wall, wall), min(best_cpu, cpu)
    steps = seconds * FPS * worlds[0].config.substeps
    return steps / best_wall, seconds / best_wall, seconds / max(best_cpu, 1e-9)


def _largest_realtime(guess: int, seconds: float, body, walk, nworlds: int = 1, limit: int = 256,
                      which: int = 1, repeats: int = REPEATS) -> int:
    """Largest n with RTF >= 1 near ``guess`` (measured: up while real time, down while not);
    ``which`` picks the wall (1) or CPU (2) real-time factor."""
    n = max(1, min(guess, limit))
    r = _rtf(n, seconds, body, walk, nworlds, repeats)[which]
    if r >= 1.0:
        step = max(1, n // 8)
        while n + step <= limit:
            r2 = _rtf(n + step, seconds, body, walk, nworlds, repeats)[which]
            if r2 < 1.0:
                break
            n += step
        return n
    while n > 1:
        n -= max(1, n // 8)
        r = _rtf(n, seconds, body, walk, nworlds, repeats)[which]
        if r >= 1.0:
            return n
    return 0


def _python_pd_rate(seconds: float, body, walk) -> float:
    """Steps per second of one character whose servo torques are computed in Python each step."""
    import mujoco

    from kinodyn.errors import SimulationDivergedError
    from kinodyn.math import quat

    w = tracked_world(1, body, walk)
    c = w.characters[0]
    c.set_gains(0.0, 0.0)  # engine servos off; Python applies the same PD law
    m, d = w.model, w.data
    bm = c.map
    balls = [(k, b) for k, b in enumerate(bm.actuated) if bm.segments[b].kind == "ball"]
    hinges = [(k, b) for k, b in enumerate(bm.actuated) if bm.segments[b].kind == "hinge"]
    qa = np.array([c.qadr + bm.qpos_adr[b] for _, b in balls])
    va = np.array([c.vadr + bm.dof_adr[b] for _, b in balls])
    ca = np.array([c.cadr + bm.ctrl_adr[b] for _, b in balls])
    kpb, kvb = c.body.kp[[k for k, _ in balls]], c.body.kv[[k for k, _ in balls]]
    qh = np.array([c.qadr + bm.qpos_adr[b] for _, b in hinges])
    vh = np.array([c.vadr + bm.dof_adr[b] for _, b in hinges])
    ch = np.array([c.cadr + bm.ctrl_adr[b] for _, b in hinges])
    kph, kvh = c.body.kp[[k for k, _ in hinges]], c.body.kv[[k for k, _ in hinges]]
    nsteps = int(seconds * FPS * w.config.substeps)
    ctrl_seq = None
    from kinodyn.physics.rollout import clip_controls

    ctrl_seq = clip_controls(w, nsteps)
    t0 = time.perf_counter()
    done = 0
    try:
        for i in range(nsteps):
            target = ctrl_seq[i]
            q = d.qpos[qa[:, None] + np.arange(4)]
            qt = target[ca[:, None] + np.arange(4)]
            err = quat.to_rotvec(quat.inv_mul(q, qt))
            tau = kpb[:, None] * err - kvb[:, None] * d.qvel[va[:, None] + np.arange(3)]
            d.qfrc_applied[:] = 0.0
            d.qfrc_applied[va[:, None] + np.arange(3)] = tau
            d.qfrc_applied[vh] = kph * (target[ch] - d.qpos[qh]) - kvh * d.qvel[vh]
            mujoco.mj_step(m, d)
            done += 1
            if not np.isfinite(d.qvel).all() or np.abs(d.qvel).max() > 100.0:
                raise SimulationDivergedError("python PD diverged", step=i)  # stop before MuJoCo must
    except SimulationDivergedError:
        pass
    return done / (time.perf_counter() - t0)


def _rollout_rate(nroll: int, nstep: int, nthread: int, body, walk, repeats: int = REPEATS) -> float:
    from kinodyn.physics import rollout

    w = tracked_world(1, body, walk)
    c = w.characters[0]
    w.throw(c, "chest", mass=3.0, radius=0.1, speed=8.0, direction=np.pi / 2, height=1.4)
    s = w.get_state()
    states = np.repeat(s[None], nroll, axis=0)
    states[:, 1 + c.qadr] += np.linspace(0.0, 0.05, nroll)  # spread the characters a little
    ctrl = rollout.clip_controls(w, nstep)[None]
    rollout.rollout(w, states[:2], ctrl[:, :10], nthread=nthread)  # warm-up
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        rollout.rollout(w, states, ctrl, nthread=nthread)
        best = min(best, time.perf_counter() - t0)
    return nroll * nstep / best


def run(quick: bool = False, progress=None) -> BenchResult:
    from kinodyn.data import library
    from kinodyn.data.skeleton import humanoid
    from kinodyn.physics.body import build_body

    reps = 1 if quick else REPEATS
    res = BenchResult("physics")
    body = build_body(humanoid())
    walk = library.load("walk")
    seconds = 1.0 if quick else 2.0
    todo = ["1", "8", "32", "realtime", "realtime2", "rollout", "baseline"]
    bar = progress(total=len(todo), desc="physics bench") if progress else None

    def tick():
        if bar is not None:
            bar.update(1)

    rates, cpu_rates = {}, {}
    for n in (1, 8, 32):
        sps, rtf, rtf_cpu = _rtf(n, seconds, body, walk, repeats=reps)
        rates[n] = sps
        cpu_rates[n] = rtf_cpu * FPS * 4
        res.add(f"steps_per_s_{n}", sps, "steps/s")
        res.add(f"rtf_{n}", rtf, "x real time")
        res.add(f"rtf_cpu_{n}", rtf_cpu, "x real time per CPU second")
        tick()

    def guess_from(r):  # time per step = a + b n through the 8 and 32 measurements
        b = (1.0 / r[32] - 1.0 / r[8]) / 24.0
        a = 1.0 / r[8] - 8 * b
        return int((1.0 / (FPS * 4) - a) / b) if b > 0 else 64

    guess, guess_cpu = guess_from(rates), guess_from(cpu_rates)
    if quick:
        res.add("realtime_characters", max(0, guess), "characters")
        res.add("realtime_characters_cpu", max(0, guess_cpu), "characters")
        res.notes["realtime_characters"] = "estimated from the 8 and 32 measurements (--quick)"
        tick()
        res.add("realtime_characters_2worlds", max(0, 2 * guess), "characters")
        res.notes["realtime_characters_2worlds"] = "twice the one-world estimate (--quick, not measured)"
        tick()
    else:
        n1 = _largest_realtime(guess, seconds, body, walk, repeats=reps)
        res.add("realtime_characters", n1, "characters")
        res.add("realtime_characters_cpu", _largest_realtime(guess_cpu, seconds, body, walk, which=2, repeats=reps),
                "characters")
        tick()
        n2 = _largest_realtime(max(2, int(1.7 * max(n1, 1))), seconds, body, walk, nworlds=2, repeats=reps)
        res.add("realtime_characters_2worlds", n2, "characters")
        tick()
    nroll, nstep = (16, 300) if quick else (64, 600)
    res.add("rollout_steps_per_s", _rollout_rate(nroll, nstep, 2, body, walk, reps), "steps/s")
    res.add("rollout_steps_per_s_1thread", _rollout_rate(nroll, nstep, 1, body, walk, reps), "steps/s")
    res.add("rollout_thread_speedup", res.metrics["rollout_steps_per_s"] / res.metrics["rollout_steps_per_s_1thread"],
            "x")
    tick()
    py = _python_pd_rate(0.5 if quick else 1.0, body, walk)
    res.baseline["python_pd_steps_per_s_1"] = py
    res.add("engine_pd_speedup_1", rates[1] / py, "x")
    tick()
    if bar is not None:
        bar.close()
    res.notes["scene"] = ("built-in humanoid tracking the built-in walk with in-engine inertia-scaled PD servos, "
                          "dt = 1/240 s, 60 output frames/s; characters 3 m apart")
    res.notes["goal"] = "at least 32 tracked characters in real time on a 2-core machine"
    return res
