"""kinodyn.kinematics: the numba forward kinematics against two references, end sites, and velocities
against motions whose velocities are known in closed form."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from kinodyn import kinematics
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

_TOL = 1e-12  # metres and quaternion components (the module promises 1e-12 against quat.fk)
_SEED = 99


def branchy(n_joints: int = 12, seed: int = _SEED) -> Skeleton:
    """A random tree with parents[j] < j and several branches."""
    rng = np.random.default_rng(seed)
    parents = np.array([-1] + [int(rng.integers(0, j)) for j in range(1, n_joints)])
    ends = np.array([n_joints - 1, n_joints // 2, 0])
    return Skeleton(
        tuple(f"j{i}" for i in range(n_joints)),
        parents,
        rng.normal(size=(n_joints, 3)) * 0.3,
        end_parents=ends,
        end_offsets=rng.normal(size=(3, 3)) * 0.1,
    )


def random_motion(sk: Skeleton, n: int = 25, seed: int = _SEED, translations: bool = False) -> Motion:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, sk.num_joints, 4))
    tr = rng.normal(size=(n, sk.num_joints, 3)) if translations else None
    return Motion(sk, rng.normal(size=(n, 3)), q, 30.0, translations=tr)


def matrix_fk(motion: Motion):
    """Independent reference: 4x4 homogeneous transforms built with scipy, multiplied down the tree."""
    sk = motion.skeleton
    lp = motion.local_positions()
    f, j = motion.num_frames, sk.num_joints
    world = np.zeros((f, j, 4, 4))
    for k in range(j):
        local = np.zeros((f, 4, 4))
        local[:, :3, :3] = Rotation.from_quat(quat.to_scipy(motion.local_rot[:, k])).as_matrix()
        local[:, :3, 3] = lp[:, k]
        local[:, 3, 3] = 1.0
        world[:, k] = local if sk.parents[k] < 0 else world[:, sk.parents[k]] @ local
    return world


def assert_same_rotation(a, b, tol=_TOL, err_msg=""):
    d = np.minimum(np.abs(a - b).max(axis=-1), np.abs(a + b).max(axis=-1))
    assert np.all(d <= tol), f"{err_msg}: {d.max():.3g} > {tol:g}"


# --------------------------------------------------------------------------- forward kinematics


@pytest.mark.parametrize("translations", [False, True])
def test_numba_fk_equals_quat_fk(translations):
    m = random_motion(branchy(), translations=translations)
    gr, gp = kinematics.forward_kinematics(m)
    ref_r, ref_p = quat.fk(m.local_rot, m.local_positions(), m.skeleton.parents)
    assert gr.shape == (25, 12, 4) and gp.shape == (25, 12, 3)
    assert_allclose(gr, ref_r, atol=_TOL, rtol=0, err_msg="global rotations")
    assert_allclose(gp, ref_p, atol=_TOL, rtol=0, err_msg="global positions")


@pytest.mark.parametrize("translations", [False, True])
def test_fk_equals_matrix_product_fk(translations):
    m = random_motion(branchy(seed=3), seed=4, translations=translations)
    gr, gp = m.fk()
    world = matrix_fk(m)
    assert_allclose(gp, world[..., :3, 3], atol=_TOL, err_msg="positions")
    assert_allclose(quat.to_matrix(gr), world[..., :3, :3], atol=_TOL, err_msg="rotation matrices")


def test_translations_replace_offsets_but_not_the_root():
    sk = branchy()
    m = random_motion(sk, translations=True)
    rest = m.replace(translations=np.broadcast_to(sk.offsets, (25, 12, 3)) + 0.0)
    gr0, gp0 = m.replace(translations=None).fk()
    gr1, gp1 = rest.fk()
    assert_allclose(gp1, gp0, atol=_TOL, err_msg="translations equal to the offsets change nothing")
    assert_allclose(gr1, gr0, atol=_TOL)
    shifted = m.replace(translations=np.array(m.translations) + [0.0, 0.0, 0.0])
    tr = np.array(m.translations)
    tr[:, 0] += 100.0  # the root's slot is ignored: the root is at root_pos
    assert_allclose(m.replace(translations=tr).fk()[1], shifted.fk()[1], atol=_TOL)
    assert_allclose(m.fk()[1][:, 0], m.root_pos)


def test_fk_arrays_single_frame_and_known_chain():
    """A straight chain bent 90 degrees about Z at the second joint, root at (-3, 6, 5)."""
    parents = np.array([-1, 0, 1, 2])
    offsets = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    rot = quat.identity((1, 4))
    rot[0, 1] = quat.from_axis_angle([0.0, 0.0, 1.0], np.pi / 2)
    gr, gp = kinematics.fk_arrays(np.array([[-3.0, 6.0, 5.0]]), rot, offsets, parents)
    assert_allclose(gp[0], [[-3, 6, 5], [-2, 6, 5], [-2, 7, 5], [-4, 7, 5]], atol=_TOL)
    assert_same_rotation(gr[0, 3], rot[0, 1])
    empty = kinematics.fk_arrays(np.zeros((0, 3)), np.zeros((0, 4, 4)), offsets, parents)
    assert empty[0].shape == (0, 4, 4) and empty[1].shape == (0, 4, 3)


def test_fk_accepts_non_contiguous_input():
    m = random_motion(branchy(), n=40)
    strided = kinematics.fk_arrays(m.root_pos[::2], m.local_rot[::2], m.skeleton.offsets, m.skeleton.parents)
    full = kinematics.fk_arrays(m.root_pos, m.local_rot, m.skeleton.offsets, m.skeleton.parents)
    assert_allclose(strided[1], full[1][::2], atol=0.0)


def test_end_site_positions():
    m = random_motion(branchy(seed=5), seed=6)
    ends = kinematics.end_site_positions(m)
    world = matrix_fk(m)
    sk = m.skeleton
    parent = world[:, sk.end_parents]  # (F, E, 4, 4)
    want = (parent[..., :3, :3] @ sk.end_offsets[None, :, :, None])[..., 0] + parent[..., :3, 3]
    assert ends.shape == (25, 3, 3)
    assert_allclose(ends, want, atol=_TOL, err_msg="end sites")
    gr, gp = m.fk()
    assert_allclose(kinematics.end_site_positions(m, gr, gp), ends, atol=0.0, err_msg="precomputed FK")


# --------------------------------------------------------------------------- velocities


def test_root_moving_at_constant_velocity():
    sk = branchy()
    n, fps = 30, 60.0
    vel = np.array([1.5, -0.5, 0.25])
    t = np.arange(n) / fps
    rot = quat.normalize(np.tile(np.random.default_rng(1).normal(size=(sk.num_joints, 4)), (n, 1, 1)))
    m = Motion(sk, np.array([0.1, 0.2, 0.9]) + t[:, None] * vel, rot, fps)
    lin, ang = kinematics.joint_velocities(m)
    assert lin.shape == ang.shape == (n, sk.num_joints, 3)
    assert_allclose(
        lin, np.broadcast_to(vel, lin.shape), atol=1e-10, err_msg="every joint moves with the root"
    )
    assert_allclose(ang, 0.0, atol=1e-10, err_msg="nothing turns")


def test_joint_spinning_at_known_angular_velocity():
    """Joint 1 spins about a fixed axis at omega; joint 2 sits at distance r from that axis, so it moves on a
    circle: central differences give speed r sin(omega dt) / dt exactly (one-sided ones at the ends)."""
    parents = np.array([-1, 0, 1])
    offsets = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.5], [0.3, 0.0, 0.0]])
    sk = Skeleton(("root", "spinner", "tip"), parents, offsets)
    n, fps, omega = 50, 30.0, 4.0  # rad/s about +Z
    t = np.arange(n) / fps
    rot = quat.identity((n, 3))
    tilt = quat.from_axis_angle([1.0, 0.0, 0.0], 0.4)  # a fixed, tilted root: the world axis is R_root z
    rot[:, 0] = tilt
    rot[:, 1] = quat.from_axis_angle([0.0, 0.0, 1.0], omega * t)
    m = Motion(sk, np.zeros((n, 3)), rot, fps)
    lin, ang = kinematics.joint_velocities(m)
    axis_world = quat.mul_vec(tilt, [0.0, 0.0, 1.0])
    assert_allclose(ang[:, 1], np.broadcast_to(omega * axis_world, (n, 3)), atol=1e-10, err_msg="spinner")
    assert_allclose(ang[:, 2], ang[:, 1], atol=1e-10, err_msg="the tip turns with it")
    assert_allclose(ang[:, 0], 0.0, atol=1e-12, err_msg="root still")
    dt = 1.0 / fps
    speed = np.linalg.norm(lin[:, 2], axis=-1)
    assert_allclose(speed[1:-1], 0.3 * np.sin(omega * dt) / dt, atol=1e-10, err_msg="central differences")
    assert_allclose(
        speed[[0, -1]], 0.3 * 2 * np.sin(omega * dt / 2) / dt, atol=1e-10, err_msg="one-sided ends"
    )
    gp = m.global_positions()
    # direction: omega x r (tangent to the circle), up to the O(dt^2) of the finite difference
    tangent = np.cross(omega * axis_world, gp[:, 2] - gp[:, 1])
    cos = np.sum(lin[1:-1, 2] * tangent[1:-1], -1) / (speed[1:-1] * np.linalg.norm(tangent[1:-1], axis=-1))
    assert_allclose(cos, 1.0, atol=1e-12)


def test_angular_velocity_is_in_the_world_frame_and_handles_sign_flips():
    n, fps = 40, 100.0
    t = np.arange(n) / fps
    w1, w2 = 2.0, 3.0
    parent = quat.from_axis_angle([0.0, 0.0, 1.0], w1 * t)
    child = quat.mul(parent, quat.from_axis_angle([1.0, 0.0, 0.0], w2 * t))
    child[::3] *= -1.0  # q and -q are the same rotation
    ang = kinematics.angular_velocity(child, fps)
    # world angular velocity of R_z(w1 t) R_x(w2 t) is w1 z + R_z(w1 t) w2 x
    want = np.stack([w2 * np.cos(w1 * t), w2 * np.sin(w1 * t), np.full(n, w1)], axis=-1)
    assert_allclose(ang[1:-1], want[1:-1], atol=3e-3, err_msg="world frame (O(dt^2) differences)")
    assert_allclose(kinematics.angular_velocity(child[:1], fps), 0.0)
    assert kinematics.angular_velocity(child[:, None], fps).shape == (n, 1, 3)


def test_linear_velocity_edges():
    x = np.array([[0.0], [1.0], [4.0], [9.0]])
    assert_allclose(
        kinematics.linear_velocity(x, 2.0), [[2.0], [4.0], [8.0], [10.0]], err_msg="central / one-sided"
    )
    assert_allclose(kinematics.linear_velocity(x[:1], 2.0), [[0.0]], err_msg="one frame: zero")
