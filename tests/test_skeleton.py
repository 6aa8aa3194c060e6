"""kinodyn.skeleton: validation with exact messages, name lookup, mirroring, subtrees and rest geometry."""

from __future__ import annotations

import re
from dataclasses import FrozenInstanceError

import numpy as np
import pytest
from numpy.testing import assert_allclose

from conftest import mocap_files
from kinodyn.errors import SkeletonError, UnknownNameError
from kinodyn.skeleton import Skeleton, mirror_name

_TOL = 1e-12

# The cgspeed MotionBuilder-friendly CMU BVH skeleton (names and hierarchy as in ../shared/mocap/MANIFEST.md).
CMU_BVH = (
    ("Hips", -1),
    ("LHipJoint", 0),
    ("LeftUpLeg", 1),
    ("LeftLeg", 2),
    ("LeftFoot", 3),
    ("LeftToeBase", 4),
    ("RHipJoint", 0),
    ("RightUpLeg", 6),
    ("RightLeg", 7),
    ("RightFoot", 8),
    ("RightToeBase", 9),
    ("LowerBack", 0),
    ("Spine", 11),
    ("Spine1", 12),
    ("Neck", 13),
    ("Neck1", 14),
    ("Head", 15),
    ("LeftShoulder", 13),
    ("LeftArm", 17),
    ("LeftForeArm", 18),
    ("LeftHand", 19),
    ("LeftFingerBase", 20),
    ("LeftHandIndex1", 21),
    ("LThumb", 20),
    ("RightShoulder", 13),
    ("RightArm", 24),
    ("RightForeArm", 25),
    ("RightHand", 26),
    ("RightFingerBase", 27),
    ("RightHandIndex1", 28),
    ("RThumb", 27),
)
# The CMU ASF bone names, same topology.
CMU_ASF = (
    "root",
    "lhipjoint",
    "lfemur",
    "ltibia",
    "lfoot",
    "ltoes",
    "rhipjoint",
    "rfemur",
    "rtibia",
    "rfoot",
    "rtoes",
    "lowerback",
    "upperback",
    "thorax",
    "lowerneck",
    "upperneck",
    "head",
    "lclavicle",
    "lhumerus",
    "lradius",
    "lwrist",
    "lhand",
    "lfingers",
    "lthumb",
    "rclavicle",
    "rhumerus",
    "rradius",
    "rwrist",
    "rhand",
    "rfingers",
    "rthumb",
)


def cmu_skeleton(names=None) -> Skeleton:
    """A CMU-shaped skeleton with symmetric offsets (left = +Y, Z up)."""
    names = names or tuple(n for n, _ in CMU_BVH)
    parents = np.array([p for _, p in CMU_BVH])
    offsets = np.zeros((len(parents), 3))
    rng = np.random.default_rng(7)
    for j, n in enumerate(CMU_BVH):
        offsets[j] = rng.normal(size=3) * 0.1
    # make the two sides mirror images: right joints copy their left twin with y negated
    base = Skeleton(names, parents, offsets)
    m = base.mirror_map()
    for j in range(len(parents)):
        if m[j] > j:  # j is the first of a pair
            offsets[m[j]] = offsets[j] * [1.0, -1.0, 1.0]
        elif m[j] == j:
            offsets[j, 1] = 0.0
    return Skeleton(
        names,
        parents,
        offsets,
        end_parents=np.array([5, 10, 16]),
        end_offsets=np.array([[0.05, 0.0, 0.0], [0.05, 0.0, 0.0], [0.0, 0.0, 0.1]]),
    )


def chain(n=4) -> Skeleton:
    return Skeleton(tuple(f"j{i}" for i in range(n)), np.arange(n) - 1, np.tile([0.0, 0.0, 1.0], (n, 1)))


# --------------------------------------------------------------------------- validation


def _raises(msg, **kw):
    base = dict(names=("a", "b", "c"), parents=np.array([-1, 0, 1]), offsets=np.zeros((3, 3)))
    base.update(kw)
    with pytest.raises(SkeletonError, match="^" + re.escape(msg) + "$"):
        Skeleton(**base)


def test_valid_skeleton_is_read_only_and_frozen():
    sk = cmu_skeleton()
    assert sk.num_joints == len(sk) == 31
    assert sk.parents.dtype == np.int64 and sk.offsets.dtype == np.float64
    for arr in (sk.parents, sk.offsets, sk.end_parents, sk.end_offsets):
        with pytest.raises(ValueError):
            arr[0] = 0
    with pytest.raises(FrozenInstanceError):
        sk.names = ("x",)  # type: ignore[misc]
    offsets = np.zeros((3, 3))
    sk2 = Skeleton(("a", "b", "c"), [-1, 0, 1], offsets)
    offsets[1] = 5.0
    assert_allclose(sk2.offsets, 0.0, err_msg="the skeleton copied its input")
    assert isinstance(sk2.names, tuple) and sk2.end_offsets.shape == (0, 3)


def test_validation_messages():
    _raises(
        "a skeleton needs at least one joint, got 0",
        names=(),
        parents=np.zeros(0, int),
        offsets=np.zeros((0, 3)),
    )
    _raises(
        "joint names must be unique, repeated: a, b",
        names=("a", "b", "a", "b"),
        parents=np.array([-1, 0, 1, 2]),
        offsets=np.zeros((4, 3)),
    )
    _raises("parents must be an int array of shape (3,), got int64 (2,)", parents=np.array([-1, 0]))
    _raises(
        "parents must be an int array of shape (3,), got float64 (3,)", parents=np.array([-1.0, 0.0, 1.0])
    )
    _raises("offsets must have shape (3, 3), got (3, 2)", offsets=np.zeros((3, 2)))
    _raises("offsets must have shape (3, 3), got (9,)", offsets=np.zeros(9))
    _raises(
        "offsets must be finite, found NaN or inf", offsets=np.array([[0, 0, 0], [0, np.nan, 0], [0, 0, 0.0]])
    )
    _raises(
        "offsets must be finite, found NaN or inf", offsets=np.array([[0, 0, 0], [0, 0, 0], [np.inf, 0, 0.0]])
    )
    _raises("parents[0] must be -1 (the root), got 0", parents=np.array([0, 0, 1]))
    _raises(
        "parents[j] must satisfy 0 <= parents[j] < j for j > 0; joint 1 ('b') has 2",
        parents=np.array([-1, 2, 0]),
    )
    _raises(
        "parents[j] must satisfy 0 <= parents[j] < j for j > 0; joint 2 ('c') has 2",
        parents=np.array([-1, 0, 2]),
    )
    _raises(
        "parents[j] must satisfy 0 <= parents[j] < j for j > 0; joint 2 ('c') has -1",
        parents=np.array([-1, 0, -1]),
    )
    _raises("end_parents must index joints 0..2", end_parents=np.array([3]), end_offsets=np.zeros((1, 3)))
    _raises(
        "end_parents must be an int array of shape (2,), got int64 (1,)",
        end_parents=np.array([1]),
        end_offsets=np.zeros((2, 3)),
    )


def test_end_site_validation():
    """Regression: end_offsets of a wrong shape were silently reshaped (or failed inside numpy), and NaN
    end offsets were accepted."""
    _raises(
        "end_offsets must have shape (E, 3), got (2, 2)",
        end_parents=np.array([1, 2]),
        end_offsets=np.zeros((2, 2)),
    )
    _raises(
        "end_offsets must have shape (E, 3), got (3,)", end_parents=np.array([1]), end_offsets=np.zeros(3)
    )
    _raises(
        "end_offsets must be finite, found NaN or inf",
        end_parents=np.array([1]),
        end_offsets=np.array([[0.0, np.nan, 0.0]]),
    )
    sk = Skeleton(("a", "b"), [-1, 0], np.zeros((2, 3)), end_parents=[], end_offsets=[])
    assert sk.end_parents.shape == (0,) and sk.end_offsets.shape == (0, 3)


def test_errors_are_value_errors():
    assert issubclass(SkeletonError, ValueError)
    with pytest.raises(ValueError):
        Skeleton(("a",), [0], np.zeros((1, 3)))


# --------------------------------------------------------------------------- lookup and structure


def test_index_find_children_subtree():
    sk = cmu_skeleton()
    assert sk.index("LeftFoot") == 4
    assert_allclose(sk.indices(["Hips", "Head"]), [0, 16])
    msg = "no joint named 'LeftFooot'; joints are: " + ", ".join(sk.names)
    with pytest.raises(UnknownNameError, match="^" + re.escape(msg) + "$"):
        sk.index("LeftFooot")
    with pytest.raises(KeyError):  # UnknownNameError is also a KeyError
        sk.index("nope")
    assert sk.find("foot") == [4, 9]
    assert sk.find("^left", "thumb") == [2, 3, 4, 5, 17, 18, 19, 20, 21, 22, 23, 30]
    assert sk.children(13).tolist() == [14, 17, 24]
    assert sk.subtree(17).tolist() == [17, 18, 19, 20, 21, 22, 23]
    assert sk.subtree(6).tolist() == [6, 7, 8, 9, 10]
    assert sk.subtree(0).tolist() == list(range(31))
    assert sk.subtree(30).tolist() == [30]
    assert sk.subtree(11).tolist() == list(range(11, 31))


def test_subtree_matches_ancestor_walk():
    sk = cmu_skeleton()
    for j in range(sk.num_joints):
        want = []
        for k in range(sk.num_joints):
            a = k
            while a != -1 and a != j:
                a = sk.parents[a]
            if a == j:
                want.append(k)
        assert sk.subtree(j).tolist() == want, sk.names[j]


def test_rest_positions_bone_lengths_height():
    sk = chain(4).replace(
        offsets=np.array([[9.0, 9.0, 9.0], [0.0, 0.0, 1.0], [0.0, 2.0, 0.0], [3.0, 0.0, 0.0]])
    )
    assert_allclose(
        sk.rest_positions(), [[0, 0, 0], [0, 0, 1], [0, 2, 1], [3, 2, 1]], err_msg="root at origin"
    )
    assert_allclose(sk.bone_lengths(), [0.0, 1.0, 2.0, 3.0], err_msg="root bone is 0")
    assert sk.height() == pytest.approx(1.0)
    with_end = sk.replace(end_parents=np.array([3]), end_offsets=np.array([[0.0, 0.0, 0.5]]))
    assert with_end.height() == pytest.approx(1.5), "end sites count"
    cmu = cmu_skeleton()
    pos = cmu.rest_positions()
    for j in range(1, cmu.num_joints):
        assert_allclose(pos[j], pos[cmu.parents[j]] + cmu.offsets[j], atol=_TOL)


def test_scaled_replace_and_equality():
    sk = cmu_skeleton()
    s2 = sk.scaled(0.01)
    assert_allclose(s2.offsets, sk.offsets * 0.01)
    assert_allclose(s2.end_offsets, sk.end_offsets * 0.01)
    assert_allclose(s2.rest_positions(), sk.rest_positions() * 0.01, atol=_TOL)
    assert s2.same_topology(sk) and s2 != sk
    assert sk.replace() == sk and sk.replace() is not sk
    assert sk != chain(4) and not sk.same_topology(chain(4))
    assert "31 joints" in repr(sk) and "'Hips'" in repr(sk)


# --------------------------------------------------------------------------- mirroring


@pytest.mark.parametrize(
    "name, other",
    [
        ("LeftArm", "RightArm"),
        ("RightArm", "LeftArm"),
        ("LeftUpLeg", "RightUpLeg"),
        ("LHipJoint", "RHipJoint"),
        ("LThumb", "RThumb"),
        ("RightHandIndex1", "LeftHandIndex1"),
        ("lfemur", "rfemur"),
        ("rtibia", "ltibia"),
        ("lhumerus", "rhumerus"),
        ("rclavicle", "lclavicle"),
        ("lhipjoint", "rhipjoint"),
        ("l_ankle", "r_ankle"),
        ("r_knee", "l_knee"),
        ("foot_l", "foot_r"),
        ("Hand_R", "Hand_L"),
        ("leftfoot", "rightfoot"),
        ("HipLeft", "HipRight"),
        ("Hips", "Hips"),
        ("LowerBack", "LowerBack"),
        ("lowerback", "lowerback"),
        ("Leg", "Leg"),
        ("root", "root"),
        ("Spine1", "Spine1"),
        ("head", "head"),
        ("Ribs", "Ribs"),
    ],
)
def test_mirror_name(name, other):
    assert mirror_name(name) == other
    assert mirror_name(mirror_name(name)) == name


@pytest.mark.parametrize("names", [tuple(n for n, _ in CMU_BVH), CMU_ASF], ids=["bvh", "asf"])
def test_mirror_map_on_cmu_names(names):
    sk = cmu_skeleton(names)
    m = sk.mirror_map()
    assert_allclose(m[m], np.arange(31), err_msg="an involution")
    pairs = {(names[i], names[m[i]]) for i in range(31) if m[i] != i}
    assert len(pairs) == 2 * 12, "12 left/right pairs"
    midline = [names[i] for i in range(31) if m[i] == i]
    assert midline == [names[i] for i in (0, 11, 12, 13, 14, 15, 16)]
    assert names[m[names.index(names[2])]] == names[7], "left femur <-> right femur"


def test_mirror_map_with_underscore_names_and_missing_partner():
    names = ("pelvis", "l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle", "l_extra")
    sk = Skeleton(names, np.array([-1, 0, 1, 2, 0, 4, 5, 0]), np.zeros((8, 3)))
    assert sk.mirror_map().tolist() == [0, 4, 5, 6, 1, 2, 3, 7]


def test_mirrored_skeleton():
    sym = cmu_skeleton()
    assert sym.mirrored() is sym, "a symmetric skeleton mirrors to itself"
    offs = np.array(sym.offsets)
    offs[2] += [0.0, 0.05, 0.0]  # a longer left hip
    asym = sym.replace(offsets=offs)
    mir = asym.mirrored()
    assert mir is not asym
    m = asym.mirror_map()
    assert_allclose(mir.offsets, asym.offsets[m] * [1.0, -1.0, 1.0], atol=_TOL, err_msg="offsets swap sides")
    assert mir.mirrored() == asym, "mirrored twice"
    assert_allclose(
        mir.rest_positions(),
        (asym.rest_positions() * [1.0, -1.0, 1.0])[m],
        atol=_TOL,
        err_msg="rest pose reflected",
    )
    assert sorted(mir.end_parents.tolist()) == sorted(m[asym.end_parents].tolist())


@pytest.mark.mocap
@pytest.mark.parametrize("pattern", ["locomotion/cmu_02_01.bvh", "locomotion/cmu3dsmax_131_01.bvh"])
def test_mirror_map_of_real_cmu_files(pattern):
    files = mocap_files(pattern)
    if not files:
        pytest.skip(f"../shared/mocap/{pattern} not found")
    import kinodyn

    sk = kinodyn.load(files[0])[:2].skeleton
    m = sk.mirror_map()
    assert_allclose(m[m], np.arange(sk.num_joints), err_msg="an involution")
    assert np.sum(m != np.arange(sk.num_joints)) == 24, "12 left/right pairs"
    for i, j in enumerate(m):
        assert sk.parents[j] == m[sk.parents[i]] or sk.parents[i] < 0, "mirrored joints have mirrored parents"
        if j != i:
            # the two sides of a real subject differ by millimetres to a few centimetres, never in sign
            assert sk.offsets[i, 1] * sk.offsets[j, 1] <= 1e-12, (sk.names[i], sk.names[j])
