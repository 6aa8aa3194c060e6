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

import hashlib
from collections import OrderedDict

import mujoco
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from kinodyn.errors import MotionError, ParameterError
from kinodyn.math import quat, xform
from kinodyn.motion import Motion
from kinodyn.physics import tracking
from kinodyn.physics.assembly import lowest_point
from kinodyn.physics.body import CharacterBody, check_skeleton, motion_to_qpos, pose_to_ctrl

__all__ = [
    "REST_DEPTH",
    "actuator_index",
    "clip_controls",
    "clip_qvel",
    "floor_plane",
    "floor_shift",
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
    """``(nu,)`` steps by which each control's target leads: the configured lookahead, else ``kv/kp`` of
    its servo (none with ``feedforward="dynamics"``, whose torques carry the damping)."""
    bm = body.map
    out = np.zeros(bm.nu, dtype=np.int64)
    for k, b in enumerate(bm.actuated):
        if body.pd.lookahead is not None:
            lead = body.pd.lookahead
        elif body.pd.feedforward == "dynamics":
            lead = 0.0  # its feedforward carries the servo's damping of the clip's velocities
        else:
            lead = body.kv[k] / body.kp[k] if body.kp[k] > 0 else 0.0
        a, w = bm.ctrl_adr[b], bm.ctrl_width[b]
        out[a:a + w] = round(lead / dt)
    return out


#: Recently sampled clips, by content (see :func:`sample_clip`): a response world plays the same looped base
#: motion for every impact, and its servo feed-forward is most of the cost of a training case.
_SAMPLED: OrderedDict = OrderedDict()
_SAMPLED_MAX = 128


def _sample_key(char, motion: Motion, dt: float, root_quat, align_floor, loop: bool) -> tuple:
    h = hashlib.blake2b(motion.digest().encode(), digest_size=20)
    for a in (char.lead_steps, np.zeros(0) if root_quat is None else np.asarray(root_quat, dtype=np.float64)):
        h.update(np.ascontiguousarray(a).tobytes())
        h.update(b"|")
    return (id(char.body), h.hexdigest(), float(dt), root_quat is None, repr(align_floor), bool(loop))


def sample_clip(char, motion: Motion, dt: float, root_quat, align_floor, loop: bool):
    """``motion`` sampled every ``dt`` seconds for ``char`` (a pure function of its inputs: the last
    :data:`_SAMPLED_MAX` results are kept by content and handed out as copies).

    Args:
        root_quat: ``(4,)`` rotation of a fixed root (its mocap body), ``None`` for a free root.
        align_floor: ``True``/``"auto"`` puts the clip's capture floor (a plane fitted to the body's
            lowest points, :func:`floor_plane`) on the world's floor, frame by frame; a number shifts the
            clip by that; ``False``/``None`` keeps it.
        loop: also return the ground transform from one repetition to the next.

    Returns:
        ``(qpos (n, nq), qvel (n, nv), ctrl (n, nu), cycle (3,) or None)``.
    """
    check_skeleton(char.map, motion.skeleton)
    if motion.num_frames < 1:
        raise MotionError("cannot play an empty motion")
    key = _sample_key(char, motion, dt, root_quat, align_floor, loop)
    if key not in _SAMPLED:
        _SAMPLED[key] = (char.body, _sample_clip(char, motion, dt, root_quat, align_floor, loop))
        while len(_SAMPLED) > _SAMPLED_MAX:
            _SAMPLED.popitem(last=False)
    _SAMPLED.move_to_end(key)
    return tuple(None if a is None else np.array(a) for a in _SAMPLED[key][1])


def _sample_clip(char, motion: Motion, dt: float, root_quat, align_floor, loop: bool):
    bm = char.map
    rate = 1.0 / dt
    if align_floor is True or align_floor == "auto":
        motion = _shifted(motion, floor_shift(char, motion))
    elif align_floor not in (False, None):
        motion = _shifted(motion, np.full(motion.num_frames, float(align_floor)))
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
    qpos = motion_to_qpos(bm, root_pos, fine.local_rot)
    rq = None if root_quat is None else np.repeat(np.asarray(root_quat)[None], len(qpos), 0)
    ctrl = tracking.feedforward_targets(char.body, qpos, pose_to_ctrl(bm, fine.local_rot), qvel, dt,
                                        rq, lead_steps=char.lead_steps)
    g = fine.ground()
    cycle = xform.compose(g[-1], xform.inverse(g[0])) if loop and fine.num_frames > 1 else None
    return qpos, qvel, ctrl, cycle


#: Depth (m) at which the soles of the built-in humanoid rest in the default ground when it stands
#: simulated (0.38-0.39 mm measured). Clips are played with their support this deep, not exactly at
#: z = 0: a sole exactly on the plane touches it or not by the last bit of a float, and with it the
#: ground's support in the first steps after a switch to dynamic (on the built-in walk at 1 s, floors
#: 1e-12 m apart gave 4.1 % and 6.8 % body velocity change one frame after the switch).
REST_DEPTH = 0.0004


def _shifted(motion: Motion, dz: np.ndarray) -> Motion:
    """``motion`` with its root moved up by ``dz (F,)`` metres."""
    root = np.array(motion.root_pos)
    root[:, 2] += dz
    return motion.replace(root_pos=root)


def _lowest_points(char, motion: Motion) -> np.ndarray:
    """``(F,)`` lowest world z of the body's geometry in every frame of ``motion``."""
    bm = char.map
    m = char.body.model()
    d = mujoco.MjData(m)
    q = motion_to_qpos(bm, motion.root_pos, motion.local_rot)
    geoms = np.arange(1, m.ngeom)
    lows = np.empty(motion.num_frames)
    for f in range(motion.num_frames):
        d.qpos[:] = q[f]
        if bm.segments[0].kind != "free":
            d.mocap_pos[0] = motion.root_pos[f]
            d.mocap_quat[0] = motion.local_rot[f, 0]
        mujoco.mj_kinematics(m, d)
        lows[f] = lowest_point(m, d, geoms)
    return lows


def floor_plane(xy: np.ndarray, lows: np.ndarray) -> np.ndarray:
    """``(3,)`` plane ``z = a + b x + c y`` of the floor a clip was captured on, fitted to the body's
    lowest points ``lows (F,)`` at the root's ``xy (F, 2)``.

    A capture floor is rarely level with the capture's Z = 0 (CMU 02_01 rises 4 cm over its walk), so one
    offset leaves the feet inside the floor at one end and above it at the other. The fit is trimmed: the
    lowest point is on the floor in support and above it in flight, so each of three refits keeps the 60 %
    of frames lowest above the last plane. Slopes are fitted only along directions the root travels at
    least 0.3 m, and a floor that rises less than 1 cm over the clip counts as level."""
    level = np.array([np.median(lows), 0.0, 0.0])
    if len(lows) < 6:
        return level
    # slopes only along the directions the clip travels far enough to tell a slope from noise (a straight
    # walk sways a few centimetres sideways)
    centre = xy.mean(axis=0)
    axes = np.linalg.svd(xy - centre, full_matrices=False)[2]
    span = np.ptp((xy - centre) @ axes.T, axis=0)
    axes = axes[span >= 0.3]
    if not len(axes):
        return level
    a = np.column_stack([np.ones(len(lows)), (xy - centre) @ axes.T])
    coef = np.array([np.median(lows)] + [0.0] * len(axes))
    for _ in range(3):
        res = lows - a @ coef
        keep = res <= np.percentile(res, 60)
        coef = np.linalg.lstsq(a[keep], lows[keep], rcond=None)[0]
    if np.max(np.abs(coef[1:]) * span[span >= 0.3]) < 0.01:
        return level  # a floor rising less than 1 cm over the clip counts as level
    slope = coef[1:] @ axes
    return np.array([coef[0] - centre @ slope, *slope])


def floor_shift(char, motion: Motion, flight: float = 0.02, window: float = 0.25, smooth: float = 0.5
                ) -> np.ndarray:
    """``(F,)`` vertical shift of each frame that puts the supporting foot on the world's floor z = 0.

    The capture floor is the plane :func:`floor_plane` fits under the root. On top of it the floor
    follows the support: in frames where the body's lowest point is within ``flight`` metres of the
    plane, the lower fifth of the lowest point's heights over ``window`` seconds (the sole in support,
    not the heel or toe rolling above it, nor a toe dipping through for a frame) is the floor there; interpolated across flight and smoothed over ``smooth`` seconds (a
    moving average, so the shift adds no step-to-step jitter to the clip's vertical velocity). A clip
    captured on a level floor keeps one shift; one whose floor rises or bends keeps its stance feet on
    the world's floor throughout, so a switch to dynamic at any instant finds them there. The support
    ends :data:`REST_DEPTH` below z = 0, where a simulated body rests."""
    lows = _lowest_points(char, motion)
    xy = motion.root_pos[:, :2]
    plane = floor_plane(xy, lows)
    floor = plane[0] + xy @ plane[1:]
    res = lows - floor
    support = res < flight
    if support.any() and motion.num_frames > 1:
        f = np.arange(motion.num_frames)
        res = np.interp(f, f[support], res[support])
        half = max(1, round(window * motion.fps / 2))
        res = np.percentile(sliding_window_view(np.pad(res, half, mode="edge"), 2 * half + 1), 20, axis=1)
        w = max(1, round(smooth * motion.fps) | 1)  # odd window
        res = np.convolve(np.pad(res, w // 2, mode="edge"), np.ones(w) / w, mode="valid")
        floor = floor + res
    return -floor - REST_DEPTH


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
