"""The real-time motion mixer: actions with priorities and ramps, synchronized, blended per frame.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, sections 3 and 5 (after the
blending module of their reference [Lba]). An *action* plays a clip (or a clip adapted by a parametric
model, such as a time scaling) and is started and stopped at any time. Its weight ramps up from 0
over ``ramp_in`` seconds after it starts (``t1 -> t2`` of figure 2) and down to 0 over ``ramp_out``
seconds after it is stopped (``t3 -> t4``), with a smoothstep. *Priorities* resolve the weights:
actions of a higher priority take the legs and body first (their summed activation, capped at 1, is
their share), lower ones get what is left, and a neutral double-support pose of lowest priority takes
the remainder, so the character stands when nothing plays. Actions of the same priority share by
activation.

With ``synchronize=True`` every character runs a :class:`~kinodyn.blend.sync.Synchronizer` and a
:class:`~kinodyn.blend.timewarp.WarpPlanner`: actions start at a step boundary, their support phases
are organized so that no step mixes a left and a right single support, and each action's time is
warped to the common steps. An action stopped while another waits for its synchronized start hands
over: it plays on until the newcomer starts, then fades out. With ``synchronize=False`` (the baseline)
actions start when asked and play at their own speed.

Blending: local joint rotations are averaged with the weights (normalized weighted sum of
hemisphere-aligned quaternions, or Markley's eigenvector mean); the root is blended in each action's
*facing frame*: its height and its rotation without heading are averaged, and its motion over the
frame (floor displacement and heading change, expressed in the action's own facing frame) is averaged
and integrated in the character's frame, so a mix of straight walks goes straight. With
synchronization the support constraints are then enforced (:mod:`kinodyn.blend.footlock`): the
planted feet stay where they landed.

Per-frame evaluation is batched over characters: every array is ``(N, S, ...)`` for ``N`` characters
and ``S`` action slots (numpy, with the frame blend and the leg IK as compiled kernels looping over
characters); Python runs per character only when one of its steps ends or on a command.
Shapes: ``J`` joints. Units: seconds, metres, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numba
import numpy as np

from kinodyn import contacts
from kinodyn import phases as _phases
from kinodyn.phases import PhaseConfig, PhaseSequence
from kinodyn.blend.sync import SyncConfig, Synchronizer
from kinodyn.blend.timewarp import WarpConfig, WarpPlanner, eval_poly
from kinodyn.errors import MotionError, ParameterError, UnknownNameError
from kinodyn.kinematics import fk_link
from kinodyn.math import quat, xform
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

__all__ = [
    "ActionState",
    "BlendConfig",
    "ClipLibrary",
    "Mixer",
    "Pose",
    "Recording",
    "activation",
    "blend_frames",
    "blend_frames_fast",
    "blend_rotations",
    "priority_weights",
    "smoothstep",
]

_AVERAGES = ("nlerp", "markley")


@dataclass(frozen=True)
class BlendConfig:
    """Mixer parameters.

    Attributes:
        synchronize: run the support-phase synchronization (False: the unsynchronized baseline).
        sync: :class:`~kinodyn.blend.sync.SyncConfig` (``nk``).
        warp: :class:`~kinodyn.blend.timewarp.WarpConfig` (spline tension).
        ramp_in: default activation duration ``t2 - t1`` in seconds.
        ramp_out: default deactivation duration ``t4 - t3`` in seconds.
        max_actions: action slots per character (actions playing or fading at once).
        average: ``"nlerp"`` (normalized weighted sum, fast) or ``"markley"`` (eigenvector mean).
        constraints: enforce the support after blending (:mod:`kinodyn.blend.footlock`): planted feet
            stay where they landed (the root follows the held feet by the weight each carries,
            two-bone IK pins them). ``"auto"``: on with synchronization, off without (without synchronization the
            actions disagree on which foot carries the body, so there is no single constraint to
            enforce); ``"on"`` / ``"off"`` force it.
        root_halflife: seconds for the root to follow the held feet (IK pins the feet in
            the meantime; a short halflife keeps the legs natural, a non-zero one keeps the root
            smooth when the support changes foot).
        release_halflife: seconds over which a lifted foot's IK correction fades out.
        max_foot_offset: metres a planted foot may be held away from where the blended pose puts it;
            beyond that, or beyond what the leg reaches, it follows the pose (it slides) instead of
            stretching the leg.
        max_pelvis_drop: metres the pelvis may come down so that a planted foot stays within its leg's
            reach (a straight back leg at push-off); 0 never lowers it.
    """

    synchronize: bool = True
    sync: SyncConfig = SyncConfig()
    warp: WarpConfig = WarpConfig()
    ramp_in: float = 0.4
    ramp_out: float = 0.4
    max_actions: int = 6
    average: str = "nlerp"
    constraints: str = "auto"
    root_halflife: float = 0.04
    release_halflife: float = 0.05
    max_foot_offset: float = 0.5
    max_pelvis_drop: float = 0.05

    @property
    def enforce(self) -> bool:
        """Whether support constraints are enforced (see ``constraints``)."""
        return self.constraints == "on" or (self.constraints == "auto" and self.synchronize)

    def __post_init__(self):
        for name in ("ramp_in", "ramp_out"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f"{name} must be a non-negative number of seconds, got {v}")
        if not isinstance(self.max_actions, int) or self.max_actions < 1:
            raise ParameterError(f"max_actions must be an integer >= 1, got {self.max_actions!r}")
        if self.constraints not in ("auto", "on", "off"):
            raise ParameterError(f"constraints must be 'auto', 'on' or 'off', got {self.constraints!r}")
        if not (np.isfinite(self.max_foot_offset) and self.max_foot_offset > 0):
            raise ParameterError(f"max_foot_offset must be a positive number of metres, got {self.max_foot_offset}")
        for name in ("root_halflife", "release_halflife", "max_pelvis_drop"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f"{name} must be a non-negative number of seconds, got {v}")
        if self.average not in _AVERAGES:
            raise ParameterError(f"average must be one of {', '.join(_AVERAGES)}, got {self.average!r}")


class Pose(NamedTuple):
    """Poses of ``N`` characters: ``root_pos (N, 3)`` and ``local_rot (N, J, 4)``."""

    root_pos: np.ndarray
    local_rot: np.ndarray


# ----------------------------------------------------------------------------------------- weights


def smoothstep(x):
    """``3x^2 - 2x^3`` on ``[0, 1]``, 0 below, 1 above."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def activation(t, t_on, ramp_in, t_off, ramp_out):
    """Activation level of actions at time ``t`` (figure 2): 0 before ``t_on``, up to 1 at ``t_on +
    ramp_in``, down from ``t_off`` to 0 at ``t_off + ramp_out``. Arrays broadcast; ``inf`` disables."""
    t = np.asarray(t, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        up = np.where(np.asarray(ramp_in) > 0, smoothstep((t - t_on) / np.maximum(ramp_in, 1e-12)),
                      (t >= t_on).astype(np.float64))
        down = np.where(np.asarray(ramp_out) > 0, smoothstep((t - t_off) / np.maximum(ramp_out, 1e-12)),
                        (t >= t_off).astype(np.float64))
    up = np.where(np.isfinite(t_on), up, 0.0)
    down = np.where(np.isfinite(t_off), down, 0.0)
    return up * (1.0 - down)


def priority_weights(act, prio) -> tuple[np.ndarray, np.ndarray]:
    """Blend weights from activations and priorities.

    Args:
        act: ``(N, S)`` activation levels in ``[0, 1]``.
        prio: ``(N, S)`` priorities (higher first); empty slots may hold any value with ``act = 0``.

    Returns:
        ``w (N, S)`` and the neutral pose's weight ``(N,)``; they sum to 1 per character. A priority
        level's share is ``min(1, sum of its activations)`` of what higher levels left, split among
        its actions in proportion to their activation.
    """
    act = np.asarray(act, dtype=np.float64)
    prio = np.asarray(prio, dtype=np.float64)
    same = prio[:, :, None] == prio[:, None, :]                      # (N, S, S)
    group = np.einsum("nst,nt->ns", same, act)                        # summed activation of s's level
    cover = np.minimum(group, 1.0)
    higher = prio[:, None, :] > prio[:, :, None]                      # t strictly above s
    # (1 - cover_t) once per higher level: average the log over the members of each level
    members = same.sum(axis=2)                                        # (N, S) size of each level
    with np.errstate(divide="ignore"):
        logfree = np.log(np.maximum(1.0 - cover, 0.0)) / members      # -inf when a level covers all
    logfree = np.where(np.isfinite(logfree), logfree, -np.inf)
    above = np.einsum("nst,nt->ns", higher, np.where(np.isfinite(logfree), logfree, 0.0))
    blocked = np.einsum("nst,nt->ns", higher, ~np.isfinite(logfree)) > 0
    rem = np.where(blocked, 0.0, np.exp(above))
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(group > 0, rem * cover * act / np.where(group > 0, group, 1.0), 0.0)
    return w, np.clip(1.0 - w.sum(axis=1), 0.0, 1.0)


def blend_rotations(q, w, ref, wref, method: str = "nlerp") -> np.ndarray:
    """Weighted average of rotations ``q (N, S, J, 4)`` with weights ``w (N, S)`` and a reference pose
    ``ref (J, 4)`` of weight ``wref (N,)`` (the neutral pose); returns ``(N, J, 4)``.

    ``nlerp``: every quaternion is put in the hemisphere of the one with the most weight and the weighted
    sum is normalized (the first-order approximation of the chordal mean; within a fraction of a degree
    of it for rotations less than about 30 degrees apart). ``markley``: the eigenvector mean of
    :func:`kinodyn.math.quat.average`.
    """
    if method == "markley":
        allq = np.concatenate([q, np.broadcast_to(ref, (q.shape[0], 1) + ref.shape)], axis=1)
        allw = np.concatenate([w, wref[:, None]], axis=1)
        return quat.average(allq, np.broadcast_to(allw[:, :, None], allq.shape[:-1]), axis=1)
    # hemisphere of the rotation with the most weight (the neutral pose's or a slot's), per joint
    top = np.argmax(w, axis=1)
    anchor = np.where((wref >= w.max(axis=1))[:, None, None], ref, q[np.arange(len(q)), top])
    sign = np.where(np.einsum("nsjc,njc->nsj", q, anchor) < 0.0, -1.0, 1.0)
    sref = np.where(np.einsum("jc,njc->nj", ref, anchor) < 0.0, -1.0, 1.0)
    acc = np.einsum("nsjc,nsj->njc", q, sign * w[:, :, None]) + (wref[:, None] * sref)[..., None] * ref
    return acc / np.maximum(np.linalg.norm(acc, axis=-1, keepdims=True), 1e-12)


def _rotate(q, v):
    """``quat.mul_vec`` for ``q (..., 4)`` and ``v (..., 3)`` written out (no ``np.cross`` overhead)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return np.stack([vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz),
                     vz + w * tz + (x * ty - y * tx)], axis=-1)


def blend_frames(rot_db, i0, a, w, ref, wref) -> np.ndarray:
    """Weighted blend of clip frames, each interpolated between two database frames (numpy reference).

    Args:
        rot_db: ``(F, J, 4)`` packed frames (consecutive frames of a clip in the same hemisphere).
        i0: ``(N, S)`` first frame of each sample; ``a (N, S)`` the fraction toward ``i0 + 1``.
        w: ``(N, S)`` weights; ``ref (J, 4)`` the neutral pose with weights ``wref (N,)``.

    Returns:
        ``(N, J, 4)``: the normalized sum of ``w * lerp(frame i0, frame i0 + 1)`` and ``wref * ref``,
        every quaternion first put in the hemisphere of the one with the most weight.
    """
    N, S = w.shape
    top = np.argmax(w, axis=1)
    rows_n = np.arange(N)
    anchor = np.where((wref >= w[rows_n, top])[:, None, None], ref, rot_db[i0[rows_n, top]])
    sref = np.where(np.einsum("jc,njc->nj", ref, anchor) < 0.0, -1.0, 1.0)
    q = (wref[:, None] * sref)[..., None] * ref
    for k in range(S):
        live = w[:, k] > 0.0
        if not live.any():
            continue
        rows = None if live.all() else np.nonzero(live)[0]
        ik = i0[:, k] if rows is None else i0[rows, k]
        wk = w[:, k] if rows is None else w[rows, k]
        ak = a[:, k] if rows is None else a[rows, k]
        r0 = rot_db[ik]
        r1 = rot_db[ik + 1]
        sign = np.where(np.einsum("njc,njc->nj", r0, anchor if rows is None else anchor[rows]) < 0.0, -1.0, 1.0)
        c1 = (wk * ak)[:, None] * sign
        c0 = wk[:, None] * sign - c1
        r0 *= c0[..., None]
        r1 *= c1[..., None]
        r0 += r1
        if rows is None:
            q += r0
        else:
            q[rows] += r0
    q /= np.maximum(np.sqrt(np.einsum("njc,njc->nj", q, q)), 1e-12)[..., None]
    return q


@numba.njit(cache=True)
def _blend_kernel(rot_db, i0, a, w, ref, wref, out):  # pragma: no cover - compiled
    n_chars, n_slots = w.shape
    n_joints = ref.shape[0]
    for n in range(n_chars):
        top = -1
        best = wref[n]
        for k in range(n_slots):
            if w[n, k] > best:
                best = w[n, k]
                top = k
        for j in range(n_joints):
            if top < 0:
                x0, x1, x2, x3 = ref[j, 0], ref[j, 1], ref[j, 2], ref[j, 3]
            else:
                f = i0[n, top]
                x0, x1, x2, x3 = rot_db[f, j, 0], rot_db[f, j, 1], rot_db[f, j, 2], rot_db[f, j, 3]
            s = 1.0 if ref[j, 0] * x0 + ref[j, 1] * x1 + ref[j, 2] * x2 + ref[j, 3] * x3 >= 0.0 else -1.0
            c = wref[n] * s
            q0, q1, q2, q3 = c * ref[j, 0], c * ref[j, 1], c * ref[j, 2], c * ref[j, 3]
            for k in range(n_slots):
                wk = w[n, k]
                if wk <= 0.0:
                    continue
                f = i0[n, k]
                r0, r1, r2, r3 = rot_db[f, j, 0], rot_db[f, j, 1], rot_db[f, j, 2], rot_db[f, j, 3]
                s = 1.0 if r0 * x0 + r1 * x1 + r2 * x2 + r3 * x3 >= 0.0 else -1.0
                c1 = wk * a[n, k] * s
                c0 = wk * s - c1
                q0 += c0 * r0 + c1 * rot_db[f + 1, j, 0]
                q1 += c0 * r1 + c1 * rot_db[f + 1, j, 1]
                q2 += c0 * r2 + c1 * rot_db[f + 1, j, 2]
                q3 += c0 * r3 + c1 * rot_db[f + 1, j, 3]
            nrm = max(np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3), 1e-12)
            out[n, j, 0] = q0 / nrm
            out[n, j, 1] = q1 / nrm
            out[n, j, 2] = q2 / nrm
            out[n, j, 3] = q3 / nrm


@numba.njit(cache=True)
def _support_kernel(w, wn, phase, left, support, planted, vote):  # pragma: no cover - compiled
    """Planted feet, their votes and the foot carrying most weight of every character (the first part of
    ``_constrain``)."""
    n_chars, n_slots = w.shape
    for n in range(n_chars):
        sl = 0.0
        sr = 0.0
        for k in range(n_slots):
            p = phase[n, k]
            sl += w[n, k] if (p == 2 or p == 0) else 0.0   # LS or DS put the left foot down
            sr += w[n, k] if (p == 1 or p == 0) else 0.0   # RS or DS put the right foot down
        vote[n, 0] = sl + wn[n]
        vote[n, 1] = sr + wn[n]
        pl = vote[n, 0] >= 0.5
        pr = vote[n, 1] >= 0.5
        planted[n, 0] = pl
        planted[n, 1] = pr
        if pl and pr:
            support[n] = 1 if left[n] >= 0.5 else 2
        elif pl:
            support[n] = 1
        elif pr:
            support[n] = 2
        else:
            support[n] = 0


#: Fraction of a leg's length up to which the pelvis lowers to keep a held foot within reach (a knee
#: that stays slightly bent keeps the two-bone solution well conditioned).
_REACH_MARGIN = 0.995
#: Seconds the pelvis takes at least to come down by ``max_pelvis_drop`` (no sudden crouch).
_DROP_TIME = 0.2


@numba.njit(cache=True)
def _hold_kernel(root, q, offsets, parents, chain, gr, gp, planted, vote, left, rest, was_planted, foot_pt, foot_xy,
                 release, release_z, drop, leg_joints, n_joints, end_par, end_off, n_ends, hips, ankles, reach, alpha,
                 decay, lim, max_drop, rise, target, xy, lift, need):  # pragma: no cover - compiled
    """Where each foot is held and how far the root follows (the middle part of ``_constrain``, one pass
    per character). Forward kinematics fills ``gr``, ``gp`` for the joints of ``chain`` (the root, the legs
    and their ancestors, parents first) only; ``root``, ``gp``, ``foot_pt``, ``foot_xy``, ``release``,
    ``release_z``, ``drop`` are updated in place; ``target``, ``xy``, ``lift`` (how far each
    ankle goes up) and ``need`` are outputs."""
    n_chars = root.shape[0]
    pz = np.empty(leg_joints.shape[1] + end_par.shape[1])
    px = np.empty_like(pz)
    py = np.empty_like(pz)
    for n in range(n_chars):
        # forward kinematics of the leg chains only
        for c in range(4):
            gr[n, 0, c] = q[n, 0, c]
        for c in range(3):
            gp[n, 0, c] = root[n, c]
        for i in range(chain.shape[0]):
            j = chain[i]
            fk_link(gr[n], gp[n], parents[j], j, q[n, j], offsets[j])
        for s in range(2):
            m = 0
            for i in range(n_joints[s]):
                j = leg_joints[s, i]
                px[m], py[m], pz[m] = gp[n, j, 0], gp[n, j, 1], gp[n, j, 2]
                m += 1
            for i in range(n_ends[s]):
                j = end_par[s, i]
                w, x, y, z = gr[n, j, 0], gr[n, j, 1], gr[n, j, 2], gr[n, j, 3]
                vx, vy, vz = end_off[s, i, 0], end_off[s, i, 1], end_off[s, i, 2]
                tx = 2.0 * (y * vz - z * vy)
                ty = 2.0 * (z * vx - x * vz)
                tz = 2.0 * (x * vy - y * vx)
                px[m] = gp[n, j, 0] + (vx + w * tx + (y * tz - z * ty))
                py[m] = gp[n, j, 1] + (vy + w * ty + (z * tx - x * tz))
                pz[m] = gp[n, j, 2] + (vz + w * tz + (x * ty - y * tx))
                m += 1
            low = 0
            for i in range(1, m):
                if pz[i] < pz[low]:
                    low = i
            # hysteresis: the point held so far stays held while it is within 1 cm of the lowest
            old = foot_pt[n, s]
            oldz = pz[max(old, 0)]
            idx = old if (old >= 0 and oldz - pz[low] < 0.01) else low
            xy[n, s, 0] = px[idx]
            xy[n, s, 1] = py[idx]
            if was_planted[n, s] and planted[n, s] and old >= 0 and idx != old:
                foot_xy[n, s, 0] = xy[n, s, 0] + foot_xy[n, s, 0] - px[old]
                foot_xy[n, s, 1] = xy[n, s, 1] + foot_xy[n, s, 1] - py[old]
            foot_pt[n, s] = idx if planted[n, s] else -1
            # feet planted now are held where they are
            if planted[n, s] and not was_planted[n, s]:
                foot_xy[n, s, 0] = xy[n, s, 0]
                foot_xy[n, s, 1] = xy[n, s, 1]
            # how far the ankle must go up so that a held foot does not sink below the height the actions'
            # planted feet have; a lifted foot lets the correction go smoothly
            sink = max(rest[n] - pz[idx], 0.0)
            if planted[n, s]:
                release_z[n, s] = 0.0
                lift[n, s] = sink
            elif was_planted[n, s]:
                release_z[n, s] = sink
                lift[n, s] = sink
            else:
                release_z[n, s] *= decay
                lift[n, s] = release_z[n, s]
        # the planted feet pull the root toward where they are held, each by the share of the weight it
        # carries, faded out as its vote nears one half
        b0 = left[n] * min(max((vote[n, 0] - 0.5) * 4.0, 0.0), 1.0) if planted[n, 0] else 0.0
        b1 = (1.0 - left[n]) * min(max((vote[n, 1] - 0.5) * 4.0, 0.0), 1.0) if planted[n, 1] else 0.0
        gx = b0 * (foot_xy[n, 0, 0] - xy[n, 0, 0]) + b1 * (foot_xy[n, 1, 0] - xy[n, 1, 0])
        gy = b0 * (foot_xy[n, 0, 1] - xy[n, 0, 1]) + b1 * (foot_xy[n, 1, 1] - xy[n, 1, 1])
        sx, sy = alpha * gx, alpha * gy
        root[n, 0] += sx
        root[n, 1] += sy
        gp[n, 0, 0] += sx
        gp[n, 0, 1] += sy
        for i in range(chain.shape[0]):
            gp[n, chain[i], 0] += sx
            gp[n, chain[i], 1] += sy
        need_drop = 0.0
        for s in range(2):
            xy[n, s, 0] += sx
            xy[n, s, 1] += sy
            pl = planted[n, s]
            # a foot that lifts off keeps the IK offset it had and lets it go smoothly (no pop)
            if pl:
                release[n, s, 0] = 0.0
                release[n, s, 1] = 0.0
            elif was_planted[n, s]:
                release[n, s, 0] = foot_xy[n, s, 0] - xy[n, s, 0]
                release[n, s, 1] = foot_xy[n, s, 1] - xy[n, s, 1]
            else:
                release[n, s, 0] *= decay
                release[n, s, 1] *= decay
            if pl and max_drop > 0.0:
                # how far the pelvis must come down for the leg to reach where the foot is held
                h, a = hips[s], ankles[s]
                hx = gp[n, a, 0] + foot_xy[n, s, 0] - xy[n, s, 0] - gp[n, h, 0]
                hy = gp[n, a, 1] + foot_xy[n, s, 1] - xy[n, s, 1] - gp[n, h, 1]
                lr = _REACH_MARGIN * reach[s]
                hd2 = hx * hx + hy * hy
                v = gp[n, h, 2] - gp[n, a, 2] - lift[n, s]
                need_drop = max(need_drop, v - np.sqrt(lr * lr - hd2) if hd2 < lr * lr else max_drop)
        # the pelvis comes down (at a bounded speed) when a held foot needs it, and back up smoothly
        dz = max(min(need_drop, max_drop, drop[n] + rise), drop[n] * decay)
        drop[n] = dz
        if dz > 0.0:
            root[n, 2] -= dz
            for i in range(chain.shape[0]):
                gp[n, chain[i], 2] -= dz
        for s in range(2):
            ox = foot_xy[n, s, 0] - xy[n, s, 0]
            oy = foot_xy[n, s, 1] - xy[n, s, 1]
            if planted[n, s]:
                # a planted foot never strays more than `lim` from where the blend puts it, nor further
                # than the leg reaches (see _constrain_reference)
                dist = np.sqrt(ox * ox + oy * oy)
                scale = lim / max(dist, 1e-12) if dist > lim else 1.0
                h, a = hips[s], ankles[s]
                e0, e1 = gp[n, a, 0] - gp[n, h, 0], gp[n, a, 1] - gp[n, h, 1]
                e2 = gp[n, a, 2] + dz + lift[n, s] - gp[n, h, 2]
                ee = e0 * e0 + e1 * e1 + e2 * e2
                r = max(reach[s], np.sqrt(ee))
                d0, d1 = ox * scale, oy * scale
                a_ = d0 * d0 + d1 * d1
                b_ = e0 * d0 + e1 * d1
                c_ = ee - r * r
                disc = max(b_ * b_ - a_ * c_, 0.0)
                lam = (-b_ + np.sqrt(disc)) / max(a_, 1e-12) if a_ > 1e-12 else 1.0
                scale *= min(max(lam, 0.0), 1.0)
                if scale < 1.0:
                    foot_xy[n, s, 0] = xy[n, s, 0] + ox * scale
                    foot_xy[n, s, 1] = xy[n, s, 1] + oy * scale
                target[n, s, 0] = foot_xy[n, s, 0]
                target[n, s, 1] = foot_xy[n, s, 1]
            else:
                target[n, s, 0] = xy[n, s, 0] + release[n, s, 0]
                target[n, s, 1] = xy[n, s, 1] + release[n, s, 1]
            lift[n, s] += dz
            dx = target[n, s, 0] - xy[n, s, 0]
            dy = target[n, s, 1] - xy[n, s, 1]
            need[n, s] = abs(lift[n, s]) > 1e-9 or np.sqrt(dx * dx + dy * dy) > 1e-6


@numba.njit(cache=True, inline="always")
def _ramp(t, start, duration):  # pragma: no cover - compiled
    """Smoothstep from 0 to 1 over ``[start, start + duration]``; 0 when ``start`` is not finite."""
    if not np.isfinite(start):
        return 0.0
    if duration > 0:
        x = min(max((t - start) / max(duration, 1e-12), 0.0), 1.0)
        return x * x * (3.0 - 2.0 * x)
    return 1.0 if t >= start else 0.0


@numba.njit(cache=True)
def _mix_weights_kernel(t, seg, speed, ramp, prio, h, tau, w, wn):  # pragma: no cover - compiled
    """Per character: action times ``h`` (the frozen warp segments), clip times ``tau``, activations and
    priority weights ``w``, ``wn`` (the arithmetic of eval_poly, activation and priority_weights)."""
    n_chars, n_slots = h.shape
    act = np.empty(n_slots)
    group = np.empty(n_slots)
    logf = np.empty(n_slots)
    for n in range(n_chars):
        for s in range(n_slots):
            t0 = seg[n, s, 0]
            u = min(max(t - t0, 0.0), max(seg[n, s, 1] - t0, 0.0))
            hh = ((seg[n, s, 5] * u + seg[n, s, 4]) * u + seg[n, s, 3]) * u + seg[n, s, 2]
            h[n, s] = hh
            tau[n, s] = hh * speed[n, s]
            act[s] = _ramp(t, ramp[n, s, 0], ramp[n, s, 1]) * (1.0 - _ramp(t, ramp[n, s, 2], ramp[n, s, 3]))
        for s in range(n_slots):
            # two interleaved partial sums, the order of numpy's einsum over the level
            a0 = 0.0
            a1 = 0.0
            members = 0
            for k in range(n_slots):
                v = act[k] if prio[n, k] == prio[n, s] else 0.0
                if k % 2 == 0:
                    a0 += v
                else:
                    a1 += v
                if prio[n, k] == prio[n, s]:
                    members += 1
            group[s] = a0 + a1
            free = max(1.0 - min(group[s], 1.0), 0.0)
            logf[s] = np.log(free) / members if free > 0.0 else -np.inf
        tot = 0.0
        for s in range(n_slots):
            a0 = 0.0
            a1 = 0.0
            blocked = False
            for k in range(n_slots):
                v = 0.0
                if prio[n, k] > prio[n, s]:
                    if np.isfinite(logf[k]):
                        v = logf[k]
                    else:
                        blocked = True
                if k % 2 == 0:
                    a0 += v
                else:
                    a1 += v
            g = group[s]
            if g > 0:
                rem = 0.0 if blocked else np.exp(a0 + a1)
                ws = rem * min(g, 1.0) * act[s] / g
            else:
                ws = 0.0
            w[n, s] = ws
            tot += ws
        wn[n] = min(max(1.0 - tot, 0.0), 1.0)


def blend_frames_fast(rot_db, i0, a, w, ref, wref) -> np.ndarray:
    """Compiled :func:`blend_frames` (same result); one pass per character, no temporaries."""
    out = np.empty((w.shape[0], ref.shape[0], 4))
    _blend_kernel(rot_db, np.ascontiguousarray(i0, dtype=np.int64), np.ascontiguousarray(a, dtype=np.float64),
                  np.ascontiguousarray(w, dtype=np.float64), np.ascontiguousarray(ref, dtype=np.float64),
                  np.ascontiguousarray(wref, dtype=np.float64), out)
    return out


# ----------------------------------------------------------------------------------------- library


def _rest_height(found) -> float:
    """Height of a planted foot's lowest point from a clip's :class:`~kinodyn.contacts.FootContacts`:
    the median over its contact frames (the lowest foot point of the whole clip when it never touches
    the ground; 0 when the skeleton has no feet, ``found is None``)."""
    if found is None:
        return 0.0
    z = np.concatenate([found.lowest[s][found.labels[s], 2] for s in contacts.SIDES])
    if len(z) == 0:
        return float(min(found.lowest[s][:, 2].min() for s in contacts.SIDES))
    return float(np.median(z))


def _close_loop(rot, z):
    """Make a cyclic clip seamless: its last frame must equal its first, which captured cycles only
    approximate (a few degrees and centimetres apart). The mismatch of every joint rotation ``rot
    (F, J, 4)`` (facing frame) and of the root height ``z (F,)`` is spread linearly over the clip, half
    taken off the first frame and half added to the last, so the loop point no longer jumps."""
    n = len(z)
    s = np.arange(n) / (n - 1) - 0.5
    d = quat.inv_mul(rot[-1], rot[0])
    rot = quat.mul(rot, quat.exp(s[:, None, None] * quat.log(d)[None]))
    return rot, z + s * (z[0] - z[-1])


class ClipLibrary:
    """Clips packed for batched sampling, each with its support-phase sequence.

    Every clip is stored in its *facing frame*: root rotation without heading, root height, and the
    ground transform ``(x, y, unwrapped heading)`` of every frame. Clips of the same topology but other
    bone lengths are retargeted to the library's skeleton.

    Args:
        skeleton: the skeleton every clip is played on.
        contact_config: :class:`kinodyn.contacts.ContactConfig` used to build sequences.
        phase_config: :class:`~kinodyn.phases.PhaseConfig`.
    """

    def __init__(self, skeleton: Skeleton, contact_config=None, phase_config: PhaseConfig = PhaseConfig()):
        if not isinstance(skeleton, Skeleton):
            raise ParameterError(f"skeleton must be a Skeleton, got {type(skeleton).__name__}")
        self.skeleton = skeleton
        self.contact_config = contact_config
        self.phase_config = phase_config
        self._names: list[str] = []
        self._seqs: list[PhaseSequence] = []
        self._motions: list[Motion] = []
        self._parts: list[dict] = []
        self._packed = None

    # ------------------------------------------------------------------ building
    def add(self, name: str, motion: Motion, cyclic: bool = False, sequence: PhaseSequence | None = None,
            feet=None) -> int:
        """Add a clip; returns its index.

        Args:
            name: unique name.
            motion: the clip (any fps; same joint names and parents as the library's skeleton).
            cyclic: the clip loops: its last frame is its first again, up to the root's floor position
                (a captured cycle that misses by a little is closed, see :func:`_close_loop`).
            sequence: its support-phase sequence; detected from foot contacts when ``None``.
            feet: foot joints for contact detection (see :func:`kinodyn.contacts.find_feet`).
        """
        if name in self._names:
            raise ParameterError(f"a clip named {name!r} is already in the library")
        if not isinstance(motion, Motion):
            raise ParameterError(f"motion must be a Motion, got {type(motion).__name__}")
        if not motion.skeleton.same_topology(self.skeleton):
            raise MotionError(f"clip {name!r} does not fit the library's skeleton (joint names or parents differ)")
        if motion.num_frames < 2:
            raise MotionError(f"clip {name!r} needs at least 2 frames, got {motion.num_frames}")
        if not np.allclose(motion.skeleton.offsets, self.skeleton.offsets, atol=1e-6):
            motion = motion.retargeted(self.skeleton)
        if sequence is not None and sequence.cyclic != bool(cyclic):
            raise ParameterError(f"clip {name!r}: sequence.cyclic={sequence.cyclic} but cyclic={cyclic}")
        # one contact detection gives the sequence (when not given) and the planted-foot height
        try:
            found = contacts.detect(motion, self.contact_config or contacts.ContactConfig(), feet)
        except UnknownNameError:
            if sequence is None:
                raise
            found = None
        if sequence is None:
            sequence = _phases.from_labels(found.labels["left"], found.labels["right"], motion.fps, cyclic,
                                           self.phase_config)
        lr = quat.unroll(motion.local_rot)
        g = motion.ground()
        g[:, 2] = np.unwrap(g[:, 2])
        lr = np.array(lr)
        lr[:, 0] = quat.inv_mul(quat.from_heading(g[:, 2]), lr[:, 0])
        lr = quat.unroll(lr)
        z = np.array(motion.root_pos[:, 2])
        if cyclic:
            lr, z = _close_loop(lr, z)
        # one loop of a cyclic clip moves the whole clip by `loop` (world frame, applied on the left):
        # the frame at time u of cycle c is compose(loop^c, ground(u))
        loop = xform.compose(g[-1], xform.inverse(g[0])) if cyclic else np.zeros(3)
        self._names.append(name)
        self._seqs.append(sequence)
        self._motions.append(motion)
        frame_phase = sequence.phase_at(motion.times()).astype(np.int8)
        self._parts.append(dict(rot=lr, z=z, ground=g, fps=motion.fps, cyclic=bool(cyclic), loop=loop,
                                phase=frame_phase, share=sequence.left_share(motion.times()),
                                rest=_rest_height(found)))
        self._packed = None
        return len(self._names) - 1

    def add_blend(self, name: str, weights: dict) -> int:
        """Add the cycle between library clips at ``weights`` (``{clip: weight}``), a parametric model
        (:func:`kinodyn.blend.parametric.blend_cycles`); returns its index.

        The clips must be cyclic and share a support pattern; the new clip's sequence is built with it.
        """
        from kinodyn.blend.parametric import blend_cycles

        if not isinstance(weights, dict) or not weights:
            raise ParameterError(f"weights must map clip names to weights, got {weights!r}")
        idx = [self.index(k) for k in weights]
        for i in idx:
            if not self._parts[i]["cyclic"]:
                raise MotionError(f"clip {self._names[i]!r} is not cyclic; only cycles blend into a new cycle")
        motion, seq = blend_cycles([self._motions[i] for i in idx], list(weights.values()),
                                   [self._seqs[i] for i in idx], fps=self._motions[idx[0]].fps)
        return self.add(name, motion.replace(name=name), cyclic=True, sequence=seq)

    def _pack(self):
        if self._packed is None:
            if not self._parts:
                raise ParameterError("the clip library is empty")
            n = np.array([len(p["z"]) for p in self._parts])
            start = np.concatenate([[0], np.cumsum(n)[:-1]])
            fps = np.array([p["fps"] for p in self._parts])
            cyc = np.array([p["cyclic"] for p in self._parts])
            self._packed = dict(
                rot=np.ascontiguousarray(np.concatenate([p["rot"] for p in self._parts])),
                z=np.concatenate([p["z"] for p in self._parts]),
                ground=np.concatenate([p["ground"] for p in self._parts]),
                phase=np.concatenate([p["phase"] for p in self._parts]),
                share=np.concatenate([p["share"] for p in self._parts]),
                rest=np.array([p["rest"] for p in self._parts]),
                start=start, nframes=n, fps=fps, cyclic=cyc, dur=(n - 1) / fps,
                loop=np.stack([p["loop"] for p in self._parts]))
        return self._packed

    # ------------------------------------------------------------------ queries
    def __len__(self) -> int:
        return len(self._names)

    @property
    def names(self) -> list[str]:
        return list(self._names)

    def index(self, name) -> int:
        if isinstance(name, (int, np.integer)):
            if not 0 <= int(name) < len(self._names):
                raise UnknownNameError(f"clip index {name} out of range (library has {len(self._names)} clips)")
            return int(name)
        try:
            return self._names.index(name)
        except ValueError:
            raise UnknownNameError(f"unknown clip {name!r}; the library has: {', '.join(self._names)}") from None

    def sequence(self, name) -> PhaseSequence:
        return self._seqs[self.index(name)]

    def motion(self, name) -> Motion:
        return self._motions[self.index(name)]

    def cyclic(self, name) -> bool:
        return self._parts[self.index(name)]["cyclic"]

    def duration(self, name) -> float:
        return self._motions[self.index(name)].duration

    @classmethod
    def builtin(cls, names=None, contact_config=None, phase_config: PhaseConfig = PhaseConfig()) -> ClipLibrary:
        """The built-in clips of :mod:`kinodyn.data.library` (all of them, or ``names``)."""
        from kinodyn.data import library as data_lib
        from kinodyn.data.skeleton import humanoid

        lib = cls(humanoid(), contact_config, phase_config)
        for n in (data_lib.names() if names is None else names):
            lib.add(n, data_lib.load(n), data_lib.info(n).cyclic)
        return lib

    # ------------------------------------------------------------------ sampling
    def sample(self, clip, tau, prev_tau=None):
        """Batched sampling of clips at clip times.

        Args:
            clip: ``(...)`` clip indices.
            tau: ``(...)`` clip times in seconds (cyclic clips wrap, others clamp).
            prev_tau: ``(...)`` clip times one frame earlier, for the root motion (optional).

        Returns:
            ``rot (..., J, 4)`` facing-frame local rotations, ``z (...)`` root heights, and when
            ``prev_tau`` is given the root motion ``delta (..., 3)`` (dx, dy, dheading) from
            ``prev_tau`` to ``tau`` in the facing frame at ``prev_tau`` (the support phase at ``tau``
            of each sample is then left in ``last_phase``).
        """
        P = self._pack()
        clip = np.asarray(clip, dtype=np.int64)
        tau = np.asarray(tau, dtype=np.float64)
        i0, a, cyc, g = self._locate(P, clip, tau)
        a4 = a[..., None, None]
        rot = P["rot"][i0] * (1.0 - a4) + P["rot"][i0 + 1] * a4
        z = P["z"][i0] * (1.0 - a) + P["z"][i0 + 1] * a
        if prev_tau is None:
            return rot, z
        self.last_phase = P["phase"][np.where(a < 0.5, i0, i0 + 1)]
        _, _, cyc0, g0 = self._locate(P, clip, np.asarray(prev_tau, dtype=np.float64))
        g = _unroll_loops(P["loop"][clip], g, np.maximum(cyc - cyc0, 0))
        delta = xform.relative(g0, g)
        return rot, z, delta

    @staticmethod
    def _locate(P, clip, tau):
        fps = P["fps"][clip]
        n = P["nframes"][clip]
        dur = P["dur"][clip]
        cyclic = P["cyclic"][clip]
        cyc = np.where(cyclic, np.floor(tau / dur), 0.0)
        u = np.where(cyclic, tau - cyc * dur, np.clip(tau, 0.0, dur))
        x = u * fps
        i = np.clip(np.floor(x), 0, n - 2).astype(np.int64)
        a = np.clip(x - i, 0.0, 1.0)
        i0 = P["start"][clip] + i
        gr = P["ground"]
        g = gr[i0] * (1.0 - a[..., None]) + gr[i0 + 1] * a[..., None]
        return i0, a, cyc.astype(np.int64), g


# ----------------------------------------------------------------------------------------- actions


@dataclass(eq=False)
class ActionState:
    """One action of one character (mutable bookkeeping; the mixer owns it).

    Attributes:
        key: identifier (unique per character).
        clip: library index.
        seq: the adapted support-phase sequence (time-scaled by ``speed``).
        speed: time scaling; clip time = action time * speed.
        priority: higher wins.
        ramp_in, ramp_out: activation and deactivation durations (s).
        requested: time the start was asked for.
        t_on: time it actually started (``None`` while waiting for synchronization).
        t_off: time it was stopped (``None``: playing).
        auto_stop: a non-cyclic action stops by itself so that it has faded out when its clip ends.
        h0: action time at the start (the first element's beginning).
        handover: stopped while another action waited for its synchronized start: it keeps playing
            until that action starts, then fades out (the character never falls back to the neutral
            pose between the two).
    """

    key: object
    clip: int
    seq: PhaseSequence
    speed: float
    priority: float
    ramp_in: float
    ramp_out: float
    requested: float
    t_on: float | None = None
    t_off: float | None = None
    auto_stop: bool = False
    h0: float = 0.0
    end_h: float = math.inf
    order: int = 0
    handover: bool = False

    def weight_params(self):
        return (math.inf if self.t_on is None else self.t_on, self.ramp_in,
                math.inf if self.t_off is None else self.t_off, self.ramp_out)

    def gone(self, t: float) -> bool:
        return self.t_off is not None and t >= self.t_off + self.ramp_out


@dataclass
class Recording:
    """Per-frame record of one character: times, each action's action time and weight (NaN when absent)."""

    times: list = field(default_factory=list)
    action_time: dict = field(default_factory=dict)
    weight: dict = field(default_factory=dict)
    neutral: list = field(default_factory=list)

    def arrays(self) -> dict:
        n = len(self.times)
        out = {"t": np.array(self.times), "neutral": np.array(self.neutral)}
        for k in self.action_time:
            h = np.full(n, np.nan)
            w = np.zeros(n)
            for i, v in self.action_time[k].items():
                h[i] = v
            for i, v in self.weight[k].items():
                w[i] = v
            out[k] = (h, w)
        return out


class _Character:
    """Python-side state of one character: its actions, synchronizer and warp planner."""

    def __init__(self, mixer: Mixer, index: int):
        self.mixer = mixer
        self.index = index
        cfg = mixer.config
        self.actions: dict[object, ActionState] = {}
        self.order: list[object] = []           # slot order: priority desc, then start order
        self.sync = Synchronizer(cfg.sync, log=mixer.keep_log) if cfg.synchronize else None
        self.planner = (WarpPlanner(self.sync, self.weights_at, cfg.warp, keep_history=mixer.keep_log)
                        if cfg.synchronize else None)
        self.counter = 0
        self.weights_valid_until = math.inf
        self._wcache = None
        self.history: dict[object, ActionState] = {}   # every action ever started (for analysis)

    # ------------------------------------------------------------------ weights (scalar, for planning)
    def weights_at(self, t: float) -> dict:
        """Leg weights ``P_i`` of equation 6 at time ``t``: the share of the legs each action would have
        by its priority if it were fully active, given the others' activations at ``t``.

        Higher priority levels take their (capped) summed activation first; within its level an action
        counts itself as fully active. So actions of one priority share equally, an action overridden
        by a fully active higher level does not set the tempo, and a new action of higher priority
        imposes its timing from its first step (weighting by its ramped blend weight instead would
        squeeze its first elements into the running action's timing while it fades in). Pure Python:
        it runs once per planned step.
        """
        state = [(a.t_on, a.t_off) for a in self.actions.values()]
        c = self._wcache
        if c is not None and c[0] == state and (c[1] <= t < c[2] or t == c[1]):
            self.weights_valid_until = c[2]
            return c[3]
        out = self._weights(t)
        self._wcache = (state, t, self.weights_valid_until, out)
        return out

    def _weights(self, t: float) -> dict:
        acts = [a for a in self.actions.values() if a.t_on is not None and a.t_on <= t + 1e-9 and not a.gone(t)]
        # the weights stay the same until the next ramp event (a start, the end of a ramp, a stop)
        until = math.inf
        for a in self.actions.values():
            on, ri, off, ro = a.weight_params()
            if on < t < on + ri or off < t < off + ro:  # mid-ramp: the weights change continuously
                until = t
                break
            for e in (on, on + ri, off, off + ro):
                if t + 1e-9 < e < until:
                    until = e
        self.weights_valid_until = until
        if not acts:
            return {}
        if len(acts) == 1:
            return {acts[0].key: 1.0}
        level: dict[float, float] = {}
        act = {}
        for a in acts:
            on, ri, off, ro = a.weight_params()
            x = 1.0 if ri <= 0 else min(max((t - on) / ri, 0.0), 1.0)
            up = x * x * (3.0 - 2.0 * x)
            y = 0.0 if off == math.inf else (1.0 if ro <= 0 else min(max((t - off) / ro, 0.0), 1.0))
            act[a.key] = up * (1.0 - y * y * (3.0 - 2.0 * y))
            level[a.priority] = level.get(a.priority, 0.0) + act[a.key]
        out = {}
        for a in acts:
            free = 1.0
            for p, s in level.items():
                if p > a.priority:
                    free *= max(0.0, 1.0 - min(1.0, s))
            out[a.key] = free / (1.0 + level[a.priority] - act[a.key])
        return out

    # ------------------------------------------------------------------ commands
    def start(self, key, clip: int, speed: float, priority: float, ramp_in: float, ramp_out: float,
              auto_stop: bool, now: float):
        lib = self.mixer.library
        if key in self.actions:
            raise ParameterError(f"character {self.index} already has an action {key!r}")
        if len(self.actions) >= self.mixer.config.max_actions:
            raise ParameterError(f"character {self.index} already plays {len(self.actions)} actions "
                                 f"(max_actions={self.mixer.config.max_actions}); stop one first")
        seq = lib._seqs[clip].time_scaled(speed)
        cyclic = lib._parts[clip]["cyclic"]
        a = ActionState(key, clip, seq, speed, priority, ramp_in, ramp_out, now, auto_stop=auto_stop and not cyclic,
                        h0=seq.element(0)[1], end_h=(lib._motions[clip].duration / speed) if not cyclic else math.inf)
        a.order = self.counter
        self.counter += 1
        self.actions[key] = a
        self.history[key] = a
        if self.sync is None:
            a.t_on = now
            if a.auto_stop:
                a.t_off = max(now, now + (a.end_h - a.h0) - a.ramp_out)
        else:
            was_idle = self.sync.idle and not self.sync.pending
            self.sync.request(key, seq, priority)
            if was_idle:
                a.t_on = now
                self.planner.start(now)
                self._auto_stops(now)
        self._layout()

    def stop(self, key, now: float):
        a = self.actions.get(key)
        if a is None:
            raise UnknownNameError(f"character {self.index} has no action {key!r}; it has: "
                                   f"{', '.join(map(str, self.actions)) or 'none'}")
        if a.t_on is None:  # still waiting for synchronization: never started
            self.sync.cancel(key)
            del self.actions[key]
            if not self.sync.pending:
                for b in list(self.actions.values()):
                    if b.handover:
                        self.stop(b.key, now)
            self._layout()
            return
        if self.sync is not None and a.t_off is None and self.sync.pending and not a.handover:
            a.handover = True   # fades out when the waiting action starts (see ActionState.handover)
            return
        if a.t_off is None or a.t_off > now:
            a.t_off = now
            a.handover = False
            if self.planner is not None:
                self.planner.replan()
            self._write_segments()

    # ------------------------------------------------------------------ time
    def next_event(self) -> float:
        if self.sync is None:
            ends = [a.t_off + a.ramp_out for a in self.actions.values() if a.t_off is not None]
            return min(ends) if ends else math.inf
        if self.sync.idle:
            return math.inf
        return self.planner.T.get(self.sync.current + 1, math.inf)

    def advance(self, t: float):
        """Enter every step that begins at or before ``t``."""
        if self.sync is None:
            for k in [k for k, a in self.actions.items() if a.gone(t)]:
                del self.actions[k]
            self._layout()
            return
        guard = 0
        changed = False
        sync = self.sync
        planner = self.planner
        actions = self.actions
        while sync.tracks and planner.T.get(sync.current + 1, math.inf) <= t:
            guard += 1
            if guard > 10_000:
                raise ParameterError("time warp produced degenerate steps")
            tk = planner.T[sync.current + 1]
            gone = [key for key, a in actions.items()
                    if a.t_on is not None and a.t_off is not None and tk >= a.t_off + a.ramp_out]
            for key in gone:
                sync.remove(key, sync.current + 1)
            sync.enter_next()
            k = sync.current
            if len(sync.tracks) + len(sync.pending) != len(actions):
                live = {tr.key for tr in sync.tracks}
                for key in [key for key, a in actions.items() if a.t_on is not None and key not in live]:
                    del actions[key]
                    changed = True
            if not sync.tracks:
                break
            started = handed = False
            for tr in sync.tracks:
                if tr.first == k:
                    a = actions[tr.key]
                    if a.t_on is None:
                        a.t_on = tk
                        changed = started = True
            if started and not sync.pending:
                for a in actions.values():
                    if a.handover:
                        a.handover = False
                        if a.t_off is None:
                            a.t_off = tk
                            handed = True
            planner.enter()
            if handed:
                planner.replan()
            changed |= self._auto_stops(tk)
        if changed or self.sync.idle:
            self._layout()
        else:
            self._write_steps()

    def _auto_stops(self, now: float) -> bool:
        changed = False
        for a in self.actions.values():
            if a.auto_stop and a.t_off is None and a.t_on is not None:
                te = self.planner.time_of(a.key, a.end_h)
                if te is not None:
                    a.t_off = max(now, te - a.ramp_out)
                    self.planner.replan()
                    changed = True
        return changed

    # ------------------------------------------------------------------ slot arrays
    def _layout(self):
        self.order = sorted(self.actions, key=lambda k: (-self.actions[k].priority, self.actions[k].order))
        self._write_segments()

    def _write_steps(self):
        """After a step entry with the same actions: only the warp segments and the next boundary change."""
        m = self.mixer
        n = self.index
        planner = self.planner
        k = self.sync.current
        T = planner.T
        tk = T.get(k)
        timing = planner.timing
        order = self.order
        on = m._ramp[n, :len(order), 0].tolist()
        rows = []
        for s, key in enumerate(order):
            tm = timing.get(key)
            seg = None if tm is None else tm.current
            if seg is not None and seg.t1 > seg.t0 and on[s] != math.inf and seg.t0 == tk:
                rows.append((seg.t0, seg.t1) + seg.coef)
            else:
                self._write_segments()
                return
        if rows:
            m._seg[n, :len(rows)] = rows
        m._next[n] = T.get(k + 1, math.inf)  # next_event() while the synchronizer plays

    def _write_segments(self):
        """Write every slot of this character (after its actions or their order changed)."""
        m = self.mixer
        n = self.index
        S = m.slots
        sync = self.sync
        k = None if sync is None else sync.current
        tracks = None if sync is None else {x.key: x for x in sync.tracks}
        order = self.order
        L = len(order)
        clip, speed, prio, seg, ramp = [], [], [], [], []
        for key in order:
            a = self.actions[key]
            clip.append(a.clip)
            speed.append(a.speed)
            prio.append(a.priority)
            on, ri, off, ro = a.weight_params()
            if sync is None:
                seg.append((a.t_on, math.inf, a.h0, 1.0, 0.0, 0.0))
            else:
                tr = tracks.get(a.key)
                if tr is None or tr.elem(k) is None:
                    on = math.inf  # waiting: no weight
                    seg.append((0.0, math.inf, a.h0, 0.0, 0.0, 0.0))
                else:
                    sg = self.planner.segment(a.key)
                    seg.append((sg.t0, sg.t1) + sg.coef)
            ramp.append((on, ri, off, ro))
        keys = m._key[n]
        new_keys = [self.actions[key].key for key in order] + [None] * (S - L)
        if keys != new_keys:  # slots changed hands: carry each action's sampling state to its new slot
            prev = {keys[s]: (m._prev_tau[n, s], m._prev_g[n, s].copy(), m._prev_cyc[n, s], m._fresh[n, s])
                    for s in range(S) if keys[s] is not None}
            for s in range(S):
                key = new_keys[s]
                if key is None:
                    keys[s] = None
                elif keys[s] != key:
                    keys[s] = key
                    if key in prev:
                        m._prev_tau[n, s], m._prev_g[n, s], m._prev_cyc[n, s], m._fresh[n, s] = prev[key]
                    else:
                        m._fresh[n, s] = True
        m._count[n] = L
        if L:
            m._clip[n, :L] = clip
            m._speed[n, :L] = speed
            m._prio[n, :L] = prio
            m._seg[n, :L] = seg
            m._ramp[n, :L] = ramp
        if L < S:
            m._ramp[n, L:] = (math.inf, 0.0, math.inf, 0.0)
            m._seg[n, L:] = (0.0, math.inf, 0.0, 0.0, 0.0, 0.0)
        m._next[n] = self.next_event()


class Mixer:
    """Mixes actions for ``N`` characters, one frame at a time (mutable real-time state).

    Args:
        library: the :class:`ClipLibrary` the actions play from.
        n_characters: number of characters mixed together.
        config: :class:`BlendConfig`.
        neutral: the neutral double-support pose: a clip name (its first frame), a
            :class:`~kinodyn.motion.Motion` (first frame), or ``None`` for the ``idle`` clip when the
            library has one, else the first double-support frame of the first clip.
        record: keep a per-frame :class:`Recording` of every character (for plots and checks).

    Example::

        mixer = Mixer(library)
        mixer.start("walk", priority=1)
        for _ in range(120):
            pose = mixer.step(1 / 60)
    """

    def __init__(self, library: ClipLibrary, n_characters: int = 1, config: BlendConfig = BlendConfig(),
                 neutral=None, record: bool = False, keep_log: bool | None = None):
        if not isinstance(library, ClipLibrary):
            raise ParameterError(f"library must be a ClipLibrary, got {type(library).__name__}")
        if not isinstance(n_characters, (int, np.integer)) or n_characters < 1:
            raise ParameterError(f"n_characters must be a positive integer, got {n_characters!r}")
        self.library = library
        self.config = config
        self.n = int(n_characters)
        self.slots = config.max_actions
        self.keep_log = record if keep_log is None else keep_log
        self.time = 0.0
        N, S = self.n, self.slots
        self._clip = np.zeros((N, S), dtype=np.int64)
        self._speed = np.ones((N, S))
        self._prio = np.zeros((N, S))
        self._ramp = np.tile(np.array([math.inf, 0.0, math.inf, 0.0]), (N, S, 1))
        self._seg = np.tile(np.array([0.0, math.inf, 0.0, 0.0, 0.0, 0.0]), (N, S, 1))
        self._prev_tau = np.zeros((N, S))
        self._prev_g = np.zeros((N, S, 3))
        self._prev_cyc = np.zeros((N, S), dtype=np.int64)
        self._count = np.zeros(N, dtype=np.int64)       # occupied slots per character
        self._fresh = np.ones((N, S), dtype=bool)
        self._key = [[None] * S for _ in range(N)]
        self._next = np.full(N, math.inf)
        self.ground = np.zeros((N, 3))
        self.support = np.zeros(N, dtype=np.int64)       # planted foot carrying most weight: 0 none, 1 left, 2 right
        self._planted = np.zeros((N, 2), dtype=bool)     # left, right planted at the previous frame
        self._foot_pt = np.full((N, 2), -1, dtype=np.int64)
        self._foot_xy = np.zeros((N, 2, 2))              # where each planted foot's lowest point is held
        self._release = np.zeros((N, 2, 2))              # IK offset fading out after a foot lifts off
        self._drop = np.zeros(N)                         # how far the pelvis is lowered to reach the feet
        self._release_z = np.zeros((N, 2))               # height correction fading out after a lift-off
        from kinodyn.blend.footlock import legs

        self._legs = legs(library.skeleton)
        if self._legs is not None:  # hip-to-ankle length of each leg (the rest bone lengths)
            bl = library.skeleton.bone_lengths()
            self._reach = [float(bl[leg.knee] + bl[leg.ankle]) for leg in self._legs]
        self._legarr = None
        self._compiled = True  # False: the numpy reference of the support constraints (tests)
        self._neutral = self._neutral_pose(neutral)
        self._neutral_rest = self._pose_rest(*self._neutral)
        self.chars = [_Character(self, i) for i in range(N)]
        self.recordings = [Recording() for _ in range(N)] if record else None
        self._frame = 0

    # ------------------------------------------------------------------ setup
    def _neutral_pose(self, neutral):
        lib = self.library
        if neutral is None:
            if "idle" in lib.names:
                neutral = "idle"
            else:
                name = lib.names[0]
                seq = lib.sequence(name)
                ds = [i for i, p in enumerate(seq.phases) if p == _phases.DS]
                t = 0.0 if not ds else max(0.0, (seq.bounds[ds[0]] + seq.bounds[ds[0] + 1]) / 2)
                rot, z = lib.sample(np.array([lib.index(name)]), np.array([t]))
                return rot[0], float(z[0])
        if isinstance(neutral, Motion):
            tmp = ClipLibrary(lib.skeleton)
            tmp.add("neutral", neutral[:2] if neutral.num_frames >= 2 else neutral)
            rot, z = tmp.sample(np.array([0]), np.array([0.0]))
            return rot[0], float(z[0])
        rot, z = lib.sample(np.array([lib.index(neutral)]), np.array([0.0]))
        return rot[0], float(z[0])

    def _pose_rest(self, rot, z) -> float:
        """Height of the lowest foot point of a standing pose (``rot (J, 4)`` facing frame, root height)."""
        if self._legs is None:
            return 0.0
        pose = Motion(self.library.skeleton, np.array([[0.0, 0.0, z]]), rot[None], 60.0)
        return float(min(p[..., 2].min() for p in contacts.foot_points(pose).values()))

    def _leg_arrays(self):
        """The legs' foot points as padded arrays for :func:`_hold_kernel` (built once)."""
        if self._legarr is None:
            sk = self.library.skeleton
            nj = np.array([len(leg.joints) for leg in self._legs], dtype=np.int64)
            ne = np.array([len(leg.ends) for leg in self._legs], dtype=np.int64)
            joints = np.zeros((2, max(int(nj.max()), 1)), dtype=np.int64)
            par = np.zeros((2, max(int(ne.max()), 1)), dtype=np.int64)
            off = np.zeros((2, par.shape[1], 3))
            for s, leg in enumerate(self._legs):
                joints[s, :nj[s]] = leg.joints
                if ne[s]:
                    par[s, :ne[s]] = sk.end_parents[leg.ends]
                    off[s, :ne[s]] = sk.end_offsets[leg.ends]
            self._legarr = (joints, nj, par, off, ne, np.array([leg.hip for leg in self._legs], dtype=np.int64),
                            np.array([leg.ankle for leg in self._legs], dtype=np.int64),
                            np.array(self._reach, dtype=np.float64))
            need = set()
            for leg in self._legs:
                for j in list(leg.joints) + list(sk.end_parents[leg.ends]) + [leg.hip, leg.knee]:
                    j = int(j)
                    while j > 0:
                        need.add(j)
                        j = int(sk.parents[j])
            chain = np.array(sorted(need), dtype=np.int64)  # parents come first (parents[j] < j)
            self._legarr += (chain, np.ascontiguousarray(sk.offsets, dtype=np.float64),
                             np.ascontiguousarray(sk.parents, dtype=np.int64))
        return self._legarr

    def _constrain(self, root, q, w, wn, phase, left, rest, dt: float):
        """Enforce the support (:mod:`kinodyn.blend.footlock`); returns new ``root (N, 3)``, ``q (N, J, 4)``.

        Compiled version of :meth:`_constrain_reference` (same result up to rounding): one pass per
        character for the support, forward kinematics, one pass per character for the holds, the IK.
        """
        if not self._compiled:
            return self._constrain_reference(root, q, w, wn, phase, left, rest, dt)
        from kinodyn.blend.footlock import pin_feet_fast

        N = len(root)
        planted = np.empty((N, 2), dtype=np.bool_)
        vote = np.empty((N, 2))
        support = np.ascontiguousarray(self.support, dtype=np.int64)
        left = np.ascontiguousarray(left, dtype=np.float64)
        _support_kernel(np.ascontiguousarray(w, dtype=np.float64), np.ascontiguousarray(wn, dtype=np.float64),
                        np.ascontiguousarray(phase, dtype=np.int8), left, support, planted, vote)
        self.support = support
        if (not planted.any() and not self._planted.any() and not self._release.any() and not self._drop.any()
                and not self._release_z.any()):
            return root, q
        hl = self.config.root_halflife
        alpha = 1.0 if hl <= 0 else 1.0 - 0.5 ** (dt / hl)
        decay = 0.5 ** (dt / self.config.release_halflife) if self.config.release_halflife > 0 else 0.0
        root = np.array(root, dtype=np.float64)
        q = np.ascontiguousarray(q, dtype=np.float64)
        J = q.shape[1]
        gr = np.zeros((N, J, 4))  # only the legs' chains are computed
        gp = np.zeros((N, J, 3))
        target = np.empty((N, 2, 2))
        xy = np.empty((N, 2, 2))
        need = np.empty((N, 2), dtype=np.bool_)
        lift = np.empty((N, 2))
        joints, nj, par, off, ne, hips, ankles, reach, chain, offsets, parents = self._leg_arrays()
        _hold_kernel(root, q, offsets, parents, chain, gr, gp, planted, vote, left,
                     np.ascontiguousarray(rest, dtype=np.float64), self._planted, self._foot_pt, self._foot_xy,
                     self._release, self._release_z,
                     self._drop, joints, nj, par, off, ne, hips, ankles, reach, alpha, decay,
                     float(self.config.max_foot_offset), float(self.config.max_pelvis_drop),
                     float(self.config.max_pelvis_drop) * dt / _DROP_TIME, target, xy, lift, need)
        self._planted = planted
        heading = self.ground[:, 2]
        for s, leg in enumerate(self._legs):
            r = np.nonzero(need[:, s])[0]
            if len(r):
                q = pin_feet_fast(q, gr, gp, leg, r, target[r, s], xy[r, s], heading[r], dz=lift[r, s])
        return root, q

    def _constrain_reference(self, root, q, w, wn, phase, left, rest, dt: float):
        """Numpy reference of :meth:`_constrain` (the same steps, array by array)."""
        from kinodyn.blend.footlock import pin_feet_fast
        from kinodyn.kinematics import fk_arrays

        down_l = (phase == _phases.LS) | (phase == _phases.DS)
        down_r = (phase == _phases.RS) | (phase == _phases.DS)
        vote = np.stack([(w * down_l).sum(axis=1) + wn, (w * down_r).sum(axis=1) + wn], axis=1)
        planted = vote >= 0.5
        self.support = np.where(planted[:, 0] & (~planted[:, 1] | (left >= 0.5)), 1, np.where(planted[:, 1], 2, 0))
        if (not np.any(planted) and not np.any(self._planted) and not np.any(self._release) and not np.any(self._drop)
                and not np.any(self._release_z)):
            return root, q
        sk = self.library.skeleton
        gr, gp = fk_arrays(root, q, sk.offsets, sk.parents)
        xy = np.zeros((len(root), 2, 2))
        zl = np.zeros((len(root), 2))
        idx = np.zeros((len(root), 2), dtype=np.int64)
        rows = np.arange(len(root))
        for s, leg in enumerate(self._legs):
            pts = [gp[:, leg.joints]]
            if len(leg.ends):
                par = sk.end_parents[leg.ends]
                pts.append(gp[:, par] + _rotate(gr[:, par], sk.end_offsets[leg.ends]))
            p = np.concatenate(pts, axis=1)
            low = np.argmin(p[..., 2], axis=1)
            # hysteresis: the point held so far stays held while it is within 1 cm of the lowest
            old = self._foot_pt[:, s]
            oldz = p[rows, np.maximum(old, 0), 2]
            idx[:, s] = np.where((old >= 0) & (oldz - p[rows, low, 2] < 0.01), old, low)
            xy[:, s] = p[rows, idx[:, s], :2]
            zl[:, s] = p[rows, idx[:, s], 2]
            # another point of a held foot takes over (heel to toe): it is held where the foot is held,
            # i.e. with the same offset from the blended pose as the point it replaces
            switch = self._planted[:, s] & planted[:, s] & (old >= 0) & (idx[:, s] != old)
            if np.any(switch):
                self._foot_xy[switch, s] = xy[switch, s] + self._foot_xy[switch, s] - p[rows, old, :2][switch]
        # feet planted now are held where they are; the planted feet pull the root toward where they are
        # held, each by the share of the weight it carries, faded out as its vote nears one half
        rebase = planted & ~self._planted
        self._foot_xy = np.where(rebase[..., None], xy, self._foot_xy)
        # how far each ankle must go up so that a held foot does not sink below the height the actions'
        # planted feet have; a lifted foot lets the correction go smoothly
        released = self._planted & ~planted
        decay = 0.5 ** (dt / self.config.release_halflife) if self.config.release_halflife > 0 else 0.0
        sink = np.maximum(rest[:, None] - zl, 0.0)
        self._release_z = np.where(planted, 0.0, np.where(released, sink, self._release_z * decay))
        lift = np.where(planted, sink, self._release_z)
        err = self._foot_xy - xy
        share = np.stack([left, 1.0 - left], axis=1) * np.clip((vote - 0.5) * 4.0, 0.0, 1.0) * planted
        target = (share[..., None] * err).sum(axis=1)
        hl = self.config.root_halflife
        alpha = 1.0 if hl <= 0 else 1.0 - 0.5 ** (dt / hl)
        shift = alpha * target
        root = root.copy()
        root[:, :2] += shift
        xy = xy + shift[:, None, :]
        gp = gp.copy()
        gp[..., :2] += shift[:, None, :]
        # a foot that lifts off keeps the IK offset it had and lets it go smoothly (no pop)
        released = self._planted & ~planted
        self._release = np.where(released[..., None], self._foot_xy - xy, self._release * decay)
        self._release = np.where(planted[..., None], 0.0, self._release)
        # the pelvis comes down (at a bounded speed, and back up smoothly) as far as a held foot needs to
        # stay within the leg's reach, up to max_pelvis_drop
        need = np.zeros(len(root))
        max_drop = self.config.max_pelvis_drop
        if max_drop > 0:
            for s, leg in enumerate(self._legs):
                h = gp[:, leg.ankle, :2] + self._foot_xy[:, s] - xy[:, s] - gp[:, leg.hip, :2]
                hd2 = (h * h).sum(axis=1)
                lr2 = (_REACH_MARGIN * self._reach[s]) ** 2
                v = gp[:, leg.hip, 2] - gp[:, leg.ankle, 2] - lift[:, s]
                d = np.where(hd2 < lr2, v - np.sqrt(np.maximum(lr2 - hd2, 0.0)), max_drop)
                need = np.maximum(need, np.where(planted[:, s], d, 0.0))
        rise = self._drop + max_drop * dt / _DROP_TIME
        self._drop = np.maximum(np.minimum(np.minimum(need, max_drop), rise), self._drop * decay)
        root[:, 2] -= self._drop
        gp[..., 2] -= self._drop[:, None]
        # a planted foot never strays more than max_foot_offset from where the blend puts it: beyond
        # that the blend has moved on to another stance and the foot slides along (bounded leg stretch)
        off = self._foot_xy - xy
        dist = np.linalg.norm(off, axis=-1)
        lim = self.config.max_foot_offset
        scale = np.where(planted & (dist > lim), lim / np.maximum(dist, 1e-12), 1.0)
        # ... and never further than the leg reaches: the ankle moves by `off` horizontally, so keep
        # the largest fraction of it that leaves the ankle within the leg's length of the hip (or
        # within the blended pose's own hip-ankle distance when that is longer)
        for s, leg in enumerate(self._legs):
            hip = gp[:, leg.hip]
            ank = gp[:, leg.ankle]
            e = ank - hip
            e[:, 2] += self._drop + lift[:, s]
            reach = np.maximum(self._reach[s], np.linalg.norm(e, axis=1))
            d = np.zeros_like(ank)
            d[:, :2] = off[:, s] * scale[:, s, None]
            # |e + lam d|^2 = reach^2  ->  a lam^2 + 2 b lam + c = 0
            a_ = (d * d).sum(axis=1)
            b_ = (e * d).sum(axis=1)
            c_ = (e * e).sum(axis=1) - reach * reach
            disc = np.maximum(b_ * b_ - a_ * c_, 0.0)
            lam = np.where(a_ > 1e-12, (-b_ + np.sqrt(disc)) / np.maximum(a_, 1e-12), 1.0)
            lam = np.clip(lam, 0.0, 1.0)
            scale[:, s] *= np.where(planted[:, s], lam, 1.0)
        if np.any(scale < 1.0):
            self._foot_xy = xy + off * scale[..., None]
        self._foot_pt = np.where(planted, idx, -1)
        self._planted = planted
        heading = self.ground[:, 2]
        target = np.where(planted[..., None], self._foot_xy, xy + self._release)
        lift = lift + self._drop[:, None]
        for s, leg in enumerate(self._legs):
            need = (np.linalg.norm(target[:, s] - xy[:, s], axis=-1) > 1e-6) | (np.abs(lift[:, s]) > 1e-9)
            r = np.nonzero(need)[0]
            if len(r):
                q = pin_feet_fast(q, gr, gp, leg, r, target[r, s], xy[r, s], heading[r], dz=lift[r, s])
        return root, q

    # ------------------------------------------------------------------ commands
    def start(self, clip, character: int = 0, priority: float = 0.0, ramp_in: float | None = None,
              ramp_out: float | None = None, speed: float = 1.0, key=None, auto_stop: bool = True,
              at: float | None = None):
        """Start an action playing ``clip`` on ``character``; returns its key.

        Args:
            clip: library clip name or index.
            priority: higher overrides lower.
            ramp_in, ramp_out: activation / deactivation durations (default: the config's).
            speed: time scaling of the clip (and of its sequence).
            key: identifier (default: the clip name, suffixed when taken).
            auto_stop: a non-cyclic clip fades out by itself at its end.
            at: time of the command, within the frame being prepared (default: the mixer's time).
        """
        c = self._char(character)
        idx = self.library.index(clip)
        if not (np.isfinite(speed) and speed > 0):
            raise ParameterError(f"speed must be a positive number, got {speed!r}")
        if not np.isfinite(priority):
            raise ParameterError(f"priority must be a finite number, got {priority!r}")
        ri = self.config.ramp_in if ramp_in is None else float(ramp_in)
        ro = self.config.ramp_out if ramp_out is None else float(ramp_out)
        if ri < 0 or ro < 0 or not (np.isfinite(ri) and np.isfinite(ro)):
            raise ParameterError(f"ramps must be non-negative seconds, got ramp_in={ri}, ramp_out={ro}")
        if key is None:
            base = self.library.names[idx]
            key, i = base, 1
            while key in c.actions:
                i += 1
                key = f"{base}#{i}"
        c.start(key, idx, float(speed), float(priority), ri, ro, auto_stop, self._at(at))
        return key

    def stop(self, key, character: int = 0, at: float | None = None) -> None:
        """Stop an action: it fades out over its ``ramp_out``. A start still waiting is cancelled; an action
        stopped while another waits for its synchronized start plays on until that one starts (hand-over).
        """
        self._char(character).stop(key, self._at(at))

    def _at(self, at) -> float:
        if at is None:
            return self.time
        at = float(at)
        if not np.isfinite(at) or at < self.time - 1e-9:
            raise ParameterError(f"a command cannot be dated before the mixer's time {self.time:.6f} s, got {at}")
        return at

    def actions(self, character: int = 0) -> dict:
        """The character's :class:`ActionState` objects by key."""
        return dict(self._char(character).actions)

    def _char(self, i) -> _Character:
        if not isinstance(i, (int, np.integer)) or not 0 <= int(i) < self.n:
            raise ParameterError(f"character must be an index in [0, {self.n}), got {i!r}")
        return self.chars[int(i)]

    # ------------------------------------------------------------------ per frame
    def step(self, dt: float) -> Pose:
        """Advance every character by ``dt`` seconds and return their poses."""
        if not (np.isfinite(dt) and dt > 0):
            raise ParameterError(f"dt must be a positive number of seconds, got {dt!r}")
        t = self.time + float(dt)
        for i in np.nonzero(self._next <= t)[0]:
            self.chars[i].advance(t)
        self.time = t
        return self._evaluate(t, dt=float(dt))

    def pose(self) -> Pose:
        """The poses at the current time without advancing (no root motion)."""
        return self._evaluate(self.time, move=False)

    def _evaluate(self, t: float, move: bool = True, dt: float = 0.0) -> Pose:
        """Poses of every character at time ``t`` (batched; see the module docstring)."""
        P = self.library._pack()
        S = max(int(self._count.max()), 1)
        seg = self._seg[:, :S]
        r = self._ramp[:, :S]
        if self._compiled:
            N = self.n
            h, tau, w, wn = np.empty((N, S)), np.empty((N, S)), np.empty((N, S)), np.empty(N)
            _mix_weights_kernel(float(t), seg, self._speed[:, :S], r, self._prio[:, :S], h, tau, w, wn)
        else:
            u = np.clip(t - seg[..., 0], 0.0, np.maximum(seg[..., 1] - seg[..., 0], 0.0))
            h = eval_poly(seg[..., 2:6], u)
            tau = h * self._speed[:, :S]
            act = activation(t, r[..., 0], r[..., 1], r[..., 2], r[..., 3])
            w, wn = priority_weights(act, self._prio[:, :S])
        clip = self._clip[:, :S]
        i0, a, cyc, g = ClipLibrary._locate(P, clip, tau)
        fresh = self._fresh[:, :S]
        g_prev = np.where(fresh[..., None], g, self._prev_g[:, :S])
        cyc_prev = np.where(fresh, cyc, self._prev_cyc[:, :S])
        self._prev_g[:, :S] = g
        self._prev_cyc[:, :S] = cyc
        self._prev_tau[:, :S] = tau
        self._fresh[:] = False
        phase = P["phase"][np.where(a < 0.5, i0, i0 + 1)]
        nrot, nz = self._neutral
        if self.config.average == "markley":
            a4 = a[..., None, None]
            rot = P["rot"][i0] * (1.0 - a4) + P["rot"][i0 + 1] * a4
            q = blend_rotations(rot, w, nrot, wn, "markley")
        else:
            q = blend_frames_fast(P["rot"], i0, a, w, nrot, wn)
        zdb = P["z"]
        z = zdb[i0] * (1.0 - a) + zdb[i0 + 1] * a
        zz = (w * z).sum(axis=1) + wn * nz
        if move:
            g = _unroll_loops(P["loop"][clip], g, np.maximum(cyc - cyc_prev, 0))
            delta = xform.relative(g_prev, g)
            d = (w[..., None] * delta).sum(axis=1)
            self.ground = xform.compose(self.ground, d)
        g = self.ground
        root = np.stack([g[:, 0], g[:, 1], zz], axis=1)
        q[:, 0] = quat.mul(quat.from_heading(g[:, 2]), q[:, 0])
        if move and self.config.enforce and self._legs is not None:
            sh = P["share"]
            total = np.maximum(w.sum(axis=1) + wn, 1e-12)
            left = ((w * (sh[i0] * (1.0 - a) + sh[i0 + 1] * a)).sum(axis=1) + 0.5 * wn) / total
            rest = ((w * P["rest"][clip]).sum(axis=1) + wn * self._neutral_rest) / total
            root, q = self._constrain(root, q, w, wn, phase, left, rest, dt)
            self.ground = np.concatenate([root[:, :2], g[:, 2:]], axis=1)
        if self.recordings is not None and move:
            for n, rec in enumerate(self.recordings):
                fi = len(rec.times)
                rec.times.append(t)
                rec.neutral.append(float(wn[n]))
                for s, key in enumerate(self._key[n]):
                    if key is None:
                        continue
                    rec.action_time.setdefault(key, {})[fi] = float(h[n, s]) if np.isfinite(r[n, s, 0]) else np.nan
                    rec.weight.setdefault(key, {})[fi] = float(w[n, s])
        self._frame += 1
        return Pose(root, q)

    # ------------------------------------------------------------------ offline
    def sequence_of(self, key, character: int = 0) -> PhaseSequence:
        """The adapted support-phase sequence of a playing action."""
        return self._char(character).actions[key].seq


def _unroll_loops(loop: np.ndarray, g: np.ndarray, cycles: np.ndarray) -> np.ndarray:
    """Ground transforms ``g (..., 3)`` moved on by ``cycles (...)`` whole loops of their clip, each
    loop displacing the root by ``loop (..., 3)``."""
    for _ in range(int(cycles.max(initial=0))):
        g = np.where((cycles > 0)[..., None], xform.compose(loop, g), g)
        cycles = cycles - 1
    return g
