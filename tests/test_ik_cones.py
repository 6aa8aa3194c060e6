"""Reach cones are anatomical: an arms-down and a T-pose skeleton meet the same cone for the same arm
direction, and every cone lies within its joint's range from the rest pose."""

import numpy as np
import pytest

from kinodyn import limits as jl
from kinodyn.ik import cones
from kinodyn.math import quat
from kinodyn.skeleton import Skeleton


def _humanoid():
    from kinodyn.data.skeleton import humanoid

    return humanoid()


def tpose(sk: Skeleton) -> Skeleton:
    """``sk`` (arms hanging) with the arms stretched sideways: the forearm, hand and hand end offsets
    turned from down to out (+Y on the left)."""
    off, end = sk.offsets.copy(), sk.end_offsets.copy()
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        for name in (f"{side}ForeArm", f"{side}Hand"):
            j = sk.index(name)
            off[j] = [0.0, sign * np.linalg.norm(off[j]), 0.0]
        for e in np.nonzero(sk.end_parents == sk.index(f"{side}Hand"))[0]:
            end[e] = [0.0, sign * np.linalg.norm(end[e]), 0.0]
    return Skeleton(sk.names, sk.parents, off, sk.end_parents, end)


def _cones(sk):
    lims = jl.limits_for(sk)
    return lims, *cones.reach_cones(sk, lims)


@pytest.mark.parametrize("side", ["Left", "Right"])
def test_the_same_arm_direction_meets_the_same_cone_on_both_rest_poses(side, rng):
    down, t = _humanoid(), tpose(_humanoid())
    (_, ax_d, pt_d), (_, ax_t, pt_t) = _cones(down), _cones(t)
    j = down.index(f"{side}Arm")
    d_down, d_t = jl.bone_direction(down, j), jl.bone_direction(t, j)
    assert d_down @ d_t < 1e-9  # the rest directions are 90 degrees apart
    inside = 0
    for w in rng.normal(size=(400, 3)):
        w /= np.linalg.norm(w)
        a = cones.cone_contains(quat.between(d_down, w), ax_d[j], pt_d[j])
        b = cones.cone_contains(quat.between(d_t, w), ax_t[j], pt_t[j])
        assert a == b, w
        inside += a
    assert 100 < inside < 400  # the cone is neither empty nor everything


def test_anatomical_directions_of_a_t_pose_arm():
    """Raised forward and up is inside, swung far back is not, hanging down is inside, and across the
    chest (the other side) is not: the same verdicts the arms-down skeleton gives."""
    sk = tpose(_humanoid())
    _, axes, pts = _cones(sk)
    j = sk.index("LeftArm")
    d0 = jl.bone_direction(sk, j)
    dirs = {"forward_up": ([np.cos(np.deg2rad(60)), 0.0, np.sin(np.deg2rad(60))], True),
            "down": ([0.0, 0.0, -1.0], True), "out": ([0.0, 1.0, 0.0], True),
            "far_back": ([-np.cos(np.deg2rad(10)), 0.0, -np.sin(np.deg2rad(10))], False),
            "across": ([0.0, -1.0, 0.0], False)}
    for name, (w, ok) in dirs.items():
        assert bool(cones.cone_contains(quat.between(d0, np.array(w)), axes[j], pts[j])) == ok, name


@pytest.mark.parametrize("make", [_humanoid, lambda: tpose(_humanoid())], ids=["arms_down", "t_pose"])
def test_every_cone_vertex_is_within_the_joint_range_of_the_rest_direction(make):
    sk = make()
    lims, axes, pts = _cones(sk)
    for j, lim in enumerate(lims):
        if lim.kind != "ball":
            continue
        d0, c, ex, ey = axes[j]
        r = np.linalg.norm(pts[j], axis=1)
        az = np.arctan2(pts[j][:, 1], pts[j][:, 0])
        side = np.cos(az)[:, None] * ex + np.sin(az)[:, None] * ey
        v = np.cos(r)[:, None] * c + np.sin(r)[:, None] * side
        assert np.arccos(np.clip(v @ d0, -1, 1)).max() <= lim.max_angle, sk.names[j]
