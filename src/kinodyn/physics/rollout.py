"""Batched rollouts on both cores, for generating training data.

``mujoco.rollout`` steps many initial states forward under open-loop controls in C, on a pool of
threads that run without the GIL. Here the controls are the servo targets of the characters' clips (the
PD servos run in the engine), so a rollout is exactly what :meth:`World.step` would compute for dynamic
characters. :func:`impact_batch` builds the fast dynamic-response paper's training set (section 7.2): the
same walking character hit by a ball thrown with many angles, speeds, heights and target landmarks.

In a rollout every character is simulated (nothing is played kinematically); start it from the state
where the simulation should take over.

Shapes: ``N`` rollouts, ``T`` steps, ``S`` = ``mj_stateSize(FULLPHYSICS)``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import mujoco
import numpy as np

from kinodyn.errors import ParameterError, SimulationDivergedError, SimulationError
from kinodyn.physics import impacts as _impacts

__all__ = [
    "STATE_SPEC",
    "RolloutResult",
    "clip_controls",
    "default_threads",
    "impact_batch",
    "rollout",
    "step_parallel",
    "threaded_rollout",
]

STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS


def default_threads() -> int:
    """Threads for rollouts: the CPUs this process may use (2 on the reference machine)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class RolloutResult:
    """States after each step of ``N`` rollouts.

    Attributes:
        state: ``(N, T, S)`` full physics states (``mjSTATE_FULLPHYSICS``).
        nq, nv: model sizes (``qpos`` starts at column 1 of a state, ``qvel`` at ``1 + nq``).
        dt: physics timestep (s).
        diverged: ``(N,)`` True where the state became non-finite or exploded, or MuJoCo reset it;
            ``None`` when divergence was not checked (``rollout(check=False)``): unknown, not fine.
        first_bad: ``(N,)`` first diverged step, -1 where fine; ``None`` when not checked.
        bad_body: ``N`` names of the body whose speed went bad first (``""`` where fine or unknown);
            empty when not checked.
    """

    state: np.ndarray
    nq: int
    nv: int
    dt: float
    diverged: np.ndarray | None
    first_bad: np.ndarray | None
    bad_body: tuple[str, ...] = ()

    @property
    def time(self) -> np.ndarray:
        return self.state[..., 0]

    @property
    def qpos(self) -> np.ndarray:
        return self.state[..., 1:1 + self.nq]

    @property
    def qvel(self) -> np.ndarray:
        return self.state[..., 1 + self.nq:1 + self.nq + self.nv]

    @property
    def checked(self) -> bool:
        """Whether divergence was checked (``diverged`` is known)."""
        return self.diverged is not None

    def check(self) -> RolloutResult:
        """Raise :class:`SimulationDivergedError` when any rollout diverged.

        Raises:
            SimulationDivergedError: a rollout diverged (the first one is named, with its step and body).
            SimulationError: divergence was not checked (``rollout(check=False)``).
        """
        if self.diverged is None:
            raise SimulationError(ERR_UNCHECKED)
        if self.diverged.any():
            i = int(np.argmax(self.diverged))
            body = self.bad_body[i] if self.bad_body else ""
            raise SimulationDivergedError(f"{int(self.diverged.sum())} of {len(self.diverged)} rollouts diverged "
                                          f"(first: rollout {i} at step {int(self.first_bad[i])}"
                                          f"{f', body {body!r}' if body else ''})",
                                          step=int(self.first_bad[i]), body=body)
        return self


ERR_UNCHECKED = ("divergence of these rollouts was not checked (rollout(check=False)), so whether they are "
                 "fine is unknown; roll out with check=True")


def _divergence(model, state: np.ndarray, max_speed: float, s0: np.ndarray, dt: float):
    """Non-finite or exploded states, and states MuJoCo reset after finding a NaN or huge value (the
    reset puts the time back to 0, so the clock stops matching the step count). ``s0 (N or 1, S)``: the
    initial states. Returns ``(diverged (N,), first_bad (N,), bad_body N names)``: the body of the
    fastest dof at the first bad state, or, when MuJoCo reset it, in the initial state if that was
    already too fast ("" when unknown)."""
    nq, nv = model.nq, model.nv
    s0 = np.broadcast_to(s0, (len(state), s0.shape[-1]))
    t0 = s0[:, 0]
    qv = state[..., 1 + nq:1 + nq + nv]
    speed = np.abs(np.nan_to_num(qv, nan=np.inf))
    bad = ~np.isfinite(state).all(axis=-1) | (speed.max(axis=-1, initial=0.0) > max_speed)
    expected = t0[:, None] + dt * np.arange(1, state.shape[1] + 1)[None, :]
    bad |= np.abs(state[..., 0] - expected) > 0.5 * dt
    div = bad.any(axis=1)
    first = np.where(div, np.argmax(bad, axis=1), -1)
    names = []
    for i in range(len(state)):
        body = ""
        if div[i] and nv:
            s = speed[i, first[i]]
            if s.max() <= max_speed and first[i] == 0:  # MuJoCo reset a state that started bad
                s = np.abs(np.nan_to_num(s0[i, 1 + nq:1 + nq + nv], nan=np.inf))
            if s.max() > max_speed:
                body = model.body(model.dof_bodyid[int(np.argmax(s))]).name
        names.append(body)
    return div, first, tuple(names)


def rollout(world, initial_state=None, control=None, nstep: int | None = None, nthread: int | None = None,
            check: bool = True) -> RolloutResult:
    """Roll out ``N`` trajectories of ``world``'s model on ``nthread`` threads.

    Args:
        world: a :class:`~kinodyn.physics.world.World` (its model; its data is untouched).
        initial_state: ``(N, S)`` or ``(S,)`` states (default: the world's current state).
        control: ``(N or 1, T or 1, nu)`` servo targets (default: :func:`clip_controls`).
        nstep: steps (inferred from ``control`` when given).
        nthread: threads (default :func:`default_threads`).
        check: mark rollouts that diverged (``result.diverged``; call ``result.check()`` to raise). Without
            it ``diverged`` is ``None`` (unknown) and ``result.check()`` raises.

    Returns:
        A :class:`RolloutResult`.
    """
    from mujoco import rollout as _mjrollout

    m = world.model
    s0 = world.get_state(STATE_SPEC) if initial_state is None else np.asarray(initial_state, dtype=np.float64)
    s0 = np.atleast_2d(s0)
    nstate = mujoco.mj_stateSize(m, STATE_SPEC)
    if s0.shape[-1] != nstate:
        raise ParameterError(f"initial states must have {nstate} columns (FULLPHYSICS), got {s0.shape}")
    if control is None:
        if nstep is None:
            raise ParameterError("pass nstep or a control array")
        control = clip_controls(world, nstep)[None]
    control = np.asarray(control, dtype=np.float64)
    if control.ndim == 2:
        control = control[None]
    if control.ndim != 3 or control.shape[-1] != m.nu:
        raise ParameterError(f"control must be (N or 1, T or 1, {m.nu}), got {control.shape}")
    if nstep is None:
        nstep = control.shape[1]
    if not (isinstance(nstep, (int, np.integer)) and nstep >= 1):
        raise ParameterError(f"nstep must be a positive integer, got {nstep!r}")
    nthread = default_threads() if nthread is None else int(nthread)
    if nthread < 1:
        raise ParameterError(f"nthread must be at least 1, got {nthread}")
    datas = [mujoco.MjData(m) for _ in range(nthread)]
    with _mjrollout.Rollout(nthread=nthread if nthread > 1 else 0) as r:
        state, _ = r.rollout(m, datas, s0, control, nstep=int(nstep))
    if not check:
        return RolloutResult(state, m.nq, m.nv, world.dt, None, None)
    return RolloutResult(state, m.nq, m.nv, world.dt, *_divergence(m, state, world.config.max_speed, s0,
                                                                    m.opt.timestep))


def clip_controls(world, nstep: int, start_step: int | None = None) -> np.ndarray:
    """``(nstep, nu)`` servo targets that :meth:`World.step` would apply over the next ``nstep`` steps
    (clip targets with their lookahead, fixed targets, or the rest pose)."""
    from kinodyn.physics import playback

    start = world.step_count if start_step is None else int(start_step)
    return playback.clip_controls(world.characters, world.data.ctrl, nstep, start)


def impact_batch(world, char, throws, duration: float = 0.5, lead: float = 0.05, mass: float = 3.0,
                 radius: float = 0.1, nthread: int | None = None,
                 on_divergence: str = "raise") -> tuple[RolloutResult, list[dict]]:
    """Roll out one ball impact per entry of ``throws`` on a character that plays a clip.

    Each throw is a dict with ``landmark``, ``speed``, ``direction``, ``height`` and ``time`` (world time
    of arrival at the landmark; default now + ``lead``), and optionally ``distance``. Each rollout starts
    ``lead`` seconds before that arrival from the clip's state (positions and finite-difference velocities)
    with the ball on its way, and runs ``duration`` seconds with the servos tracking the clip.

    Args:
        on_divergence: ``"raise"`` (default, as :meth:`World.step` does) or ``"flag"``: return the batch
            with the diverged rollouts marked in ``result.diverged`` (to drop them from a training set).

    Returns:
        The :class:`RolloutResult` (rollout ``i`` for ``throws[i]``) and per throw a dict with ``start_step``
        (world step of the rollout's first state), ``launch`` (ball start, velocity, flight time) and the
        ball's ``qpos``/``qvel`` addresses.

    Raises:
        SimulationDivergedError: with ``on_divergence="raise"``, a rollout diverged; the message names
            the throw, the world step and the body.
    """
    if on_divergence not in ("raise", "flag"):
        raise ParameterError(f"on_divergence must be 'raise' or 'flag', got {on_divergence!r}")
    if not throws:
        raise ParameterError("throws must be a non-empty list of throw parameters")
    ball = next((p for p in world.projectiles if abs(p.mass - mass) < 1e-12 and abs(p.radius - radius) < 1e-12),
                None)
    if ball is None:
        ball = world.add_projectile(mass, radius)
    ball.activate()
    if char.clip is None:
        raise ParameterError(f"character {char.name!r} plays no clip; play one first")
    m = world.model
    nsteps = round(duration / world.dt)
    lead_steps = max(1, round(lead / world.dt))
    g = np.array([0.0, 0.0, -world.config.gravity])
    base = world.get_state(STATE_SPEC)
    states, controls, info = [], [], []
    for th in throws:
        t_hit = float(th.get("time", world.time + lead))
        hit_step = round(t_hit / world.dt)
        start_step = hit_step - lead_steps
        if start_step < world.step_count:
            raise ParameterError(f"throw arriving at t={t_hit:.3f} s starts before the world's time {world.time:.3f} s")
        target = world.landmark_point(char, char.map.body(th.get("landmark", "chest")), t_hit)
        start, vel, flight = _impacts.launch(target, th["speed"], th["direction"], th["height"],
                                             th.get("distance", 2.0), g)
        tau = flight - lead_steps * world.dt  # time already flown at the rollout's start
        if tau < 0:
            raise ParameterError(f"lead ({lead} s) is longer than the ball's flight ({flight:.3f} s)")
        p0 = start + vel * tau + 0.5 * g * tau * tau
        v0 = vel + g * tau
        s = base.copy()
        s[0] = start_step * world.dt
        q, v = char.clip.state(start_step)
        s[1 + char.qadr:1 + char.qadr + char.map.nq] = q
        s[1 + m.nq + char.vadr:1 + m.nq + char.vadr + char.map.nv] = v
        s[1 + ball.qadr:1 + ball.qadr + 7] = np.concatenate([p0, [1.0, 0.0, 0.0, 0.0]])
        s[1 + m.nq + ball.vadr:1 + m.nq + ball.vadr + 6] = np.concatenate([v0, np.zeros(3)])
        states.append(s)
        controls.append(clip_controls(world, nsteps, start_step))
        info.append({"start_step": start_step, "launch": (start, vel, flight), "ball_qadr": ball.qadr,
                     "ball_vadr": ball.vadr, "throw": dict(th)})
    res = rollout(world, np.array(states), np.array(controls), nsteps, nthread)
    if on_divergence == "raise" and res.diverged.any():
        i = int(np.argmax(res.diverged))
        step = info[i]["start_step"] + int(res.first_bad[i]) + 1
        body = res.bad_body[i]
        raise SimulationDivergedError(f"{int(res.diverged.sum())} of {len(throws)} impact rollouts diverged; the "
                                      f"first is throw {i} ({throws[i]}) at world step {step} "
                                      f"(t = {step * world.dt:.4f} s){f', body {body!r}' if body else ''}; pass "
                                      "on_divergence='flag' to keep the others", step=step, body=body)
    return res, info


def threaded_rollout(world, initial_states, control, nthread: int | None = None) -> RolloutResult:
    """The same as :func:`rollout` with plain Python threads calling ``mj_step`` (which releases the
    GIL); a reference for :func:`rollout` and a fallback.

    Raises:
        ParameterError: states or controls of the wrong shape.
        Exception: whatever a worker thread raised (the first one), never a half-filled result.
    """
    from concurrent.futures import ThreadPoolExecutor

    m = world.model
    s0 = np.atleast_2d(np.asarray(initial_states, dtype=np.float64))
    control = np.asarray(control, dtype=np.float64)
    if control.ndim == 2:
        control = control[None]
    nstate = mujoco.mj_stateSize(m, STATE_SPEC)
    if s0.ndim != 2 or s0.shape[-1] != nstate:
        raise ParameterError(f"initial states must be (N, {nstate}) (FULLPHYSICS), got {s0.shape}")
    if control.ndim != 3 or control.shape[-1] != m.nu or len(control) not in (1, len(s0)):
        raise ParameterError(f"control must be (N or 1, T, {m.nu}) with N = {len(s0)}, got {control.shape}")
    n, nstep = len(s0), control.shape[1]
    out = np.full((n, nstep, nstate), np.nan)
    nthread = default_threads() if nthread is None else int(nthread)
    if nthread < 1:
        raise ParameterError(f"nthread must be at least 1, got {nthread}")

    def work(rows) -> None:
        d = mujoco.MjData(m)
        for i in rows:
            mujoco.mj_setState(m, d, s0[i], STATE_SPEC)
            ctl = control[i if len(control) > 1 else 0]
            for t in range(nstep):
                d.ctrl[:] = ctl[t if len(ctl) > 1 else 0]
                mujoco.mj_step(m, d)
                mujoco.mj_getState(m, d, out[i, t], STATE_SPEC)

    with ThreadPoolExecutor(max_workers=nthread) as ex:
        futures = [ex.submit(work, range(k, n, nthread)) for k in range(min(nthread, n))]
    for f in futures:
        f.result()  # re-raises a worker's exception here
    return RolloutResult(out, m.nq, m.nv, world.dt, *_divergence(m, out, world.config.max_speed, s0,
                                                                  m.opt.timestep))


def step_parallel(worlds: list, frames: int = 1, threads: int | None = None) -> None:
    """Step several independent worlds on a pool of threads (MuJoCo releases the GIL while it steps).

    Characters that never meet can live in separate worlds and use every core; characters that
    interact must share one world.
    """
    from concurrent.futures import ThreadPoolExecutor

    threads = default_threads() if threads is None else int(threads)
    if threads <= 1 or len(worlds) <= 1:
        for w in worlds:
            w.step(frames)
        return
    for w in worlds:  # compile in this thread first
        w.model  # noqa: B018 - compiles a world whose model changed
    with ThreadPoolExecutor(max_workers=threads) as ex:
        for f in [ex.submit(w.step, frames) for w in worlds]:
            f.result()
