"""The mixer: ramps, priorities, neutral pose, batched sampling and blending, support constraints."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from kinodyn import phases
from kinodyn.blend import footlock
from kinodyn.blend.footlock import DROP_TIME, REACH_MARGIN, pin_feet_fast
from kinodyn.blend.library import builtin
from kinodyn.blend.mixer import BlendConfig, Mixer
from kinodyn.blend.pose import blend_rotations
from kinodyn.blend.weights import activation, priority_weights, smoothstep
from kinodyn.errors import ParameterError, UnknownNameError
from kinodyn.kinematics import fk_arrays
from kinodyn.math import interp, quat

_TOL = 1e-9
_ANGLE_TOL = 1e-9


def _rotate(q, v):
    """``quat.mul_vec`` for ``q (..., 4)`` and ``v (..., 3)`` written out (the reference's own)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return np.stack([vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz),
                     vz + w * tz + (x * ty - y * tx)], axis=-1)


def constrain_reference(self, root, q, w, wn, phase, left, rest, dt: float, heading, pin: bool = True):
    """Numpy reference of :meth:`kinodyn.blend.footlock.FootLock.constrain` (the same steps, array by
    array); ``self`` is the lock."""

    down_l = (phase == phases.LS) | (phase == phases.DS)
    down_r = (phase == phases.RS) | (phase == phases.DS)
    vote = np.stack([(w * down_l).sum(axis=1) + wn, (w * down_r).sum(axis=1) + wn], axis=1)
    planted = vote >= 0.5
    self.support = np.where(planted[:, 0] & (~planted[:, 1] | (left >= 0.5)), 1, np.where(planted[:, 1], 2, 0))
    self.offset = np.full((len(root), 2), np.nan)
    if (not np.any(planted) and not np.any(self.planted) and not np.any(self.release) and not np.any(self.drop)
            and not np.any(self.release_z)):
        return root, q
    sk = self.skeleton
    gr, gp = fk_arrays(root, q, sk.offsets, sk.parents)
    xy = np.zeros((len(root), 2, 2))
    zl = np.zeros((len(root), 2))
    idx = np.zeros((len(root), 2), dtype=np.int64)
    rows = np.arange(len(root))
    for s, leg in enumerate(self.legs):
        pts = [gp[:, leg.joints]]
        if len(leg.ends):
            par = sk.end_parents[leg.ends]
            pts.append(gp[:, par] + _rotate(gr[:, par], sk.end_offsets[leg.ends]))
        p = np.concatenate(pts, axis=1)
        low = np.argmin(p[..., 2], axis=1)
        # hysteresis: the point held so far stays held while it is within 1 cm of the lowest
        old = self.foot_pt[:, s]
        oldz = p[rows, np.maximum(old, 0), 2]
        idx[:, s] = np.where((old >= 0) & (oldz - p[rows, low, 2] < 0.01), old, low)
        xy[:, s] = p[rows, idx[:, s], :2]
        zl[:, s] = p[rows, idx[:, s], 2]
        # another point of a held foot takes over (heel to toe): it is held where the foot is held,
        # i.e. with the same offset from the blended pose as the point it replaces
        switch = self.planted[:, s] & planted[:, s] & (old >= 0) & (idx[:, s] != old)
        if np.any(switch):
            self.foot_xy[switch, s] = xy[switch, s] + self.foot_xy[switch, s] - p[rows, old, :2][switch]
    # feet planted now are held where they are; the planted feet pull the root toward where they are
    # held, each by the share of the weight it carries, faded out as its vote nears one half
    rebase = planted & ~self.planted
    self.foot_xy = np.where(rebase[..., None], xy, self.foot_xy)
    # how far each ankle must go up so that a held foot does not sink below the height the actions'
    # planted feet have; a lifted foot lets the correction go smoothly
    released = self.planted & ~planted
    decay = 0.5 ** (dt / self.config.release_halflife) if self.config.release_halflife > 0 else 0.0
    sink = np.maximum(rest[:, None] - zl, 0.0)
    self.release_z = np.where(planted, 0.0, np.where(released, sink, self.release_z * decay))
    lift = np.where(planted, sink, self.release_z)
    err = self.foot_xy - xy
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
    released = self.planted & ~planted
    self.release = np.where(released[..., None], self.foot_xy - xy, self.release * decay)
    self.release = np.where(planted[..., None], 0.0, self.release)
    # the pelvis comes down (at a bounded speed, and back up smoothly) as far as a held foot needs to
    # stay within the leg's reach, up to max_pelvis_drop
    need = np.zeros(len(root))
    max_drop = self.config.max_pelvis_drop if pin else 0.0
    if max_drop > 0:
        for s, leg in enumerate(self.legs):
            h = gp[:, leg.ankle, :2] + self.foot_xy[:, s] - xy[:, s] - gp[:, leg.hip, :2]
            hd2 = (h * h).sum(axis=1)
            lr2 = (REACH_MARGIN * self.reach[s]) ** 2
            v = gp[:, leg.hip, 2] - gp[:, leg.ankle, 2] - lift[:, s]
            d = np.where(hd2 < lr2, v - np.sqrt(np.maximum(lr2 - hd2, 0.0)), max_drop)
            need = np.maximum(need, np.where(planted[:, s], d, 0.0))
    rise = self.drop + max_drop * dt / DROP_TIME
    self.drop = np.maximum(np.minimum(np.minimum(need, max_drop), rise), self.drop * decay)
    root[:, 2] -= self.drop
    gp[..., 2] -= self.drop[:, None]
    # a planted foot never strays more than max_foot_offset from where the blend puts it: beyond
    # that the blend has moved on to another stance and the foot slides along (bounded leg stretch)
    # (its height correction and this frame's root follow included)
    off = self.foot_xy - xy
    pre = off + shift[:, None, :]
    dist = np.linalg.norm(pre, axis=-1)
    lim = self.config.max_foot_offset
    rad = np.sqrt(np.maximum(lim * lim - lift * lift, 0.0))
    moved = planted & (dist > rad)
    off = np.where(moved[..., None], pre * (rad / np.maximum(dist, 1e-12))[..., None] - shift[:, None, :], off)
    scale = np.ones_like(dist)
    # ... and never further than the leg reaches: the ankle moves by `off` horizontally, so keep
    # the largest fraction of it that leaves the ankle within the leg's length of the hip (or
    # within the blended pose's own hip-ankle distance when that is longer)
    for s, leg in enumerate(self.legs):
        hip = gp[:, leg.hip]
        ank = gp[:, leg.ankle]
        e = ank - hip
        e[:, 2] += self.drop + lift[:, s]
        reach = np.maximum(self.reach[s], np.linalg.norm(e, axis=1))
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
    if np.any(scale < 1.0) or np.any(moved):
        self.foot_xy = xy + off * scale[..., None]
    self.foot_pt = np.where(planted, idx, -1)
    self.planted = planted
    target = np.where(planted[..., None], self.foot_xy, xy + self.release)
    lift = lift + self.drop[:, None]
    if not pin:
        return root, q
    sink = lift - self.drop[:, None]
    off = np.sqrt(((target - (xy - shift[:, None, :])) ** 2).sum(axis=-1) + sink ** 2)
    self.offset = np.where(planted, off, np.nan)
    for s, leg in enumerate(self.legs):
        need = (np.linalg.norm(target[:, s] - xy[:, s], axis=-1) > 1e-6) | (np.abs(lift[:, s]) > 1e-9)
        r = np.nonzero(need)[0]
        if len(r):
            q = pin_feet_fast(q, gr, gp, leg, r, target[r, s], xy[r, s], heading[r], dz=lift[r, s])
    return root, q



@pytest.fixture(scope="module")
def lib():
    return builtin(["idle", "walk", "run", "kick", "punch"])


def test_activation_follows_figure_2():
    t = np.array([0.0, 1.0, 1.25, 1.5, 3.0, 3.5, 3.99, 4.0, 5.0])
    a = activation(t, 1.0, 0.5, 3.0, 1.0)
    assert a[0] == 0.0 and a[1] == 0.0                  # before t1
    assert a[2] == pytest.approx(smoothstep(0.5))        # ramping up
    assert a[3] == pytest.approx(1.0) and a[4] == pytest.approx(1.0)   # t2 .. t3
    assert a[5] == pytest.approx(1.0 - smoothstep(0.5))  # ramping down
    assert a[7] == 0.0 and a[8] == 0.0                   # after t4
    assert activation(2.0, np.inf, 0.5, np.inf, 0.5) == 0.0   # not started: no weight


def test_priority_weights():
    # same priority: shared by activation; the neutral pose gets what is left
    w, wn = priority_weights([[0.5, 0.25]], [[1, 1]])
    np.testing.assert_allclose(w, [[0.5, 0.25]], atol=_TOL)
    np.testing.assert_allclose(wn, [0.25], atol=_TOL)
    w, wn = priority_weights([[1.0, 1.0]], [[1, 1]])
    np.testing.assert_allclose(w, [[0.5, 0.5]], atol=_TOL)
    np.testing.assert_allclose(wn, [0.0], atol=_TOL)
    # a higher priority takes its activation first
    w, wn = priority_weights([[0.75, 1.0, 1.0]], [[2, 1, 0]])
    np.testing.assert_allclose(w, [[0.75, 0.25, 0.0]], atol=_TOL)
    assert wn[0] == pytest.approx(0.0)
    rng = np.random.default_rng(0)
    act = rng.random((50, 4)) * (rng.random((50, 4)) > 0.3)
    prio = rng.integers(0, 3, (50, 4)).astype(float)
    w, wn = priority_weights(act, prio)
    np.testing.assert_allclose(w.sum(axis=1) + wn, 1.0, atol=1e-12)
    assert np.all(w >= 0) and np.all(w <= act + 1e-12)


def test_blend_rotations_nlerp_close_to_markley_oracle():
    rng = np.random.default_rng(1)
    base = quat.from_rotvec(rng.normal(0, 1, (6, 21, 3)))
    q = quat.mul(base[:, None], quat.from_rotvec(rng.normal(0, 0.15, (6, 3, 21, 3))))   # nearby rotations
    q = q * np.where(rng.random((6, 3, 21, 1)) < 0.5, -1.0, 1.0)   # random signs: q and -q are one rotation
    w = rng.dirichlet(np.ones(4), 6)
    ref = quat.identity((21,))
    a = blend_rotations(q, w[:, :3], ref, w[:, 3] * 0, "nlerp")
    b = blend_rotations(q, w[:, :3], ref, w[:, 3] * 0, "markley")
    assert np.degrees(quat.angle_between(a, b)).max() < 0.5
    # one rotation with all the weight is returned exactly
    one = blend_rotations(q[:, :1], np.ones((6, 1)), ref, np.zeros(6))
    assert quat.angle_between(one, q[:, 0]).max() < _ANGLE_TOL


def test_single_action_plays_its_clip(lib):
    """One action with no ramp reproduces the clip: joint rotations exactly, and the root travels as far."""
    from kinodyn.data import library as L

    run = L.load("run")
    for sync in (True, False):
        mx = Mixer(lib, 1, BlendConfig(synchronize=sync, ramp_in=0.0, constraints="off"), record=True)
        mx.time = -1 / 60
        mx.start("run")
        rots, roots = [], []
        for _ in range(150):
            p = mx.step(1 / 60)
            rots.append(p.local_rot[0])
            roots.append(p.root_pos[0])
        rots, roots = np.array(rots), np.array(roots)
        h = mx.recordings[0].arrays()["run"][0]
        ref = interp.slerp_frames(quat.unroll(run.local_rot), run.fps, np.mod(h, run.duration))
        assert quat.angle_between(ref[:, 1:], rots[:, 1:]).max() < 1e-9
        np.testing.assert_allclose(roots[:, 2], interp.lerp_frames(run.root_pos[:, 2], run.fps, np.mod(h, run.duration)),
                                   atol=1e-9)
        speed = np.linalg.norm(run.root_pos[-1, :2] - run.root_pos[0, :2]) / run.duration
        travelled = np.linalg.norm(roots[-1, :2] - roots[0, :2])
        assert travelled == pytest.approx(speed * (h[-1] - h[0]), rel=0.02)


def test_nothing_playing_gives_the_neutral_pose(lib):
    from kinodyn.data import library as L

    mx = Mixer(lib, 2)
    p = mx.step(1 / 60)
    idle = L.load("idle")
    for n in range(2):
        assert quat.angle_between(p.local_rot[n, 1:], idle.local_rot[0, 1:]).max() < 1e-9
        assert p.root_pos[n, 2] == pytest.approx(idle.root_pos[0, 2])


def test_batched_equals_looped(lib):
    """N characters mixed together give the same poses as N one-character mixers."""
    cmds = [[("walk", 0.0, None), ("run", 0.7, 2.0)], [("run", 0.1, None), ("kick", 0.9, None)],
            [("idle", 0.0, 1.0), ("walk", 0.5, None)]]
    cfg = BlendConfig()

    def play(mixers):
        """One mixer for all characters, or one mixer per character."""
        out = []
        for f in range(180):
            t = f / 60
            for c in range(3):
                m, ch = (mixers[0], c) if len(mixers) == 1 else (mixers[c], 0)
                for i, (clip, t0, t1) in enumerate(cmds[c]):
                    if abs(t - t0) < 1e-9:
                        m.start(clip, character=ch, key=f"a{i}", priority=2 if clip == "kick" else 1)
                    if t1 is not None and abs(t - t1) < 1e-9:
                        m.stop(f"a{i}", character=ch)
            out.append([m.step(1 / 60) for m in mixers])
        return out

    batched = play([Mixer(lib, 3, cfg)])
    looped = play([Mixer(lib, 1, cfg) for _ in range(3)])
    for fb, fl in zip(batched, looped):
        for n in range(3):
            np.testing.assert_allclose(fb[0].root_pos[n], fl[n].root_pos[0], atol=1e-9)
            assert quat.angle_between(fb[0].local_rot[n], fl[n].local_rot[0]).max() < 1e-8


def test_cyclic_clip_root_motion_is_continuous_across_the_loop(lib):
    idx = lib.index("walk")
    dur = lib.duration("walk")
    t = np.array([dur - 0.02, dur - 0.01, dur, dur + 0.01, dur + 0.02])
    _, _, delta = lib.sample(np.full(4, idx), t[1:], t[:-1])
    for d in delta[1:]:   # about the same 1 cm step on both sides of the loop point, no jump
        np.testing.assert_allclose(d, delta[0], atol=2e-3)


def test_two_bone_ik_compiled_matches_numpy_and_reaches(lib):
    from kinodyn.data import library as L

    m = L.load("walk")
    sk = m.skeleton
    legs = footlock.legs(sk)
    q = np.array(m.local_rot[::5])
    root = np.array(m.root_pos[::5])
    gr, gp = fk_arrays(root, q, sk.offsets, sk.parents)
    rng = np.random.default_rng(4)
    for leg in legs:
        for raise_ankle in (False, True):   # dz: the pelvis came down by as much, the ankle goes back up
            rows = np.arange(len(q))
            c = gp[:, leg.ankle, :2]
            d = rng.normal(0, 0.04, c.shape)
            h = rng.uniform(-3, 3, len(q))
            dz = rng.uniform(0.0, 0.05, len(q)) if raise_ankle else None
            a = footlock.pin_feet(q, gr, gp, leg, rows, c + d, c, h, dz=dz)
            b = footlock.pin_feet_fast(q.copy(), gr, gp, leg, rows, c + d, c, h, dz=dz)
            assert quat.angle_between(a, b).max() < 1e-10
            gr2, gp2 = fk_arrays(root, b, sk.offsets, sk.parents)
            t = gp[:, leg.ankle].copy()
            t[:, :2] += d
            if dz is not None:
                t[:, 2] += dz
            err = np.linalg.norm(gp2[:, leg.ankle] - t, axis=1)
            length = (np.linalg.norm(gp[:, leg.knee] - gp[:, leg.hip], axis=1)
                      + np.linalg.norm(gp[:, leg.ankle] - gp[:, leg.knee], axis=1))
            reachable = np.linalg.norm(t - gp[:, leg.hip], axis=1) < 0.999 * length
            assert reachable.sum() > 15
            assert np.median(err[reachable]) < 1e-4 and err[reachable].max() < 2e-3   # reached within 2 mm
            assert quat.angle_between(gr2[:, leg.ankle], gr[:, leg.ankle]).max() < 1e-9   # foot keeps its orientation


def test_constraints_hold_a_planted_foot_through_a_blend(lib):
    """Walk into run with synchronization: while one foot is planted by the actions it does not move."""
    from kinodyn import contacts

    mx = Mixer(lib, 1, BlendConfig(), record=True)
    frames = []
    for f in range(240):
        if f == 60:
            mx.start("walk", key="w", priority=1)
        if f == 130:
            mx.start("run", key="r", priority=1)
            mx.stop("w")
        frames.append(mx.step(1 / 60))
        frames[-1] = (frames[-1], mx.support[0])
    support = np.array([s for _, s in frames])
    root = np.array([p.root_pos[0] for p, _ in frames])
    rot = np.array([p.local_rot[0] for p, _ in frames])
    from kinodyn.motion import Motion

    m = Motion(lib.skeleton, root, rot, 60.0)
    pts = contacts.foot_points(m)
    for side, code in (("left", 1), ("right", 2)):
        p = pts[side]
        low = p[np.arange(len(p)), np.argmin(p[..., 2], axis=1), :2]
        held = np.nonzero((support[1:] == code) & (support[:-1] == code))[0] + 1
        steps = np.linalg.norm(low[held] - low[held - 1], axis=1)
        assert len(held) > 20
        assert np.median(steps) < 1e-4   # a held foot stays put (heel-to-toe changes aside)


def test_errors_name_the_problem(lib):
    mx = Mixer(lib, 1, BlendConfig(max_actions=2))
    with pytest.raises(UnknownNameError, match="unknown clip 'swim'"):
        mx.start("swim")
    mx.start("walk")
    mx.start("run")
    with pytest.raises(ParameterError, match="max_actions=2"):
        mx.start("kick")
    with pytest.raises(ParameterError, match="speed must be"):
        Mixer(lib).start("walk", speed=0.0)
    with pytest.raises(ParameterError, match="character must be"):
        mx.start("walk", character=3)
    with pytest.raises(UnknownNameError, match="no action 'zzz'"):
        mx.stop("zzz")
    with pytest.raises(ParameterError, match="dt must be"):
        mx.step(0.0)
    with pytest.raises(ParameterError, match="constraints must be"):
        BlendConfig(constraints="maybe")


def test_compiled_frame_blend_matches_numpy(lib):
    from kinodyn.blend.pose import blend_frames, blend_frames_fast

    rng = np.random.default_rng(7)
    n, s = 40, 3
    i0 = rng.integers(0, len(lib.z) - 1, (n, s))
    a = rng.random((n, s))
    act = rng.random((n, s)) * (rng.random((n, s)) > 0.3)
    w, wn = priority_weights(act, rng.integers(0, 2, (n, s)).astype(float))
    ref = quat.from_rotvec(rng.normal(0, 0.3, (lib.skeleton.num_joints, 3)))
    q1 = blend_frames(lib.rot, i0, a, w, ref, wn)
    q2 = blend_frames_fast(lib.rot, i0, a, w, ref, wn)
    assert quat.angle_between(q1, q2).max() < 1e-12


def _crowd_poses(lib, compiled: bool, synchronize: bool = True, n: int = 6, frames: int = 240, **config):
    """A small crowd with restarts, stops and higher-priority actions; every frame's poses."""
    rng = np.random.default_rng(3)
    mx = Mixer(lib, n, BlendConfig(synchronize=synchronize, max_actions=5, **config))
    if not compiled:   # the numpy references of the weights and of the support constraints
        mx.compiled = False
        mx.footlock.constrain = functools.partial(constrain_reference, mx.footlock)
    for i in range(n):
        mx.start("walk", character=i, priority=1, speed=float(rng.uniform(0.85, 1.15)), key="walk")
        mx.start("run", character=i, priority=1, speed=float(rng.uniform(0.9, 1.1)), key="run")
        mx.start("walk", character=i, priority=1, speed=1.3, key="fast")
    restart = rng.integers(0, 60, n)
    roots, rots = [], []
    for f in range(frames):
        for i in np.nonzero((restart + f) % 60 == 0)[0]:
            acts = mx.chars[i].actions
            if "run" in acts and acts["run"].t_off is None:
                mx.stop("run", character=i)
            elif "run" not in acts:
                mx.start("run", character=i, priority=1, key="run")
        if f == 100:
            mx.start("kick", character=1, priority=2)
            mx.start("jump", character=2, priority=2)
        if f == 150:
            mx.stop("walk", character=0)
            mx.start("punch", character=3, priority=3, speed=1.1)
        p = mx.step(1 / 60)
        roots.append(p.root_pos.copy())
        rots.append(p.local_rot.copy())
    return np.array(roots), np.array(rots)


@pytest.mark.parametrize("synchronize", [True, False])
def test_compiled_mixer_matches_numpy_reference(synchronize):
    """The compiled per-frame path (weights, support constraints) gives the poses of the numpy
    reference path, and the stored root positions of that reference (a change of behaviour must update
    them knowingly)."""
    lib = builtin(["idle", "walk", "run", "punch", "kick", "jump"])
    r_fast, q_fast = _crowd_poses(lib, True, synchronize)
    r_ref, q_ref = _crowd_poses(lib, False, synchronize)
    np.testing.assert_allclose(r_fast, r_ref, atol=_TOL, rtol=0, err_msg="root")
    np.testing.assert_allclose(q_fast, q_ref, atol=_TOL, rtol=0, err_msg="rotations")
    if synchronize:
        stored = [[0.0, 0.0, 0.989644181], [0.0, 0.0, 0.989643308], [1.497719604, 0.157468841, 0.930940561],
                  [3.07158376, 0.33472448, 0.922517688], [3.112472453, 0.252784383, 0.938247359]]
        np.testing.assert_allclose(r_fast[::60].reshape(-1, 3)[::5], stored, atol=2e-9, rtol=0, err_msg="stored")


def test_compiled_lock_bound_matches_numpy_reference():
    """With a bound the held feet reach (``max_foot_offset`` 3 cm), the compiled lock bounds them as the
    numpy reference does (the bound counts the root's follow and the height correction)."""
    lib = builtin(["idle", "walk", "run", "punch", "kick", "jump"])
    r_fast, q_fast = _crowd_poses(lib, True, True, max_foot_offset=0.03)
    r_ref, q_ref = _crowd_poses(lib, False, True, max_foot_offset=0.03)
    np.testing.assert_allclose(r_fast, r_ref, atol=_TOL, rtol=0, err_msg="root")
    np.testing.assert_allclose(q_fast, q_ref, atol=_TOL, rtol=0, err_msg="rotations")
    r_free, _ = _crowd_poses(lib, True, True)
    assert np.abs(r_free - r_fast).max() > 1e-3   # the bound changed the poses: it was exercised


def test_figure_script_matches_the_stored_root_path():
    """Root path of the figure 12/13 script, every 150 frames, as stored (a regression guard for
    optimizations; a change of behaviour must update it knowingly)."""
    from kinodyn.blend.demo import transition_script
    from kinodyn.blend.script import run_script

    root = run_script(transition_script()).motion.root_pos[::150]
    stored = [[0.0, 0.0, 0.99], [3.206096067, 0.066211728, 0.921690863], [9.625124723, 0.585416705, 0.903117196],
              [15.743968783, 1.070073884, 0.917116921], [18.236005165, 1.25902962, 0.973015928],
              [20.333762374, 1.245299187, 0.923828819], [20.355545729, 1.24746284, 0.99]]
    np.testing.assert_allclose(root, stored, atol=2e-9, rtol=0)


def test_a_cyclic_clip_that_misses_its_loop_point_is_closed():
    """A captured cycle whose last frame misses its first by a few degrees and centimetres loops without
    a jump: the mismatch is spread over the clip (half off the first frame, half onto the last)."""
    from kinodyn.clips import close_loop as _close_loop
    from kinodyn.data import library as L

    walk = L.load("walk")
    rng = np.random.default_rng(3)
    rot = np.array(walk.local_rot)
    n = len(rot)
    bend = quat.from_rotvec(rng.normal(0.0, 0.05, (walk.skeleton.num_joints, 3)))   # about 4 degrees
    ramp = np.linspace(0.0, 1.0, n)[:, None]
    rot = quat.mul(rot, quat.slerp(quat.identity((1, walk.skeleton.num_joints)), bend[None], ramp))
    z = np.array(walk.root_pos[:, 2]) + 0.03 * np.linspace(0.0, 1.0, n)
    closed, zc = _close_loop(rot, z)
    assert quat.angle_between(closed[-1], closed[0]).max() < 1e-9
    assert zc[-1] == pytest.approx(zc[0], abs=1e-12)
    # the correction is spread: no frame moves by more than half the mismatch, neighbours stay close
    assert quat.angle_between(closed, rot).max() <= 0.5 * quat.angle(bend).max() + 1e-9
    step = quat.angle_between(closed[1:], closed[:-1]).max()
    assert step < quat.angle_between(rot[1:], rot[:-1]).max() + quat.angle(bend).max() / (n - 1) + 1e-9
    # a seamless clip is left as it is
    same, zs = _close_loop(np.array(walk.local_rot), np.array(walk.root_pos[:, 2]))
    assert quat.angle_between(same, walk.local_rot).max() < 1e-6
    np.testing.assert_allclose(zs, walk.root_pos[:, 2], atol=1e-6)


def test_a_stop_waits_for_the_action_that_replaces_it(lib):
    """Stopping the walk while the kick waits for its synchronized start hands over: the walk plays on
    at full weight until the kick starts (the neutral pose does not fill the wait), then fades out."""
    mx = Mixer(lib, 1, BlendConfig(), record=True)
    mx.start("walk", key="w", priority=1)
    for _ in range(60):
        mx.step(1 / 60)
    mx.start("kick", key="k", priority=2)
    mx.stop("w")
    assert mx.chars[0].actions["k"].t_on is None and mx.chars[0].actions["w"].t_off is None  # waiting
    for _ in range(120):
        mx.step(1 / 60)
    k, w = mx.chars[0].history["k"], mx.chars[0].history["w"]
    assert k.t_on is not None and k.t_on > 1.0 + 1e-6     # the kick did wait for a step boundary
    assert w.t_off == pytest.approx(k.t_on)                # and the walk faded out from then on
    rec = mx.recordings[0].arrays()
    wait = (rec["t"] > 1.0) & (rec["t"] <= k.t_on)
    assert wait.sum() >= 3 and np.max(rec["neutral"][wait]) < 1e-9
    np.testing.assert_allclose(rec["w"][1][wait], 1.0, atol=1e-9)


def test_the_pelvis_lowers_to_keep_a_held_foot_within_reach(lib):
    """Held feet at a stance change: the pelvis comes down (within max_pelvis_drop, at a bounded speed)
    instead of letting a straight leg's foot slide; with max_pelvis_drop=0 it never moves down."""
    def run(cfg):
        mx = Mixer(lib, 1, cfg)
        mx.start("walk", key="w", priority=1)
        drops = []
        for f in range(240):
            if f == 100:
                mx.start("kick", key="k", priority=2)
                mx.stop("w")
            mx.step(1 / 60)
            drops.append(float(mx.footlock.drop[0]))
        return np.array(drops)

    # without the closing step the walk is warped into the kick's stance and leaves a foot behind
    cfg = BlendConfig(closing_step=False)
    drops = run(cfg)
    assert drops.max() > 0.005 and drops.max() <= cfg.max_pelvis_drop + 1e-12
    assert np.diff(drops).max() <= cfg.max_pelvis_drop / 60 / 0.2 + 1e-12
    assert run(BlendConfig(max_pelvis_drop=0.0, closing_step=False)).max() == 0.0
    with pytest.raises(ParameterError, match="max_pelvis_drop"):
        BlendConfig(max_pelvis_drop=-0.01)


def test_the_root_follows_the_feet_without_jumps():
    """The root follows each held foot by the share of the weight it carries (passed over the double
    supports), so it never jumps when a foot lifts: the largest horizontal acceleration of the root in
    the figure 12/13 script stays that of a walking body."""
    from kinodyn.blend.demo import transition_script
    from kinodyn.blend.script import run_script

    m = run_script(transition_script()).motion
    acc = np.linalg.norm(np.diff(m.root_pos[:, :2], 2, axis=0), axis=1) * m.fps ** 2
    assert acc.max() < 40.0, acc.max()   # m/s^2; a support change that moved the root at once gave 300


def test_a_walk_fading_into_the_neutral_pose_ends_with_a_closing_step(lib):
    """A walk stopped while nothing else plays, at any moment of its cycle: without ``closing_step`` the
    lock ends up holding the feet a stride away from where the standing pose puts them (up to 25 cm,
    depending on when it was stopped); with it the walk plays on (within CLOSING_DELAY) until its feet
    stand as the neutral pose's, and the final stance is the same, close to the pose, whenever it stops."""
    from kinodyn.blend.character import CLOSING_DELAY

    def final_offset(stop, closing):
        mx = Mixer(lib, 1, BlendConfig(closing_step=closing, constraints="on"), record=True)
        mx.start("walk", key="w", priority=1)
        while mx.time < stop:
            mx.step(1 / 60)
        now = mx.time
        mx.stop("w")
        a = mx.chars[0].actions["w"]
        assert a.t_off == pytest.approx(now) if not closing else now <= a.t_off <= now + CLOSING_DELAY
        while mx.time < stop + 2.2:
            mx.step(1 / 60)
        return float(np.nanmax(mx.recordings[0].lock_offsets()[-10:]))

    stops = np.arange(0.9, 1.65, 0.1)
    plain = [final_offset(t, False) for t in stops]
    closed = [final_offset(t, True) for t in stops]
    assert max(plain) > 0.2 and max(closed) < 0.08
    assert max(closed) - min(closed) < 0.01


def _rates(rec, key, fps=60.0):
    """Warp rates (action time per second) of ``key`` wherever it carries a visible weight."""
    from kinodyn.blend.evaluate import WARP_WEIGHT

    h, w = rec[key]
    ok = np.isfinite(np.diff(h)) & (w[1:] >= WARP_WEIGHT) & (w[:-1] >= WARP_WEIGHT)
    return np.diff(h)[ok] * fps


@pytest.mark.parametrize("closing", [True, False])
def test_a_walk_into_a_jump_closes_its_stride_at_its_own_speed(closing):
    """Finding 6: a walk handing over to a jump (in place, its crouch a long double support) plays on
    at its own speed until the jump takes over, and the jump plays its crouch at its own speed; without
    the closing step both share the walk's short double support (here 0.60x-1.73x)."""
    lib = builtin(["idle", "walk", "jump"])
    mx = Mixer(lib, 1, BlendConfig(closing_step=closing, ramp_in=0.5, ramp_out=0.5), record=True)
    mx.start("walk", key="w", priority=1)
    for f in range(150):
        if f == 60:
            mx.start("jump", key="j", priority=2)
        if f == 72:
            mx.stop("w")
        mx.step(1 / 60)
    rec = mx.recordings[0].arrays()
    rates = np.concatenate([_rates(rec, "w"), _rates(rec, "j")])
    w, j = mx.chars[0].history["w"], mx.chars[0].history["j"]
    if closing:
        assert w.free is not None and w.free[0] == pytest.approx(j.t_on)
        assert rates.min() > 0.95 and rates.max() < 1.05, (rates.min(), rates.max())
    else:
        assert w.free is None and np.abs(rates - 1.0).max() > 0.3, (rates.min(), rates.max())


def test_a_start_during_a_lone_stance_does_not_wait_for_its_end():
    """A walk asked for while a kick stands alone in its last double support (from 1.28 s, 0.72 s
    long) starts at the next frame (the step is split), and neither is warped beyond 0.5x-2x."""
    lib = builtin(["idle", "walk", "kick"])
    mx = Mixer(lib, 1, BlendConfig(), record=True)
    mx.start("kick", key="k", priority=2)
    for f in range(180):
        if f == 84:
            mx.start("walk", key="w", priority=1)
        mx.step(1 / 60)
    w = mx.chars[0].history["w"]
    assert w.t_on == pytest.approx(1.4, abs=1e-9)
    rec = mx.recordings[0].arrays()
    rates = np.concatenate([_rates(rec, "w"), _rates(rec, "k")])
    assert rates.min() >= 0.5 and rates.max() <= 2.0, (rates.min(), rates.max())
