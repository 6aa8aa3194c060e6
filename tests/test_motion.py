"""kinodyn.motion.Motion: validation, immutability, slicing, resampling, concatenation, mirroring, facing
frame,
scaling and retargeting, on a small synthetic humanoid (Z up, faces +X, left = +Y)."""

from __future__ import annotations

import re
from dataclasses import FrozenInstanceError

import numpy as np
import pytest
from numpy.testing import assert_allclose

from kinodyn.errors import MotionError, ParameterError
from kinodyn.math import quat, xform
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

_TOL = 1e-12  # metres, quaternion components
_ANG_TOL = 1e-9  # radians, where a heading goes through atan2 of products
_SEED = 4242
_REFLECT_Y = np.array([1.0, -1.0, 1.0])


def humanoid(asym: bool = False) -> Skeleton:
    """A 13-joint humanoid, symmetric unless ``asym`` (then the left leg is longer)."""
    rows = [
        ("Hips", -1, (0.0, 0.0, 0.0)),
        ("Spine", 0, (0.0, 0.0, 0.25)),
        ("Head", 1, (0.0, 0.0, 0.35)),
        ("LeftArm", 1, (0.0, 0.2, 0.25)),
        ("LeftHand", 3, (0.0, 0.3, 0.0)),
        ("RightArm", 1, (0.0, -0.2, 0.25)),
        ("RightHand", 5, (0.0, -0.3, 0.0)),
        ("LeftUpLeg", 0, (0.0, 0.1, -0.05)),
        ("LeftLeg", 7, (0.0, 0.0, -0.42)),
        ("LeftFoot", 8, (0.0, 0.0, -0.4)),
        ("RightUpLeg", 0, (0.0, -0.1, -0.05)),
        ("RightLeg", 10, (0.0, 0.0, -0.42)),
        ("RightFoot", 11, (0.0, 0.0, -0.4)),
    ]
    offsets = np.array([r[2] for r in rows])
    if asym:
        offsets[8] *= 1.1
    return Skeleton(
        tuple(r[0] for r in rows),
        np.array([r[1] for r in rows]),
        offsets,
        end_parents=np.array([2, 9, 12]),
        end_offsets=np.array([[0, 0, 0.1], [0.15, 0, -0.05], [0.15, 0, -0.05]]),
    )


def wavy(sk: Skeleton, n: int = 60, fps: float = 30.0, seed: int = _SEED, name: str = "wavy") -> Motion:
    """Smooth, non-trivial motion: every joint turns, the root travels and turns."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)[:, None, None] / fps
    amp = rng.uniform(0.2, 0.8, size=(1, sk.num_joints, 3))
    freq = rng.uniform(0.3, 1.5, size=(1, sk.num_joints, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(1, sk.num_joints, 3))
    rot = quat.from_rotvec(amp * np.sin(2 * np.pi * freq * t + phase))
    rot[:, 0] = quat.mul(quat.from_heading(0.8 * t[:, 0, 0] + 0.3), rot[:, 0])
    tt = t[:, 0, 0]
    root = np.stack([1.2 * tt + 0.5, 0.3 * np.sin(tt) - 0.2, 0.95 + 0.03 * np.sin(5 * tt)], axis=-1)
    return Motion(sk, root, rot, fps, name=name)


def assert_same_rotation(a, b, tol=_TOL, err_msg=""):
    d = np.minimum(np.abs(a - b).max(axis=-1), np.abs(a + b).max(axis=-1))
    assert np.all(d <= tol), f"{err_msg}: {d.max():.3g} > {tol:g}"


def wrapped(a):
    return xform.wrap_angle(np.asarray(a) + 1.0) - 1.0  # angles near 0 (mod 2 pi) to near 0


# --------------------------------------------------------------------------- validation and immutability


def test_validation_messages():
    sk = humanoid()
    rot = quat.identity((4, 13))
    root = np.zeros((4, 3))

    def raises(msg, **kw):
        args = dict(skeleton=sk, root_pos=root, local_rot=rot, fps=30.0)
        args.update(kw)
        with pytest.raises(MotionError, match="^" + re.escape(msg) + "$"):
            Motion(**args)

    raises("skeleton must be a Skeleton, got str", skeleton="hips")
    raises("local_rot must have shape (F, 13, 4), got (4, 12, 4)", local_rot=quat.identity((4, 12)))
    raises("local_rot must have shape (F, 13, 4), got (13, 4)", local_rot=quat.identity((13,)))
    raises("root_pos must have shape (4, 3), got (3, 3)", root_pos=np.zeros((3, 3)))
    raises("fps must be a positive number, got 0", fps=0)
    raises("fps must be a positive number, got -30.0", fps=-30.0)
    raises("fps must be a positive number, got nan", fps=float("nan"))
    bad_root = root.copy()
    bad_root[2, 1] = np.nan
    raises("root_pos has non-finite values (first at frame 2)", root_pos=bad_root)
    bad_rot = rot.copy()
    bad_rot[3, 5, 0] = np.inf
    raises("local_rot has non-finite values (first at frame 3)", local_rot=bad_rot)
    zero = rot.copy()
    zero[1, 4] = 0.0
    raises("local_rot contains zero quaternions", local_rot=zero)
    raises("translations must have shape (4, 13, 3), got (4, 13)", translations=np.zeros((4, 13)))
    tr = np.zeros((4, 13, 3))
    tr[0, 0, 0] = np.nan
    raises("translations have non-finite values", translations=tr)
    m = Motion(sk, root, rot, 30.0)
    with pytest.raises(MotionError, match=re.escape("root_pos has non-finite values (first at frame 0)")):
        m.replace(root_pos=np.full((4, 3), np.nan))


def test_rotations_are_normalized_and_inputs_copied():
    sk = humanoid()
    rot = quat.identity((3, 13)) * 2.0
    root = np.zeros((3, 3))
    m = Motion(sk, root, rot, 30)
    assert_allclose(m.local_rot, quat.identity((3, 13)), err_msg="normalized")
    rot[:] = 5.0
    root[:] = 1.0
    assert_allclose(m.root_pos, 0.0, err_msg="copied")
    assert isinstance(m.fps, float)


def test_arrays_are_read_only_and_motion_frozen():
    m = wavy(humanoid()).replace(translations=np.zeros((60, 13, 3)))
    for arr in (m.root_pos, m.local_rot, m.translations):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 1.0
    with pytest.raises(FrozenInstanceError):
        m.fps = 60.0  # type: ignore[misc]
    lp = m.local_positions()
    lp[:] = 1.0  # derived arrays are fresh copies
    assert np.all(m.translations == 0.0)


def test_replace_and_basics():
    m = wavy(humanoid(), n=61, fps=30)
    m2 = m.replace(fps=60.0, name="fast")
    assert m2 is not m and m2.fps == 60.0 and m2.name == "fast" and m.fps == 30.0
    assert m2.local_rot is m.local_rot or np.array_equal(m2.local_rot, m.local_rot)
    assert m.num_frames == len(m) == 61 and m.num_joints == 13
    assert m.duration == pytest.approx(2.0) and m.dt == pytest.approx(1 / 30)
    assert_allclose(m.times(), np.arange(61) / 30)
    assert repr(m) == "Motion('wavy', 61 frames at 30 fps = 2.00 s, 13 joints)"
    lp = m.local_positions()
    assert_allclose(lp[:, 0], m.root_pos)
    assert_allclose(lp[:, 1:], np.broadcast_to(m.skeleton.offsets[1:], (61, 12, 3)))


# --------------------------------------------------------------------------- slicing


def test_slicing_with_steps_and_indices():
    m = wavy(humanoid(), n=60, fps=30)
    s = m[10:50]
    assert s.num_frames == 40 and s.fps == 30.0
    assert_allclose(s.root_pos, m.root_pos[10:50])
    assert_allclose(s.local_rot, m.local_rot[10:50])
    s2 = m[::2]
    assert s2.num_frames == 30 and s2.fps == pytest.approx(15.0), "a step divides the frame rate"
    assert s2.duration == pytest.approx(m.times()[::2][-1])
    s3 = m[5:40:3]
    assert s3.fps == pytest.approx(10.0)
    assert_allclose(s3.local_rot, m.local_rot[5:40:3])
    one = m[7]
    assert one.num_frames == 1
    assert_allclose(one.root_pos[0], m.root_pos[7])
    last = m[-1]
    assert last.num_frames == 1
    assert_allclose(last.root_pos[0], m.root_pos[-1])
    assert_allclose(m[-2].root_pos[0], m.root_pos[-2])
    picked = m[[0, 5, 9]]
    assert picked.num_frames == 3 and picked.fps == 30.0
    assert_allclose(picked.root_pos, m.root_pos[[0, 5, 9]])
    with pytest.raises(ParameterError, match=r"^frame slices need a positive step, got -1$"):
        m[::-1]
    tr = m.replace(translations=np.arange(60 * 13 * 3, dtype=float).reshape(60, 13, 3))
    assert_allclose(tr[3:9:2].translations, tr.translations[3:9:2])


def test_trim_by_seconds():
    m = wavy(humanoid(), n=61, fps=30)
    t = m.trim(0.5, 1.0)
    assert t.num_frames == 16
    assert_allclose(t.root_pos, m.root_pos[15:31])
    assert m.trim().num_frames == 61
    assert m.trim(1.5).num_frames == 16


# --------------------------------------------------------------------------- resampling


@pytest.mark.parametrize("new_fps", [60.0, 90.0, 24.0, 30.0, 7.0])
def test_resample_duration_and_sample_times(new_fps):
    m = wavy(humanoid(), n=61, fps=30)  # 2 s
    r = m.resample(new_fps)
    assert r.fps == new_fps
    assert r.duration <= m.duration + 1e-9, "never past the last frame"
    assert m.duration - r.duration < 1.0 / new_fps, "duration preserved to within one new frame"
    k = int(round(new_fps)) // 30 if new_fps % 30 == 0 else None
    if k:  # an integer multiple: every k-th new frame is an original frame
        assert_allclose(r.root_pos[::k], m.root_pos, atol=_TOL, err_msg="positions at the original times")
        assert_same_rotation(
            r.local_rot[::k], m.local_rot, tol=1e-12, err_msg="rotations at the original times"
        )
    t = r.times()
    common = np.isclose((t * 30) % 1.0, 0.0, atol=1e-9) | np.isclose((t * 30) % 1.0, 1.0, atol=1e-9)
    idx = np.rint(t[common] * 30).astype(int)
    assert_allclose(r.root_pos[common], m.root_pos[idx], atol=1e-12, err_msg="every shared time reproduced")


def test_resample_uses_slerp():
    """Two keys 120 degrees apart about Z, one at 10 fps, resampled to 30 fps: slerp advances 40 degrees per
    frame (nlerp would not), and the sign of a key does not matter."""
    sk = humanoid()
    rot = quat.identity((2, 13))
    rot[1, 3] = -quat.from_axis_angle([0.0, 0.0, 1.0], np.deg2rad(120.0))  # stored with w < 0 on purpose
    m = Motion(sk, np.zeros((2, 3)), rot, 10.0)
    r = m.resample(30.0)
    assert r.num_frames == 4
    ang = np.rad2deg(quat.angle(r.local_rot[:, 3]))
    assert_allclose(ang, [0.0, 40.0, 80.0, 120.0], atol=1e-9, err_msg="constant angular speed")
    assert_allclose(r.local_rot[:, 0], quat.identity((4,)), atol=_TOL)
    assert_allclose(r.root_pos, 0.0)


def test_resample_bad_fps():
    m = wavy(humanoid(), n=10)
    with pytest.raises(ParameterError, match=r"^fps must be positive, got 0.0$"):
        m.resample(0)
    with pytest.raises(ParameterError, match=r"^fps must be positive, got nan$"):
        m.resample(float("nan"))


# ---------------------------------------------------------------- ground, transforms, concatenation


def test_ground_transformed_and_aligned_to():
    m = wavy(humanoid())
    g = m.ground()
    assert g.shape == (60, 3)
    assert_allclose(g[:, :2], m.root_pos[:, :2])
    assert_allclose(wrapped(g[:, 2] - quat.heading(m.local_rot[:, 0])), 0.0, atol=_ANG_TOL)
    move = np.array([3.0, -1.0, 2.0])
    t = m.transformed(move)
    assert_allclose(t.root_pos[:, 2], m.root_pos[:, 2], err_msg="height kept")
    gt = t.ground()
    assert_allclose(gt[:, :2], xform.compose(move, g)[:, :2], atol=_TOL, err_msg="ground moved by g")
    assert_allclose(wrapped(gt[:, 2] - xform.compose(move, g)[:, 2]), 0.0, atol=_ANG_TOL)
    assert_allclose(t.local_rot[:, 1:], m.local_rot[:, 1:], err_msg="local pose kept")
    assert_allclose(
        t.global_positions(), xform.apply(move, m.global_positions()), atol=1e-12, err_msg="rigid move"
    )
    target = np.array([-2.0, 4.0, -1.0])
    a = m.aligned_to(target, frame=10)
    assert_allclose(a.ground()[10, :2], target[:2], atol=_TOL)
    assert_allclose(wrapped(a.ground()[10, 2] - target[2]), 0.0, atol=_ANG_TOL)


def test_concatenate_aligns_the_second_clip():
    sk = humanoid()
    a = wavy(sk, n=40, seed=1)
    b = wavy(sk, n=30, seed=2).transformed([5.0, 5.0, 2.5])
    c = a.concatenate(b)
    assert c.num_frames == 40 + 29, "b's first frame is dropped"
    assert c.name == a.name and c.fps == a.fps
    assert_allclose(c.root_pos[:40], a.root_pos, err_msg="first clip untouched")
    assert_same_rotation(c.local_rot[:40], a.local_rot, err_msg="first clip untouched")
    # b moved so that its (dropped) first frame stands where and faces where a's last frame does
    end = a.ground()[-1]
    gb = b.ground()
    want = xform.compose(end, xform.relative(gb[0], gb[1:]))
    got = c.ground()[40:]
    assert_allclose(got[:, :2], want[:, :2], atol=1e-12, err_msg="positions follow on")
    assert_allclose(wrapped(got[:, 2] - want[:, 2]), 0.0, atol=_ANG_TOL, err_msg="headings follow on")
    assert_allclose(c.root_pos[40:, 2], b.root_pos[1:, 2], err_msg="heights kept")
    assert_same_rotation(c.local_rot[40:, 1:], b.local_rot[1:, 1:], err_msg="local poses kept")
    # the rotations are unrolled across the junction
    assert np.all(np.sum(c.local_rot[40] * c.local_rot[39], axis=-1) >= 0.0)
    # keeping the first frame, it lands exactly on a's last ground transform
    k = a.concatenate(b, drop_first=False)
    assert k.num_frames == 70
    assert_allclose(k.ground()[40, :2], end[:2], atol=1e-12)
    assert_allclose(wrapped(k.ground()[40, 2] - end[2]), 0.0, atol=_ANG_TOL)
    raw = a.concatenate(b, align=False)
    assert_allclose(raw.root_pos[40:], b.root_pos[1:], err_msg="align=False leaves b where it is")


def test_concatenate_is_continuous_for_a_cyclic_clip():
    """A clip that walks straight at constant speed, appended to itself after being moved anywhere, continues
    the same straight line at the same speed (no jump at the junction)."""
    sk = humanoid()
    n, fps = 31, 30.0
    t = np.arange(n) / fps
    h = 0.6
    rot = quat.identity((n, 13))
    rot[:, 0] = quat.from_heading(np.full(n, h))
    rot[:, 8] = quat.from_axis_angle([0.0, 1.0, 0.0], 0.3 * np.sin(2 * np.pi * t))  # periodic in 1 s
    root = np.stack([1.3 * t * np.cos(h), 1.3 * t * np.sin(h), np.full(n, 0.9)], axis=-1)
    clip = Motion(sk, root, rot, fps)
    c = clip.concatenate(clip.transformed([10.0, -3.0, -2.0]))
    assert c.num_frames == 61
    step = np.diff(c.root_pos, axis=0)
    assert_allclose(
        step, np.broadcast_to(step[0], step.shape), atol=1e-12, err_msg="constant velocity throughout"
    )
    assert_allclose(np.linalg.norm(step[:, :2], axis=-1), 1.3 / fps, atol=1e-12)
    assert_allclose(wrapped(c.ground()[:, 2] - h), 0.0, atol=_ANG_TOL, err_msg="same heading throughout")
    whole = Motion(
        sk, np.concatenate([root, root[1:] + root[-1] - root[0]]), np.concatenate([rot, rot[1:]]), fps
    )
    assert_allclose(
        c.global_positions(), whole.global_positions(), atol=1e-12, err_msg="equals the long clip"
    )


def test_concatenate_errors():
    sk = humanoid()
    a = wavy(sk, n=10)
    with pytest.raises(
        MotionError, match=re.escape("cannot concatenate motions at 30 and 60 fps; resample first")
    ):
        a.concatenate(a.replace(fps=60.0))
    other = Motion(
        humanoid(asym=True).replace(names=tuple(f"x{i}" for i in range(13))), a.root_pos, a.local_rot, 30
    )
    with pytest.raises(MotionError, match=r"^cannot concatenate motions of different skeletons "):
        a.concatenate(other)
    with pytest.raises(
        MotionError, match=r"^cannot concatenate a motion with animated translations and one without$"
    ):
        a.concatenate(a.replace(translations=np.zeros((10, 13, 3))))


# --------------------------------------------------------------------------- mirroring


def _reflect_q(q):
    return q * np.array([1.0, -1.0, 1.0, -1.0])


@pytest.mark.parametrize("asym", [False, True])
def test_mirrored_twice_is_the_original(asym):
    m = wavy(humanoid(asym)).replace(translations=np.random.default_rng(1).normal(size=(60, 13, 3)))
    mm = m.mirrored().mirrored()
    assert mm.skeleton == m.skeleton
    assert_allclose(mm.root_pos, m.root_pos, atol=_TOL)
    assert_same_rotation(mm.local_rot, m.local_rot, err_msg="rotations")
    assert_allclose(mm.translations, m.translations, atol=_TOL)


@pytest.mark.parametrize("asym", [False, True])
def test_mirrored_fk_is_the_reflected_fk(asym):
    m = wavy(humanoid(asym))
    mir = m.mirrored()
    if not asym:
        assert mir.skeleton is m.skeleton, "a symmetric skeleton is kept"
    perm = m.skeleton.mirror_map()
    gr, gp = m.fk()
    mgr, mgp = mir.fk()
    assert_allclose(
        mgp, gp[:, perm] * _REFLECT_Y, atol=1e-12, err_msg="positions reflected across the XZ plane"
    )
    assert_same_rotation(mgr, _reflect_q(gr[:, perm]), tol=1e-12, err_msg="global rotations reflected")
    # reflecting a rotation = conjugating its matrix by diag(1, -1, 1)
    f = np.diag(_REFLECT_Y)
    assert_allclose(quat.to_matrix(mgr[:, 4]), f @ quat.to_matrix(gr[:, perm[4]]) @ f, atol=1e-12)
    # a left turn becomes a right turn
    assert_allclose(wrapped(mir.ground()[:, 2] + m.ground()[:, 2]), 0.0, atol=_ANG_TOL)


def test_mirrored_along_x():
    m = wavy(humanoid())
    mir = m.mirrored(axis=0)
    gp = m.global_positions()
    perm = m.skeleton.mirror_map()
    # the skeleton is not symmetric across X, so mirrored(0) builds a reflected skeleton
    assert_allclose(mir.global_positions(), gp[:, perm] * [-1.0, 1.0, 1.0], atol=1e-12)


# ---------------------------------------------------------------- facing frame, scaling, retargeting


@pytest.mark.parametrize("forward", [None, [1.0, 0.0, 0.0]])
def test_facing_frame(forward):
    m = wavy(humanoid())
    f = m.facing_frame(forward)
    assert_allclose(f.root_pos[:, :2], 0.0, err_msg="root xy zero")
    assert_allclose(f.root_pos[:, 2], m.root_pos[:, 2], err_msg="height kept")
    assert_allclose(wrapped(f.ground(forward)[:, 2]), 0.0, atol=_ANG_TOL, err_msg="zero heading every frame")
    assert_same_rotation(f.local_rot[:, 1:], m.local_rot[:, 1:], err_msg="local poses unchanged")
    # the whole body, seen from the ground transform, is unchanged
    g = m.ground(forward)
    gp = m.global_positions()
    local = xform.apply(xform.inverse(g)[:, None], gp)
    assert_allclose(f.global_positions(), local, atol=1e-12, err_msg="body relative to its ground transform")


def test_scaled():
    m = wavy(humanoid())
    s = m.scaled(100.0)
    assert_allclose(s.global_positions(), 100.0 * m.global_positions(), atol=1e-9, err_msg="positions scale")
    assert_allclose(s.local_rot, m.local_rot, err_msg="rotations kept")
    assert_allclose(s.skeleton.offsets, 100.0 * m.skeleton.offsets)
    tr = m.replace(translations=np.ones((60, 13, 3))).scaled(0.5)
    assert_allclose(tr.translations, 0.5)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(
            ParameterError, match="^" + re.escape(f"scale must be a positive number, got {bad}") + "$"
        ):
            m.scaled(bad)


def test_retargeted_keeps_rotations_and_scales_the_root_by_leg_ratio():
    m = wavy(humanoid())
    sk = m.skeleton
    offs = np.array(sk.offsets)
    legs = [7, 8, 9, 10, 11, 12]
    offs[legs] *= 1.25
    offs[1:7] *= 0.8
    tall = sk.replace(offsets=offs)
    r = m.retargeted(tall)
    assert r.skeleton is tall
    assert_allclose(r.local_rot, m.local_rot, err_msg="same rotations")
    h0 = -sk.rest_positions()[:, 2].min()
    h1 = -tall.rest_positions()[:, 2].min()
    assert h1 / h0 == pytest.approx(1.25), "the hip height is all leg"
    assert_allclose(r.root_pos, m.root_pos * (h1 / h0), atol=_TOL, err_msg="root scaled by the leg ratio")
    # standing in the rest pose with the feet on the floor: still on the floor after retargeting
    stand = Motion(sk, np.tile([0.3, 0.1, h0], (5, 1)), quat.identity((5, 13)), 30.0).retargeted(tall)
    assert_allclose(stand.global_positions()[:, [9, 12], 2], 0.0, atol=1e-12, err_msg="feet on the floor")
    with pytest.raises(
        MotionError, match=r"^retargeting needs a skeleton with the same joint names and parents$"
    ):
        m.retargeted(tall.replace(names=tuple(n + "_" for n in tall.names)))


def test_retarget_is_exact_for_a_uniformly_scaled_skeleton():
    m = wavy(humanoid())
    r = m.retargeted(m.skeleton.scaled(1.3))
    assert_allclose(r.global_positions(), 1.3 * m.global_positions(), atol=1e-12)


def test_fk_methods_agree():
    m = wavy(humanoid())
    gr, gp = m.fk()
    ref_r, ref_p = quat.fk(m.local_rot, m.local_positions(), m.skeleton.parents)
    assert_allclose(gp, ref_p, atol=1e-12)
    assert_allclose(gr, ref_r, atol=1e-12)
    assert_allclose(m.global_positions(), gp)


def test_digest_follows_what_the_motion_plays_not_its_name():
    from kinodyn.data import library

    walk = library.load("walk")
    same = walk.replace(root_pos=walk.root_pos.copy(), name="renamed")
    assert same.digest() == walk.digest()
    moved = walk.root_pos.copy()
    moved[10, 2] += 1e-9
    assert walk.replace(root_pos=moved).digest() != walk.digest()
    assert walk.resample(30.0).digest() != walk.digest()
    assert walk.mirrored().digest() != walk.digest()
