"""Joint limits: kinds from names, hinge axes from rest geometry, violations and clamping."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn import limits
from kinodyn.errors import ParameterError
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

_TOL = 1e-9
_DEG = np.pi / 180


def _leg_arm_skeleton() -> Skeleton:
    names = ("Hips", "LeftUpLeg", "LeftLeg", "LeftFoot", "Spine", "LeftShoulder", "LeftArm", "LeftForeArm",
             "LeftHand")
    parents = np.array([-1, 0, 1, 2, 0, 4, 5, 6, 7])
    offsets = np.array([[0, 0, 0], [0, 0.1, -0.05], [0, 0, -0.45], [0, 0, -0.42], [0, 0, 0.3], [0, 0.05, 0.2],
                        [0, 0.15, 0], [0, 0.3, 0], [0, 0.25, 0]], dtype=float)
    return Skeleton(names, parents, offsets, np.array([3, 8]), np.array([[0.15, 0, -0.05], [0, 0.1, 0]]))


def test_kinds_from_cmu_and_3dsmax_names():
    sk = _leg_arm_skeleton()
    kinds = [lim.name for lim in limits.limits_for(sk)]
    assert kinds == ["root", "thigh", "knee", "ankle", "spine", "shoulder", "upper_arm", "forearm", "wrist"]
    # 3ds Max names its clavicle "Collar" and its upper arm "Shoulder".
    sk2 = Skeleton(("Hips", "Chest", "LeftCollar", "LeftShoulder", "LeftElbow"), np.array([-1, 0, 1, 2, 3]),
                   np.array([[0, 0, 0], [0, 0, .3], [0, .05, .2], [0, .15, 0], [0, .3, 0]], dtype=float))
    assert [lim.name for lim in limits.limits_for(sk2)] == ["root", "spine", "clavicle", "upper_arm", "forearm"]


def test_hinge_axes_flex_the_right_way():
    sk = _leg_arm_skeleton()
    lim = limits.limits_for(sk)
    knee, elbow = lim[2], lim[7]
    # A positive knee angle moves the foot backward (-X); a positive elbow angle moves the hand forward.
    foot = quat.mul_vec(quat.from_axis_angle(knee.axis, 30 * _DEG), sk.offsets[3])
    hand = quat.mul_vec(quat.from_axis_angle(elbow.axis, 30 * _DEG), sk.offsets[8])
    assert foot[0] < -0.1
    assert hand[0] > 0.05


def _motion(sk: Skeleton, rot: np.ndarray) -> Motion:
    return Motion(sk, np.zeros((len(rot), 3)), rot, 30.0)


def test_violations_and_clamp():
    sk = _leg_arm_skeleton()
    lim = limits.limits_for(sk)
    rot = quat.identity((3, sk.num_joints))
    rot[1, 2] = quat.from_axis_angle(lim[2].axis, -40 * _DEG)  # knee hyper-extended by 30 deg
    rot[2, 3] = quat.from_axis_angle([1, 0, 0], 80 * _DEG)  # ankle 20 deg past its 60 deg cone
    rep = limits.violations(_motion(sk, rot))
    assert not rep.ok
    np.testing.assert_allclose(np.rad2deg(rep.excess[2]), 30.0, atol=1e-6)
    np.testing.assert_allclose(np.rad2deg(rep.excess[3]), 20.0, atol=1e-6)
    assert rep.worst_joint == "LeftLeg" and rep.worst_frame == 1
    clamped = limits.clamp(rot, lim)
    assert limits.violations(_motion(sk, clamped)).ok
    np.testing.assert_allclose(quat.angle(clamped[2, 3]), 60 * _DEG, atol=_TOL)
    # Rotations already inside the limits are left alone.
    np.testing.assert_allclose(quat.angle_between(clamped[0], rot[0]), 0.0, atol=_TOL)


def test_identity_pose_is_inside_limits():
    sk = _leg_arm_skeleton()
    assert limits.violations(_motion(sk, quat.identity((2, sk.num_joints)))).ok


def test_bad_limits_rejected():
    with pytest.raises(ParameterError, match="lower <= upper"):
        limits.JointLimit("hinge", lower=1.0, upper=0.0)
    with pytest.raises(ParameterError, match="joint kind"):
        limits.JointLimit("slider")
    sk = _leg_arm_skeleton()
    with pytest.raises(ParameterError, match="one limit per joint"):
        limits.violations(_motion(sk, quat.identity((1, sk.num_joints))), limits.limits_for(sk)[:3])
