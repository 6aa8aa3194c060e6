"""kinodyn.roles: joint roles and sides from joint names, in one table."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn import limits, roles
from kinodyn.data.skeleton import humanoid
from kinodyn.errors import UnknownNameError


@pytest.mark.parametrize("name, side", [
    ("LeftFoot", "left"), ("RightToeBase", "right"), ("lfoot", "left"), ("rtoes", "right"), ("l_ankle", "left"),
    ("ankle_R", "right"), ("LHeel", "left"), ("Hips", None), ("lowerback", None), ("Spine1", None),
])
def test_side_of_reads_the_markers_each_convention_uses(name, side):
    assert roles.side_of(name) == side


@pytest.mark.parametrize("name, other", [
    ("LeftArm", "RightArm"), ("rfemur", "lfemur"), ("l_wrist", "r_wrist"), ("Hand_L", "Hand_R"),
    ("lthumb", "rthumb"), ("Head", "Head"), ("mixamorigLeftFoot", "mixamorigRightFoot"),
])
def test_mirror_name_swaps_sides_both_ways(name, other):
    assert roles.mirror_name(name) == other
    assert roles.mirror_name(other) == name


def test_feet_and_their_points_on_the_humanoid():
    sk = humanoid()
    feet = roles.feet(sk)
    assert [sk.names[j] for j in feet["left"]] == ["LeftFoot", "LeftToeBase"]
    assert [sk.names[j] for j in feet["right"]] == ["RightFoot", "RightToeBase"]
    ends = roles.end_sites_of(sk, feet["left"])
    assert [sk.names[sk.end_parents[e]] for e in ends] == ["LeftToeBase"]
    pts = roles.foot_point_indices(sk, {s: np.array(v) for s, v in feet.items()})
    assert pts["left"].tolist() == feet["left"] + [sk.num_joints + int(ends[0])]


def test_joint_types_of_limits_are_the_role_patterns():
    assert [p for _, p, _, _ in limits.JOINT_TYPES] == [roles.ROLES[n] for n, _, _, _ in limits.JOINT_TYPES]
    sk = humanoid()
    kinds = {sk.names[j]: limits.joint_kind(sk, j)[0] for j in range(1, sk.num_joints)}
    assert kinds["LeftLeg"] == "knee" and kinds["LeftForeArm"] == "forearm" and kinds["LeftToeBase"] == "toe"


def test_roles_match_by_name_case_insensitively():
    assert roles.has_role("RightHandIndex1", "finger") and roles.has_role("lhand", "finger")
    assert not roles.has_role("RightHand", "finger") and roles.has_role("RightHand", "wrist")
    assert roles.has_role("Head_End", "end_site") and roles.has_role("LeftToe_Nub", "end_site")
    assert roles.joints_with_role(humanoid(), "head") == [4]
    with pytest.raises(UnknownNameError, match="unknown joint role 'tail'"):
        roles.pattern("tail")


def test_bone_roles_name_the_bone_that_ends_at_a_point():
    assert roles.bone_role("Head_end") == "head" and roles.bone_role("Head") == "neck"
    assert roles.bone_role("LeftLeg") == "thigh" and roles.bone_role("LeftUpLeg") == "pelvis"
    assert roles.bone_role("LeftToeBase_end") == "toe" and roles.bone_role("LeftHand_end") == "hand"
    assert roles.bone_role("Tail") is None
