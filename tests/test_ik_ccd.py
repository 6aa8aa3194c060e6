"""CCD IK (equations 2-5) with hinge limits and reach cones, on arms-down and T-pose skeletons."""

import numpy as np
import pytest

from kinodyn import limits as jl
from kinodyn.ik import ccd
from kinodyn.contact.avatar import build_avatar, pose_fk
from kinodyn.data.skeleton import humanoid
from kinodyn.math import quat
from kinodyn.motion import Motion

@pytest.fixture(scope="module")
def avatar():
    return build_avatar(humanoid())


def _arm(avatar):
    sk = avatar.skeleton
    chain = avatar.chains[[sk.names[c[0]] for c in avatar.chains].index("LeftShoulder")]
    lim = ccd.chain_limits(avatar.limits, avatar.cone_axes, avatar.cone_points, chain)
    q = quat.identity((sk.num_joints,))
    gr, gp = pose_fk(sk, np.array([0, 0, 1.0]), q)
    p = sk.parents[chain[0]]
    return chain, lim, gr[p], gp[p], sk.offsets[chain], gp


def test_ccd_reaches_a_reachable_goal_within_limits(avatar):
    chain, lim, br, bp, offs, gp = _arm(avatar)
    goal = gp[chain[0]] + np.array([0.3, 0.1, -0.2])
    r = ccd.ccd_solve(br, bp, offs, np.tile([1.0, 0, 0, 0], (4, 1)), 2, np.array([0, 0, -0.26]), goal, lim)
    assert r.status is ccd.Status.CONVERGED and r.error < 1e-4
    assert ccd.limits_hold(r.local_rot, lim).all()


def _skeleton(kind):
    from test_ik_cones import tpose

    if kind == "arms_down":
        return humanoid()
    if kind == "t_pose":
        return tpose(humanoid())
    from conftest import mocap_files

    files = mocap_files("locomotion/cmu_02_01.bvh")
    if not files:
        pytest.skip("shared motion-capture folder not found")
    from kinodyn.io import load

    return load(files[0]).skeleton


@pytest.mark.parametrize("kind", ["arms_down", "t_pose", "cmu"])
def test_limits_and_cones_hold_after_every_solve(kind):
    """Random goals, reachable or not, from random starts: every solve ends inside the hinge range, the
    reach cones and kinodyn.limits (the one specification), on the built-in skeleton, a T-pose one and
    the CMU skeleton (T-pose rest)."""
    avatar = build_avatar(_skeleton(kind))
    rng = np.random.default_rng(0)
    sk = avatar.skeleton
    for chain in avatar.chains:
        lim = ccd.chain_limits(avatar.limits, avatar.cone_axes, avatar.cone_points, chain)
        q0 = quat.identity((sk.num_joints,))
        gr, gp = pose_fk(sk, np.array([0, 0, 1.0]), q0)
        p = sk.parents[chain[0]]
        for _ in range(40):
            start = quat.from_rotvec(rng.normal(0, 0.8, (len(chain), 3)))
            goal = gp[chain[0]] + rng.normal(0, 0.5, 3)
            link = int(rng.integers(0, len(chain)))
            r = ccd.ccd_solve(gr[p], gp[p], sk.offsets[chain], start, link, rng.normal(0, 0.05, 3), goal, lim)
            assert ccd.limits_hold(r.local_rot, lim).all()
            full = np.tile([1.0, 0, 0, 0], (1, sk.num_joints, 1))
            full[0, chain] = r.local_rot
            motion = Motion(sk, np.zeros((1, 3)), full, 60.0)
            assert jl.violations(motion, avatar.limits, tolerance=1e-6).ok


def test_reach_cone_projection_is_inside_and_keeps_inside_points(avatar):
    rng = np.random.default_rng(1)
    _, lim, *_ = _arm(avatar)
    qs = quat.from_rotvec(rng.normal(0, 1.5, (500, 3)))
    for q in qs:
        out = ccd.project_chain(np.tile(q, (4, 1)), lim)
        assert ccd.limits_hold(out, lim).all()
        again = ccd.project_chain(out, lim)
        np.testing.assert_allclose(quat.abs(again), quat.abs(out), atol=1e-6)  # inside stays put


def test_the_shoulder_cone_allows_raising_the_arm_forward_but_not_far_back(avatar):
    _, lim, *_ = _arm(avatar)
    fwd = quat.from_axis_angle([0, -1.0, 0], np.deg2rad(150))  # arm raised forward and up
    back = quat.from_axis_angle([0, 1.0, 0], np.deg2rad(100))  # arm swung far back
    q = np.tile([1.0, 0, 0, 0], (4, 1))
    q[1] = fwd
    assert ccd.limits_hold(q, lim)[1]
    q[1] = back
    assert not ccd.limits_hold(q, lim)[1]
    out = ccd.project_chain(q, lim)
    assert ccd.limits_hold(out, lim)[1]
