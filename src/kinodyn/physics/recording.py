"""Recording and checks: each frame's state kept, read back as Motions, and divergence caught.

The last stage of every frame of a :class:`~kinodyn.physics.world.World`. :class:`Recording` keeps the
whole ``qpos`` and the mocap poses once per output frame (adding characters or balls later only appends
to ``qpos`` and the mocap arrays, so the addresses of what existed stay valid in older rows);
:func:`trajectory` turns a character's rows into a :class:`~kinodyn.motion.Motion`.
:func:`divergence` looks at the state after a frame: a warning MuJoCo raised (it resets the state on a
NaN or huge ``qpos``/``qvel``/``qacc``, which must not pass unnoticed), a non-finite state or a speed
above the limit, and names the steps and the body.

Shapes: ``F`` recorded frames; ``nq`` and ``nmocap`` the world model's sizes when a row was recorded.
"""

from __future__ import annotations

import mujoco
import numpy as np

from kinodyn.errors import ParameterError, SimulationDivergedError
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.physics.body import qpos_to_local_rot

__all__ = ["BAD_WARNINGS", "Recording", "divergence", "no_log_file", "trajectory", "warning_counts"]

#: MuJoCo warnings that mean the state went bad (MuJoCo reset it), with what went bad.
BAD_WARNINGS = (("qacc", mujoco.mjtWarning.mjWARN_BADQACC), ("qvel", mujoco.mjtWarning.mjWARN_BADQVEL),
                ("qpos", mujoco.mjtWarning.mjWARN_BADQPOS))


def no_log_file() -> None:
    """Stop MuJoCo from appending its warnings to ``MUJOCO_LOG.TXT`` in the working directory (its
    default log file; a diverging simulation writes one there). Kinodyn turns those warnings into
    :class:`SimulationDivergedError` instead; MuJoCo still prints them. A log file configured elsewhere
    (``mujoco.MjLogConfig``) is kept. Process-wide, as MuJoCo's log configuration is."""
    cfg = mujoco.MjLogConfig.get()
    if cfg.logto_file and cfg.logfile in ("MUJOCO_LOG.TXT", ""):
        cfg.logto_file = False
        cfg.set()


class Recording:
    """Per-frame rows of a world's state (mutable; owned by a World).

    Attributes:
        qpos: ``F`` rows of the whole ``qpos``.
        mocap: ``F`` rows of ``(mocap_pos, mocap_quat)``.
        steps: ``F`` world steps at which the rows were taken.
    """

    def __init__(self):
        self.qpos: list[np.ndarray] = []
        self.mocap: list[tuple[np.ndarray, np.ndarray]] = []
        self.steps: list[int] = []

    def __len__(self) -> int:
        return len(self.steps)

    def append(self, data: mujoco.MjData, step: int) -> None:
        """Keep the current state as the row of world step ``step``."""
        self.qpos.append(data.qpos.copy())
        self.mocap.append((data.mocap_pos.copy(), data.mocap_quat.copy()))
        self.steps.append(step)

    def times(self, dt: float) -> np.ndarray:
        """``(F,)`` world times of the rows (``dt`` seconds per step)."""
        return np.array(self.steps, dtype=np.float64) * dt


def trajectory(rec: Recording, char, dt: float, fps: float, name: str, start: float | None = None,
               stop: float | None = None) -> Motion:
    """The recorded motion of ``char`` between world times ``start`` and ``stop`` (inclusive; default
    everything) as a :class:`Motion` at ``fps`` (the rate of the rows), named ``name``.

    Raises:
        ParameterError: no row of ``char`` in that range.
    """
    bm = char.map
    t = rec.times(dt)
    # frames recorded since the character exists
    sel = np.array([len(q) >= char.qadr + bm.nq and (char.mocap_id < 0 or len(mc[0]) > char.mocap_id)
                    for q, mc in zip(rec.qpos, rec.mocap)])
    if start is not None:
        sel &= t >= start - 1e-9
    if stop is not None:
        sel &= t <= stop + 1e-9
    if not sel.any():
        raise ParameterError(f"no recorded frame of {char.name!r} between {start} and {stop} s")
    idx = np.nonzero(sel)[0]
    block = np.array([rec.qpos[i][char.qadr:char.qadr + bm.nq] for i in idx]).reshape(len(idx), bm.nq)
    if char.mocap_id >= 0:
        root_pos = np.array([rec.mocap[i][0][char.mocap_id] for i in idx])
        root_quat = np.array([rec.mocap[i][1][char.mocap_id] for i in idx])
        local = qpos_to_local_rot(bm, block, root_quat)
    else:
        root_pos = block[:, :3]
        local = qpos_to_local_rot(bm, block)
    return Motion(char.skeleton, root_pos, quat.unroll(local), fps, name=name)


def warning_counts(data: mujoco.MjData) -> np.ndarray:
    """``(W,)`` how often MuJoCo raised each warning so far (compare before and after a frame)."""
    return np.array(data.warning.number, dtype=np.int64)


def divergence(model: mujoco.MjModel, data: mujoco.MjData, warn0: np.ndarray, max_speed: float, step: int,
               substeps: int, time: float) -> SimulationDivergedError | None:
    """The error to raise when the frame that ended at world step ``step`` (``substeps`` steps, at world
    time ``time``) went bad, else ``None``.

    Bad: MuJoCo raised a bad-state warning more often than ``warn0 (W,)`` counts, the state is
    non-finite, or a speed exceeds ``max_speed`` (m/s or rad/s).
    """
    m, d = model, data
    warn = warning_counts(d)
    problem, dof = None, -1
    for what, w in BAD_WARNINGS:
        if warn[int(w)] > warn0[int(w)]:
            problem = f"MuJoCo found a NaN or huge {what} and reset the state"
            dof = int(d.warning[int(w)].lastinfo)
            break
    if problem is None:
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            problem = "the state became non-finite (NaN or inf)"
            dof = int(np.argmax(~np.isfinite(d.qvel))) if not np.isfinite(d.qvel).all() else -1
        elif m.nv and float(np.max(np.abs(d.qvel))) > max_speed:
            dof = int(np.argmax(np.abs(d.qvel)))
            problem = f"a velocity reached {abs(d.qvel[dof]):.3g} (limit {max_speed:g} m/s or rad/s)"
    if problem is None:
        return None
    body = m.body(m.dof_bodyid[dof]).name if 0 <= dof < m.nv else ""
    first = step - substeps + 1
    return SimulationDivergedError(f"simulation diverged in steps {first}-{step} (t <= {time:.4f} s)"
                                   f"{f' at body {body!r}' if body else ''}: {problem}", step=step, body=body)
