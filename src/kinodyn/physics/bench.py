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

Every timing is the best of two runs (one with ``--quick``, which also simulates 1 s instead of 2 s; every
figure is still measured at the count it names): the machine may be shared with other jobs. The compiled
(numba) kernels run on one thread.

The scene: the built-in humanoid (21 bodies, 68 servo controls) plays the built-in walk kinematically
for 0.2 s, switches to dynamic and tracks the walk with the default inertia-scaled servos; without a
balance controller it stumbles and falls within a second or two, so the timed window covers walking,
falling and lying on the ground. Characters stand 3 m apart.

Baseline (same run): ``python_pd_steps_per_s_1``, one character whose PD torques are computed in Python
every step and applied as generalized forces (:class:`PythonPD`, stable PD: explicit PD diverges within
a few steps), the alternative to the in-engine servos, over the same simulated time as
``steps_per_s_1``; ``engine_pd_speedup_1`` is their ratio. A baseline run that diverges raises.
"""

from __future__ import annotations

import time

import numpy as np

from kinodyn.bench import BenchResult, one_numba_thread

__all__ = ["PythonPD", "measure_world", "run", "tracked_world"]

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


class PythonPD:
    """Stable PD servos computed in Python every step and applied as generalized forces: the alternative
    to the in-engine servos that ``python_pd_steps_per_s_1`` times (mutable; owns nothing but index arrays).

    The same law as the engine's (``kp`` on the joint error, ``kv`` on the joint velocity, the world's
    servo targets), but integrated stably: plain explicit damping diverges within a few steps on the light
    segments (toes, hands: ``kv dt / I`` above 2), where MuJoCo's implicit integrator keeps its own servos
    stable. So this is stable PD (Tan, Liu and Turk 2011): the torque is the one at the end of the step,
    ``tau = kp (e - dt qd) - kv (qd + dt qdd)`` with ``(M + dt Kv) qdd = -c + kp (e - dt qd) - kv qd``,
    from the mass matrix ``M`` and bias forces ``c`` of the last step (MuJoCo leaves them in ``MjData``).
    """

    def __init__(self, world, char):
        self.world, self.char = world, char
        char.set_gains(0.0, 0.0)  # engine servos off; Python applies the same PD law
        bm = char.map
        nv = world.model.nv
        self.kp, self.kv = np.zeros(nv), np.zeros(nv)
        ball_q, ball_c, ball_v, hinge_q, hinge_c, hinge_v = [], [], [], [], [], []
        for k, b in enumerate(bm.actuated):
            v = char.vadr + bm.dof_adr[b]
            q = char.qadr + bm.qpos_adr[b]
            ca = char.cadr + bm.ctrl_adr[b]
            if bm.segments[b].kind == "ball":
                ball_q.append(q), ball_c.append(ca), ball_v.append(v)
                self.kp[v:v + 3], self.kv[v:v + 3] = char.body.kp[k], char.body.kv[k]
            else:
                hinge_q.append(q), hinge_c.append(ca), hinge_v.append(v)
                self.kp[v], self.kv[v] = char.body.kp[k], char.body.kv[k]
        self.bq = np.array(ball_q, dtype=np.int64)[:, None] + np.arange(4)
        self.bc = np.array(ball_c, dtype=np.int64)[:, None] + np.arange(4)
        self.bv = np.array(ball_v, dtype=np.int64)[:, None] + np.arange(3)
        self.hq, self.hc, self.hv = (np.array(x, dtype=np.int64) for x in (hinge_q, hinge_c, hinge_v))
        self.mass = np.zeros((nv, nv))
        self.dt = world.dt

    def step(self, target: np.ndarray) -> None:
        """One physics step toward the servo targets ``target (nu,)``."""
        import mujoco

        from kinodyn.math import quat

        m, d = self.world.model, self.world.data
        err = np.zeros(m.nv)
        err[self.bv] = quat.to_rotvec(quat.inv_mul(d.qpos[self.bq], target[self.bc]))
        err[self.hv] = target[self.hc] - d.qpos[self.hq]
        qd = d.qvel
        mujoco.mj_fullM(m, d, self.mass)
        drive = self.kp * (err - self.dt * qd) - self.kv * qd
        qdd = np.linalg.solve(self.mass + np.diag(self.dt * self.kv), drive - d.qfrc_bias)
        d.qfrc_applied[:] = drive - self.dt * self.kv * qdd
        mujoco.mj_step(m, d)


def _python_pd_rate(seconds: float, body, walk) -> float:
    """Steps per second of one character whose servo torques are computed in Python each step
    (:class:`PythonPD`).

    Raises:
        SimulationDivergedError: the Python servos lost the character (a timing of a diverged run would
            not be the rate of the alternative).
    """
    from kinodyn.errors import SimulationDivergedError
    from kinodyn.physics.rollout import clip_controls

    w = tracked_world(1, body, walk)
    pd = PythonPD(w, w.characters[0])
    nsteps = round(seconds * FPS * w.config.substeps)
    ctrl_seq = clip_controls(w, nsteps)
    d = w.data
    t0 = time.perf_counter()
    for i in range(nsteps):
        pd.step(ctrl_seq[i])
        if not np.isfinite(d.qvel).all() or np.abs(d.qvel).max() > w.config.max_speed:
            raise SimulationDivergedError(f"the Python PD baseline diverged at step {i} of {nsteps}", step=i)
    return nsteps / (time.perf_counter() - t0)


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
    """The physics benchmark with the compiled kernels on one thread (their thread count is restored
    after); MuJoCo steps each world on the calling thread, two worlds on two."""
    with one_numba_thread():
        return _run(quick, progress)


def _run(quick: bool, progress) -> BenchResult:
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

    def guess_from(r):  # time per step = a + b n through the 8 and 32 measurements: where to start looking
        b = (1.0 / r[32] - 1.0 / r[8]) / 24.0
        a = 1.0 / r[8] - 8 * b
        return int((1.0 / (FPS * 4) - a) / b) if b > 0 else 64

    guess, guess_cpu = guess_from(rates), guess_from(cpu_rates)
    # measured in --quick too (one run of each count instead of the best of two)
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
    py = max(_python_pd_rate(seconds, body, walk) for _ in range(reps))
    res.baseline["python_pd_steps_per_s_1"] = py
    res.add("engine_pd_speedup_1", rates[1] / py, "x")
    res.notes["engine_pd_speedup_1"] = (f"steps_per_s_1 over python_pd_steps_per_s_1, both one character for "
                                        f"{seconds:g} s ({round(seconds * FPS * 4)} steps)")
    tick()
    if bar is not None:
        bar.close()
    res.notes["scene"] = ("built-in humanoid tracking the built-in walk with in-engine inertia-scaled PD servos, "
                          "dt = 1/240 s, 60 output frames/s; characters 3 m apart")
    res.notes["threads"] = "numba kernels on 1 thread; one world per thread"
    res.notes["goal"] = "at least 32 tracked characters in real time on a 2-core machine"
    return res
