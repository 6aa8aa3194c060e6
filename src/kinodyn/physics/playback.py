"""Playback: clips sampled at the physics rate, kinematic characters set from them, servo targets.

The stage of a :class:`~kinodyn.physics.world.World` that turns a :class:`~kinodyn.motion.Motion` into
what the engine needs (dynamic-response paper, section 6: a kinematic character plays the data; a
simulated one tracks it with PD servos): ``qpos`` by slerp at the physics rate, ``qvel`` by central finite
differences, servo targets with their feedforward (:func:`~kinodyn.physics.tracking.feedforward_targets`)
and lookahead. Each step a kinematic character's ``qpos``/``qvel`` block is set from its clip
(:func:`set_kinematic`) and the servo targets of the others are written to ``ctrl``
(:func:`set_ctrl`, :func:`frame_controls`).

The functions take the model's data, the character handles (their clip, addresses and targets) and the
world step; they keep no state. Shapes: ``n`` physics-rate samples; ``nq``/``nv``/``nu`` the character's
blocks (:class:`~kinodyn.physics.body.BodyMap`).
"""

from __future__ import annotations

import mujoco
import numpy as np

from kinodyn.errors import MotionError, ParameterError
from kinodyn.math import quat, xform
from kinodyn.motion import Motion
from kinodyn.physics import tracking
from kinodyn.physics.assembly import lowest_point
from kinodyn.physics.body import CharacterBody, check_skeleton, motion_to_qpos, pose_to_ctrl

__all__ = [
    "actuator_index",
    "clip_controls",
    "clip_qvel",
    "floor_offset",
    "frame_controls",
    "lead_steps",
    "sample_clip",
    "set_ctrl",
    "set_kinematic",
]


def clip_qvel(bmap, root_pos: np.ndarray, local_rot: np.ndarray, fps: float) -> np.ndarray:
    """``(F, nv)`` generalized velocities of a clip by central finite differences (one-sided at the
    ends), in MuJoCo's convention: free joints (world linear, local angular), ball joints (local angular),
    hinges (angle rate). Matches ``mj_differentiatePos`` on the neighbouring frames."""
    from kinodyn.physics.body import body_rotations

    f = len(root_pos)
    out = np.zeros((f, bmap.nv))
    if f < 2:
        return out
    brot = quat.unroll(body_rotations(bmap, local_rot))
    qp = motion_to_qpos(bmap, root_pos, local_rot)
    lo = np.maximum(np.arange(f) - 1, 0)
    hi = np.minimum(np.arange(f) + 1, f - 1)
    span = (hi - lo) / fps
    for b, s in enumerate(bmap.segments):
        v = bmap.dof_adr[b]
        if s.kind == "free":
            a = bmap.qpos_adr[b]
            out[:, v:v + 3] = (qp[hi, a:a + 3] - qp[lo, a:a + 3]) / span[:, None]
            out[:, v + 3:v + 6] = quat.to_rotvec(quat.inv_mul(brot[lo, b], brot[hi, b])) / span[:, None]
        elif s.kind == "ball":
            out[:, v:v + 3] = quat.to_rotvec(quat.inv_mul(brot[lo, b], brot[hi, b])) / span[:, None]
        elif s.kind == "hinge":
            a = bmap.qpos_adr[b]
            ang = np.unwrap(qp[:, a])
            out[:, v] = (ang[hi] - ang[lo]) / span
    return out


def lead_steps(body: CharacterBody, dt: float) -> np.ndarray:
    """``(nu,)`` steps by which each control's target leads: ``kv/kp`` of its servo, or the configured
    lookahead."""
    bm = body.map
    out = np.zeros(bm.nu, dtype=np.int64)
    for k, b in enumerate(bm.actuated):
        if body.pd.lookahead is not None:
            lead = body.pd.lookahead
        else:
            lead = body.kv[k] / body.kp[k] if body.kp[k] > 0 else 0.0
        a, w = bm.ctrl_adr[b], bm.ctrl_width[b]
        out[a:a + w] = round(lead / dt)
    return out


def sample_clip(char, motion: Motion, dt: float, root_quat, align_floor, loop: bool):
    """``motion`` sampled every ``dt`` seconds for ``char``.

    Args:
        root_quat: ``(4,)`` rotation of a fixed root (its mocap body), ``None`` for a free root.
        align_floor: ``True``/``"auto"`` puts the clip's lowest body point on the floor (median over
            time), a number shifts it by that, ``False``/``None`` keeps it.
        loop: also return the ground transform from one repetition to the next.

    Returns:
        ``(qpos (n, nq), qvel (n, nv), ctrl (n, nu), cycle (3,) or None)``.
    """
    check_skeleton(char.map, motion.skeleton)
    if motion.num_frames < 1:
        raise MotionError("cannot play an empty motion")
    bm = char.map
    rate = 1.0 / dt
    if motion.num_frames > 1:
        fine = motion.resample(rate)
        # velocities: central differences on the clip's own frames, interpolated to the physics rate
        v0 = clip_qvel(bm, motion.root_pos, motion.local_rot, motion.fps)
        t = np.arange(fine.num_frames) / rate
        src = np.arange(motion.num_frames) / motion.fps
        qvel = np.stack([np.interp(t, src, v0[:, i]) for i in range(bm.nv)], axis=1) if bm.nv else \
            np.zeros((fine.num_frames, 0))
    else:
        fine = motion
        qvel = np.zeros((1, bm.nv))
    root_pos = np.array(fine.root_pos)
    if align_floor is True or align_floor == "auto":
        root_pos[:, 2] += floor_offset(char, fine, dt)
    elif align_floor not in (False, None):
        root_pos[:, 2] += float(align_floor)
    qpos = motion_to_qpos(bm, root_pos, fine.local_rot)
    rq = None if root_quat is None else np.repeat(np.asarray(root_quat)[None], len(qpos), 0)
    ctrl = tracking.feedforward_targets(char.body, qpos, pose_to_ctrl(bm, fine.local_rot), qvel, dt,
                                        rq, lead_steps=char.lead_steps)
    g = fine.ground()
    cycle = xform.compose(g[-1], xform.inverse(g[0])) if loop and fine.num_frames > 1 else None
    return qpos, qvel, ctrl, cycle


def floor_offset(char, fine: Motion, dt: float) -> float:
    """Vertical shift that puts the clip's lowest body point on the floor (median over time)."""
    bm = char.map
    m = char.body.model()
    d = mujoco.MjData(m)
    step = max(1, round(0.05 / dt))
    frames = range(0, fine.num_frames, step)
    lows = []
    q = motion_to_qpos(bm, fine.root_pos[list(frames)], fine.local_rot[list(frames)])
    for k in range(len(q)):
        if bm.segments[0].kind == "free":
            d.qpos[:] = q[k]
        else:
            d.qpos[:] = q[k]
            d.mocap_pos[0] = fine.root_pos[frames[k]]
            d.mocap_quat[0] = fine.local_rot[frames[k], 0]
        mujoco.mj_kinematics(m, d)
        lows.append(lowest_point(m, d, np.arange(1, m.ngeom)))
    return float(-np.percentile(lows, 50))


def set_kinematic(data: mujoco.MjData, c, step: int) -> None:
    """Set a kinematic character's ``qpos``/``qvel`` block from its clip at world step ``step``."""
    data.qpos[c.qadr:c.qadr + c.map.nq], data.qvel[c.vadr:c.vadr + c.map.nv] = c.clip.state(step)


def set_ctrl(data: mujoco.MjData, c, step: int) -> None:
    """Write a character's servo targets at world step ``step``: its fixed target, its clip's (with the
    lookahead) or the rest pose."""
    if c.ctrl_target is not None:
        data.ctrl[c.cadr:c.cadr + c.map.nu] = c.ctrl_target
    elif c.clip is not None:
        rows = c.clip.indices(step + c.lead_steps)
        data.ctrl[c.cadr:c.cadr + c.map.nu] = c.clip.ctrl[rows, c.ctrl_cols]
    else:
        data.ctrl[c.cadr:c.cadr + c.map.nu] = c.rest_ctrl


def frame_controls(characters, data: mujoco.MjData, step: int, nsub: int, ctrl_prev=None, offset: int = 0):
    """``(offset + nsub, nu)`` servo targets of the ``nsub`` steps from world step ``step`` on (rows from
    ``offset`` on are filled) for characters following a clip; ``ctrl_prev`` when nobody does.

    Kinematic characters are included: their servos change nothing while the clip sets their state, but
    the step in which something hits one is integrated by the engine before it turns dynamic, and that
    step must pull toward the clip's pose of that instant, not toward the one it started from."""
    follow = [c for c in characters if c.ctrl_target is None and c.clip is not None]
    if not follow:
        return ctrl_prev
    out = np.empty((offset + nsub, len(data.ctrl))) if ctrl_prev is None else ctrl_prev
    out[offset:] = data.ctrl
    steps = step + np.arange(nsub)[:, None]
    for c in follow:
        rows = c.clip.indices(steps + c.lead_steps[None, :])
        out[offset:, c.cadr:c.cadr + c.map.nu] = c.clip.ctrl[rows, c.ctrl_cols[None, :]]
    return out


def clip_controls(characters, ctrl: np.ndarray, nstep: int, start: int) -> np.ndarray:
    """``(nstep, nu)`` servo targets of the steps from world step ``start`` on, every character's as
    :func:`set_ctrl` writes them (``ctrl (nu,)``: the current controls, kept for actuators of nobody)."""
    out = np.empty((nstep, len(ctrl)))
    out[:] = ctrl
    steps = np.arange(start, start + nstep)
    for c in characters:
        sl = slice(c.cadr, c.cadr + c.map.nu)
        if c.ctrl_target is not None:
            out[:, sl] = c.ctrl_target
        elif c.clip is not None:
            rows = c.clip.indices(steps[:, None] + c.lead_steps[None, :])
            out[:, sl] = c.clip.ctrl[rows, c.ctrl_cols[None, :]]
        else:
            out[:, sl] = c.rest_ctrl
    return out


def actuator_index(char, joints) -> np.ndarray:
    """``(k,)`` actuator numbers of a character's segments, joints or landmarks (a name or a list)."""
    if isinstance(joints, str):
        joints = [joints]
    pos = {int(b): k for k, b in enumerate(char.map.actuated)}
    out = []
    for j in joints:
        b = char.map.body(j)
        if b not in pos:
            raise ParameterError(f"{j!r} ({char.map.segments[b].name}) has no servo (the root is unactuated)")
        out.append(pos[b])
    return np.array(out, dtype=np.int64)
