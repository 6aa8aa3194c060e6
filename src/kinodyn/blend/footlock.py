"""Support constraints after blending: keep the planted feet where they landed.

Synchronization (:mod:`kinodyn.blend.sync`) leaves every instant with actions that agree on which feet
carry the body; this module makes the blended pose respect that support, the role the paper's engine
gives to kinematic constraints computed after blending (its section 3). A foot is *planted* when the
weights of the actions whose current phase puts it down (``RS``: right, ``LS``: left, ``DS``: both; the
neutral pose: both) add up to at least one half. Each planted foot is held at the position its lowest
point had when it was planted (or when the lowest point moved from heel to toe), and never lower than
the actions' clips keep their planted feet (blending poses of different root heights would push it
through the floor).

The root's horizontal position follows the held feet, each by the share of the body's weight it
carries: all of it on a single support, passed linearly from the old support foot to the new one over a
double support, as the actions' sequences say
(:meth:`~kinodyn.phases.PhaseSequence.left_share`), and faded out as a foot's vote nears one
half. So the root never jumps when a foot lifts or lands. Two-bone inverse kinematics of each leg (hip,
knee, ankle) then puts the feet where they are held, keeping each foot's world orientation; when a held
foot is beyond a straight leg's reach (the back foot at push-off) the pelvis comes down a little, and
beyond that the foot follows the pose. Nor is a held foot ever displaced further than
:attr:`~kinodyn.blend.mixer.BlendConfig.max_foot_offset` from where the blended pose puts it, all the
lock does counted (the root's follow, the IK's offset, the height correction, which is never given up):
beyond that it follows the pose too, a bound on what the lock may do to the pose.

The two-bone solver is :func:`kinodyn.ik.two_bone_delta` (the analytic one of Daniel Holden's
Motion-Matching code, skeleton-agnostic). :class:`FootLock` holds the per-character state of the lock
(which feet are held, where, the fading corrections) and applies it every frame with compiled kernels;
the numpy reference of the same steps lives with the tests.

Shapes: ``M`` poses, ``J`` joints. Units: metres.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from kinodyn.errors import UnknownNameError
from kinodyn.ik import two_bone_delta, two_bone_delta_kernel
from kinodyn.kinematics import fk_link
from kinodyn.math import quat
from kinodyn.math.kernels import qmul, qrot

__all__ = ["FootLock", "Leg", "legs", "pin_feet", "pin_feet_fast"]


class Leg(NamedTuple):
    """One leg: ``hip``, ``knee``, ``ankle`` joint indices and the foot's points (joints + end sites)."""

    hip: int
    knee: int
    ankle: int
    joints: np.ndarray
    ends: np.ndarray


def legs(skeleton) -> tuple[Leg, Leg] | None:
    """``(left, right)`` legs of a skeleton found from its foot joints, or ``None`` when it has no feet.

    The ankle is the highest foot joint (closest to the root); the knee and hip are its parent and
    grandparent.
    """
    from kinodyn import contacts

    try:
        feet = contacts.find_feet(skeleton)
    except UnknownNameError:
        return None
    out = []
    par = skeleton.parents
    for side in ("left", "right"):
        joints = np.array(sorted(int(j) for j in feet[side]), dtype=np.int64)
        ankle = int(joints[0])
        knee = int(par[ankle])
        hip = int(par[knee]) if knee >= 0 else -1
        if knee <= 0 or hip < 0:
            return None
        ends = np.nonzero(np.isin(skeleton.end_parents, joints))[0].astype(np.int64)
        out.append(Leg(hip, knee, ankle, joints, ends))
    return out[0], out[1]


def pin_feet(q, gr, gp, leg: Leg, rows, target_xy, lowest_xy, heading, dz=None):
    """Move the ankle of ``leg`` horizontally by ``target_xy - lowest_xy`` (and up by ``dz``) for poses
    ``rows``.

    Args:
        q: ``(N, J, 4)`` local rotations (modified copy returned).
        gr, gp: ``(N, J, 4)``, ``(N, J, 3)`` world rotations and positions of the same poses.
        leg: the leg to move.
        rows: ``(M,)`` indices of the poses to change.
        target_xy, lowest_xy: ``(M, 2)`` where the foot's lowest point must be and where it is.
        heading: ``(M,)`` character headings (their lateral axis bends a straight knee).
        dz: ``(M,)`` metres to raise the ankle (the pelvis was lowered by as much), default 0.

    Returns:
        The new local rotations ``(N, J, 4)``; the foot keeps its world orientation.
    """
    if len(rows) == 0:
        return q
    q = q.copy()
    a, b, c = gp[rows, leg.hip], gp[rows, leg.knee], gp[rows, leg.ankle]
    t = c.copy()
    t[:, :2] += target_xy - lowest_xy
    if dz is not None:
        t[:, 2] += dz
    lateral = np.stack([-np.sin(heading), np.cos(heading), np.zeros_like(heading)], axis=-1)
    da, db = two_bone_delta(a, b, c, t, gr[rows, leg.hip], gr[rows, leg.knee], lateral)
    hip_l = quat.mul(q[rows, leg.hip], da)
    knee_l = quat.mul(q[rows, leg.knee], db)
    hip_parent = quat.mul_inv(gr[rows, leg.hip], q[rows, leg.hip])
    knee_w = quat.mul(quat.mul(hip_parent, hip_l), knee_l)
    q[rows, leg.hip] = hip_l
    q[rows, leg.knee] = knee_l
    q[rows, leg.ankle] = quat.inv_mul(knee_w, gr[rows, leg.ankle])
    return q


# ----------------------------------------------------------------------------------------- compiled


@numba.njit(cache=True)
def _pin_kernel(q, gr, gp, hip, knee, ankle, rows, target_xy, lowest_xy, heading, dz, eps):  # pragma: no cover
    for m in range(rows.shape[0]):
        n = rows[m]
        cx, cy, cz = gp[n, ankle, 0], gp[n, ankle, 1], gp[n, ankle, 2]
        A0, A1, A2, A3 = gr[n, hip, 0], gr[n, hip, 1], gr[n, hip, 2], gr[n, hip, 3]
        da, r1 = two_bone_delta_kernel(gp[n, hip, 0], gp[n, hip, 1], gp[n, hip, 2], gp[n, knee, 0], gp[n, knee, 1],
                                       gp[n, knee, 2], cx, cy, cz, cx + target_xy[m, 0] - lowest_xy[m, 0],
                                       cy + target_xy[m, 1] - lowest_xy[m, 1], cz + dz[m], A0, A1, A2, A3,
                                       gr[n, knee, 0], gr[n, knee, 1], gr[n, knee, 2], gr[n, knee, 3],
                                       -np.sin(heading[m]), np.cos(heading[m]), 0.0, eps)
        hl = qmul(q[n, hip, 0], q[n, hip, 1], q[n, hip, 2], q[n, hip, 3], da[0], da[1], da[2], da[3])
        kl = qmul(q[n, knee, 0], q[n, knee, 1], q[n, knee, 2], q[n, knee, 3], r1[0], r1[1], r1[2], r1[3])
        # parent of the hip in world = gr[hip] * inv(q[hip])
        P = qmul(A0, A1, A2, A3, q[n, hip, 0], -q[n, hip, 1], -q[n, hip, 2], -q[n, hip, 3])
        hw = qmul(P[0], P[1], P[2], P[3], hl[0], hl[1], hl[2], hl[3])
        kw = qmul(hw[0], hw[1], hw[2], hw[3], kl[0], kl[1], kl[2], kl[3])
        fl = qmul(kw[0], -kw[1], -kw[2], -kw[3], gr[n, ankle, 0], gr[n, ankle, 1], gr[n, ankle, 2], gr[n, ankle, 3])
        for c in range(4):
            q[n, hip, c] = hl[c]
            q[n, knee, c] = kl[c]
            q[n, ankle, c] = fl[c]


def pin_feet_fast(q, gr, gp, leg: Leg, rows, target_xy, lowest_xy, heading, eps: float = 1e-5, dz=None):
    """Compiled :func:`pin_feet` (same result); modifies ``q`` in place and returns it."""
    if len(rows):
        dz = np.zeros(len(rows)) if dz is None else np.broadcast_to(np.asarray(dz, dtype=np.float64), (len(rows),))
        _pin_kernel(q, gr, gp, leg.hip, leg.knee, leg.ankle, np.ascontiguousarray(rows, dtype=np.int64),
                    np.ascontiguousarray(target_xy, dtype=np.float64), np.ascontiguousarray(lowest_xy, dtype=np.float64),
                    np.ascontiguousarray(heading, dtype=np.float64), np.ascontiguousarray(dz), eps)
    return q


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
REACH_MARGIN = 0.995
#: Seconds the pelvis takes at least to come down by ``max_pelvis_drop`` (no sudden crouch).
DROP_TIME = 0.2


@numba.njit(cache=True, inline="always")
def _hold_foot(n, s, gr, gp, planted, was_planted, rest, foot_pt, foot_xy, release_z, leg_joints, n_joints, end_par,
               end_off, n_ends, decay, xy, lift, px, py, pz):  # pragma: no cover - compiled
    """Which point of foot ``s`` of character ``n`` is held and where (heel-to-toe hysteresis), and how
    far its ankle must go up (``lift``); ``px``, ``py``, ``pz`` are scratch space."""
    m = 0
    for i in range(n_joints[s]):
        j = leg_joints[s, i]
        px[m], py[m], pz[m] = gp[n, j, 0], gp[n, j, 1], gp[n, j, 2]
        m += 1
    for i in range(n_ends[s]):
        j = end_par[s, i]
        rx, ry, rz = qrot(gr[n, j, 0], gr[n, j, 1], gr[n, j, 2], gr[n, j, 3], end_off[s, i, 0], end_off[s, i, 1],
                          end_off[s, i, 2])
        px[m] = gp[n, j, 0] + rx
        py[m] = gp[n, j, 1] + ry
        pz[m] = gp[n, j, 2] + rz
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


@numba.njit(cache=True, inline="always")
def _follow_feet(n, root, gp, chain, planted, was_planted, vote, left, foot_xy, release, xy, lift, hips, ankles, reach,
                 alpha, decay, max_drop):  # pragma: no cover - compiled
    """The root of character ``n`` follows its held feet; lifted feet let their IK offset fade out.
    Returns how far the pelvis must come down for the legs to reach the held feet."""
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
            lr = REACH_MARGIN * reach[s]
            hd2 = hx * hx + hy * hy
            v = gp[n, h, 2] - gp[n, a, 2] - lift[n, s]
            need_drop = max(need_drop, v - np.sqrt(lr * lr - hd2) if hd2 < lr * lr else max_drop)
    return need_drop


@numba.njit(cache=True, inline="always")
def _reach_feet(n, root, gp, chain, planted, foot_xy, release, drop, xy, lift, hips, ankles, reach, need_drop, decay, lim,
                max_drop, rise, sx, sy, target, need):  # pragma: no cover - compiled
    """The pelvis of character ``n`` comes down as far as its held feet need (bounded), the held feet stay
    within ``lim`` of where the blend put them (``sx``, ``sy``: how far the root followed the feet this
    frame) and within the legs' reach; every foot's IK target and whether it needs IK."""
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
            # a planted foot is never held more than `lim` from where the blend put it (before the root
            # followed), its height correction included, nor further than the leg reaches
            hx, hy = ox + sx, oy + sy
            dist = np.sqrt(hx * hx + hy * hy)
            rad = np.sqrt(max(lim * lim - lift[n, s] * lift[n, s], 0.0))
            moved = dist > rad
            if moved:
                ox = hx * rad / dist - sx
                oy = hy * rad / dist - sy
            scale = 1.0
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
            if moved or scale < 1.0:
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


@numba.njit(cache=True)
def _hold_kernel(root, q, offsets, parents, chain, gr, gp, planted, vote, left, rest, was_planted, foot_pt, foot_xy,
                 release, release_z, drop, leg_joints, n_joints, end_par, end_off, n_ends, hips, ankles, reach, alpha,
                 decay, lim, max_drop, rise, target, xy, lift, need):  # pragma: no cover - compiled
    """Where each foot is held and how far the root follows (the middle part of :meth:`FootLock.constrain`,
    one pass per character). Forward kinematics fills ``gr``, ``gp`` for the joints of ``chain`` (the root,
    the legs and their ancestors, parents first) only; ``root``, ``gp``, ``foot_pt``, ``foot_xy``, ``release``,
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
            _hold_foot(n, s, gr, gp, planted, was_planted, rest, foot_pt, foot_xy, release_z, leg_joints, n_joints,
                       end_par, end_off, n_ends, decay, xy, lift, px, py, pz)
        r0x, r0y = root[n, 0], root[n, 1]
        need_drop = _follow_feet(n, root, gp, chain, planted, was_planted, vote, left, foot_xy, release, xy, lift, hips,
                                 ankles, reach, alpha, decay, max_drop)
        _reach_feet(n, root, gp, chain, planted, foot_xy, release, drop, xy, lift, hips, ankles, reach, need_drop, decay,
                    lim, max_drop, rise, root[n, 0] - r0x, root[n, 1] - r0y, target, need)


class FootLock:
    """Support constraints of ``N`` characters (mutable per-frame state: which feet are held and where).

    Args:
        skeleton: the characters' skeleton (its legs are found by :func:`legs`; without feet the lock
            does nothing).
        n_characters: ``N``.
        config: the mixer's :class:`~kinodyn.blend.mixer.BlendConfig` (``root_halflife``,
            ``release_halflife``, ``max_foot_offset``, ``max_pelvis_drop``).

    Attributes:
        support: ``(N,)`` planted foot carrying most weight: 0 none, 1 left, 2 right.
        planted: ``(N, 2)`` left, right planted at the previous frame.
        foot_pt: ``(N, 2)`` which point of each held foot is held (-1: none).
        foot_xy: ``(N, 2, 2)`` where each planted foot's lowest point is held.
        release: ``(N, 2, 2)`` IK offset fading out after a foot lifts off.
        drop: ``(N,)`` how far the pelvis is lowered to reach the feet.
        release_z: ``(N, 2)`` height correction fading out after a lift-off.
        offset: ``(N, 2)`` at the last frame, the distance (m) of each held foot's lowest point from where
            the blended pose put it before the lock moved the root, the IK included (NaN: not held).
        legs, reach: the legs (or ``None``) and each leg's hip-to-ankle rest length.
    """

    def __init__(self, skeleton, n_characters: int, config):
        N = int(n_characters)
        self.skeleton = skeleton
        self.config = config
        self.support = np.zeros(N, dtype=np.int64)
        self.planted = np.zeros((N, 2), dtype=bool)
        self.foot_pt = np.full((N, 2), -1, dtype=np.int64)
        self.foot_xy = np.zeros((N, 2, 2))
        self.release = np.zeros((N, 2, 2))
        self.drop = np.zeros(N)
        self.release_z = np.zeros((N, 2))
        self.offset = np.full((N, 2), np.nan)
        self.legs = legs(skeleton)
        self.reach = None
        if self.legs is not None:  # hip-to-ankle length of each leg (the rest bone lengths)
            bl = skeleton.bone_lengths()
            self.reach = [float(bl[leg.knee] + bl[leg.ankle]) for leg in self.legs]
        self._arrays = None

    def rest_of_pose(self, rot, z) -> float:
        """Height of the lowest foot point of a standing pose (``rot (J, 4)`` facing frame, root height)."""
        from kinodyn import contacts
        from kinodyn.motion import Motion

        if self.legs is None:
            return 0.0
        pose = Motion(self.skeleton, np.array([[0.0, 0.0, z]]), rot[None], 60.0)
        return float(min(p[..., 2].min() for p in contacts.foot_points(pose).values()))

    def leg_arrays(self):
        """The legs' foot points as padded arrays for the compiled kernels (built once): ``(joints,
        n_joints, end_parents, end_offsets, n_ends, hips, ankles, reach, chain, offsets, parents)``."""
        if self._arrays is None:
            sk = self.skeleton
            nj = np.array([len(leg.joints) for leg in self.legs], dtype=np.int64)
            ne = np.array([len(leg.ends) for leg in self.legs], dtype=np.int64)
            joints = np.zeros((2, max(int(nj.max()), 1)), dtype=np.int64)
            par = np.zeros((2, max(int(ne.max()), 1)), dtype=np.int64)
            off = np.zeros((2, par.shape[1], 3))
            for s, leg in enumerate(self.legs):
                joints[s, :nj[s]] = leg.joints
                if ne[s]:
                    par[s, :ne[s]] = sk.end_parents[leg.ends]
                    off[s, :ne[s]] = sk.end_offsets[leg.ends]
            need = set()
            for leg in self.legs:
                for j in list(leg.joints) + list(sk.end_parents[leg.ends]) + [leg.hip, leg.knee]:
                    j = int(j)
                    while j > 0:
                        need.add(j)
                        j = int(sk.parents[j])
            chain = np.array(sorted(need), dtype=np.int64)  # parents come first (parents[j] < j)
            self._arrays = (joints, nj, par, off, ne, np.array([leg.hip for leg in self.legs], dtype=np.int64),
                            np.array([leg.ankle for leg in self.legs], dtype=np.int64),
                            np.array(self.reach, dtype=np.float64), chain,
                            np.ascontiguousarray(sk.offsets, dtype=np.float64),
                            np.ascontiguousarray(sk.parents, dtype=np.int64))
        return self._arrays

    def idle(self, planted) -> bool:
        """Nothing planted now nor before, and no correction left to fade: the pose needs no change."""
        return (not np.any(planted) and not np.any(self.planted) and not np.any(self.release)
                and not np.any(self.drop) and not np.any(self.release_z))

    def constrain(self, root, q, w, wn, phase, left, rest, dt: float, heading, pin: bool = True):
        """Enforce the support on blended poses; returns new ``root (N, 3)`` and ``q (N, J, 4)``.

        With ``pin=False`` only the root moves: it follows the planted feet at once (no halflife), so a
        foot that carries the body stays where it is without bending a leg (the blend's root motion,
        :attr:`~kinodyn.blend.mixer.BlendConfig.root_motion`); the legs keep the blended pose.

        Args:
            root, q: ``(N, 3)``, ``(N, J, 4)`` the blended poses (world root, local rotations).
            w, wn: ``(N, S)`` action weights and ``(N,)`` the neutral pose's.
            phase: ``(N, S)`` each action's support phase now.
            left: ``(N,)`` the share of the weight on the left foot; ``rest`` ``(N,)`` planted-foot height.
            dt: seconds since the previous frame; ``heading`` ``(N,)`` the characters' headings.

        Compiled: one pass per character for the support, forward kinematics of the legs and the holds
        (:func:`_hold_kernel`), then the leg IK (:func:`pin_feet_fast`).
        """
        N = len(root)
        planted = np.empty((N, 2), dtype=np.bool_)
        vote = np.empty((N, 2))
        support = np.ascontiguousarray(self.support, dtype=np.int64)
        left = np.ascontiguousarray(left, dtype=np.float64)
        _support_kernel(np.ascontiguousarray(w, dtype=np.float64), np.ascontiguousarray(wn, dtype=np.float64),
                        np.ascontiguousarray(phase, dtype=np.int8), left, support, planted, vote)
        self.support = support
        self.offset = np.full((N, 2), np.nan)
        if self.idle(planted):
            return root, q
        root = np.array(root, dtype=np.float64)
        before = root.copy()
        q = np.ascontiguousarray(q, dtype=np.float64)
        gr, gp, target, xy, lift, need = self._hold(root, q, planted, vote, left, rest, dt, pin)
        self.planted = planted
        if not pin:
            return root, q
        # how far each held foot is from where this frame's blend put it (before the root followed)
        blend_xy = xy - (root[:, None, :2] - before[:, None, :2])
        sink = lift - self.drop[:, None]
        off = np.sqrt(((target - blend_xy) ** 2).sum(axis=-1) + sink ** 2)
        self.offset = np.where(planted, off, np.nan)
        for s, leg in enumerate(self.legs):
            r = np.nonzero(need[:, s])[0]
            if len(r):
                q = pin_feet_fast(q, gr, gp, leg, r, target[r, s], xy[r, s], heading[r], dz=lift[r, s])
        return root, q

    def _hold(self, root, q, planted, vote, left, rest, dt: float, pin: bool = True):
        """Run :func:`_hold_kernel`; returns the legs' world rotations and positions ``gr``, ``gp`` and the
        kernel's ``target``, ``xy``, ``lift``, ``need``."""
        cfg = self.config
        hl = cfg.root_halflife
        alpha = 1.0 if hl <= 0 else 1.0 - 0.5 ** (dt / hl)
        drop = float(cfg.max_pelvis_drop) if pin else 0.0
        decay = 0.5 ** (dt / cfg.release_halflife) if cfg.release_halflife > 0 else 0.0
        N, J = q.shape[:2]
        gr = np.zeros((N, J, 4))  # only the legs' chains are computed
        gp = np.zeros((N, J, 3))
        target = np.empty((N, 2, 2))
        xy = np.empty((N, 2, 2))
        need = np.empty((N, 2), dtype=np.bool_)
        lift = np.empty((N, 2))
        joints, nj, par, off, ne, hips, ankles, reach, chain, offsets, parents = self.leg_arrays()
        _hold_kernel(root, q, offsets, parents, chain, gr, gp, planted, vote, left,
                     np.ascontiguousarray(rest, dtype=np.float64), self.planted, self.foot_pt, self.foot_xy,
                     self.release, self.release_z, self.drop, joints, nj, par, off, ne, hips, ankles, reach, alpha,
                     decay, float(cfg.max_foot_offset), drop, drop * dt / DROP_TIME, target, xy, lift, need)
        return gr, gp, target, xy, lift, need
