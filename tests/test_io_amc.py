"""CMU/Acclaim ASF + AMC reading: a closed-form fixture, ASF discovery, malformed files, and the
consistency check against the cgspeed BVH of CMU trial 01_01."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import mocap_files
from kinodyn.errors import AMCParseError, FileFormatError, ParameterError
from kinodyn.io import load
from kinodyn.io.amc import AsfSkeleton, amc_from_text, find_asf, parse_asf, read_amc, read_asf
from kinodyn.io.bvh import UNIT_SCALES, read_bvh
from kinodyn.kinematics import end_site_positions
from kinodyn.math import quat

_TOL = 1e-9
_CMU_TOL = 2e-5  # metres: the BVH rounds to 4 decimals (0.0001 CMU units = 5.6 um); 5.2 um measured

ASF_SMALL = """# a two-bone chain whose poses are known in closed form
:version 1.10
:name test
:units
  mass 1.0
  length 1.0
  angle deg
:documentation
   free text: begin end :root are not keywords here
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name a
     direction 1 0 0
     length 2
     axis 0 0 90 XYZ
    dof rx ry rz
    limits (-180.0 180.0)
           (-180.0 180.0)
           (-180.0 180.0)
  end
  begin
     id 2
     name b
     direction 0 2 0
     length 1
     axis 0 0 0 XYZ
    dof rz
    limits (-180 180)
  end
:hierarchy
  begin
    root a
    a b
  end
"""

AMC_SMALL = """#!OML:ASF test.asf
:FULLY-SPECIFIED
:DEGREES
1
root 1 2 3 0 0 0
a 0 0 0
b 0
2
root 1 2 3 0 0 0
a 90 0 0
b 90
3
root 1 2 3 0 0 90
a 0 0 0
b 0
"""

# Y-up file coordinates of root, a (= root), b (= a's tip) and b's tip, per frame.
SMALL_EXPECTED = np.array([
    [[1, 2, 3], [1, 2, 3], [3, 2, 3], [3, 3, 3]],
    # a: rx 90 about its local x, which the axis (Rz 90) turns onto world y: (2,0,0) -> (0,0,-2);
    # b: rz 90 turns (0,1,0) to (-1,0,0), then a's turn makes it (0,0,1).
    [[1, 2, 3], [1, 2, 3], [1, 2, 1], [1, 2, 2]],
    # the root turns 90 about z: (2,0,0) -> (0,2,0), (0,1,0) -> (-1,0,0)
    [[1, 2, 3], [1, 2, 3], [1, 4, 3], [0, 4, 3]],
], dtype=float)


def _yup_to_kinodyn(p):
    return np.asarray(p, dtype=float)[..., [2, 0, 1]]


def _all_positions(m):
    gr, gp = m.fk()
    return np.concatenate([gp, end_site_positions(m, gr, gp)], axis=1)


@pytest.fixture
def small_files(tmp_path):
    (tmp_path / "test.asf").write_text(ASF_SMALL)
    (tmp_path / "test_01.amc").write_text(AMC_SMALL)
    return tmp_path / "test_01.amc", tmp_path / "test.asf"


def test_asf_structure():
    asf = parse_asf(ASF_SMALL, "t.asf")
    assert isinstance(asf, AsfSkeleton)
    assert asf.names == ("root", "a", "b")
    np.testing.assert_array_equal(asf.parents, [-1, 0, 1])
    np.testing.assert_allclose(asf.directions[2], [0, 1, 0])  # normalized
    assert asf.dofs == (("tx", "ty", "tz", "rx", "ry", "rz"), ("rx", "ry", "rz"), ("rz",))
    assert asf.limits[1] == ((-180.0, 180.0),) * 3
    assert asf.metres_per_unit == pytest.approx(0.0254)
    sk = asf.skeleton(scale=1.0)
    np.testing.assert_allclose(sk.offsets, _yup_to_kinodyn([[0, 0, 0], [0, 0, 0], [2, 0, 0]]), atol=_TOL)
    np.testing.assert_array_equal(sk.end_parents, [2])
    np.testing.assert_allclose(sk.end_offsets, _yup_to_kinodyn([[0, 1, 0]]), atol=_TOL)


def test_small_chain_closed_form(small_files):
    amc, asf = small_files
    m = read_amc(amc, asf=asf, scale=1.0)
    assert m.num_frames == 3 and m.fps == 120.0 and m.name == "test_01"
    got = _all_positions(m)
    want = _yup_to_kinodyn(SMALL_EXPECTED)
    for f in range(3):
        np.testing.assert_allclose(got[f], want[f], atol=_TOL, err_msg=f"frame {f}")


def test_units_up_axis_and_fps(small_files):
    amc, asf = small_files
    inch = read_amc(amc, asf=asf)  # ASF 'length 1.0': inches
    np.testing.assert_allclose(_all_positions(inch), _yup_to_kinodyn(SMALL_EXPECTED) * 0.0254, atol=_TOL)
    cm = read_amc(amc, asf=asf, scale="cm", fps=30)
    assert cm.fps == 30.0
    np.testing.assert_allclose(_all_positions(cm), _yup_to_kinodyn(SMALL_EXPECTED) * 0.01, atol=_TOL)
    z = read_amc(amc, asf=asf, scale=1.0, up="z")
    np.testing.assert_allclose(_all_positions(z), SMALL_EXPECTED, atol=_TOL)
    text = AMC_SMALL.replace(":DEGREES", ":DEGREES\n:SAMPLES-PER-SECOND 60")
    assert amc_from_text(text, read_asf(asf)).fps == 60.0
    rad = AMC_SMALL.replace(":DEGREES", ":RADIANS").replace("a 90 0 0", f"a {np.pi / 2!r} 0 0") \
        .replace("b 90", f"b {np.pi / 2!r}").replace("0 0 90\n", f"0 0 {np.pi / 2!r}\n")
    np.testing.assert_allclose(_all_positions(amc_from_text(rad, read_asf(asf), scale=1.0)),
                               _yup_to_kinodyn(SMALL_EXPECTED), atol=_TOL)
    with pytest.raises(ParameterError):
        read_amc(amc, asf=asf, scale="furlong")
    with pytest.raises(ParameterError):
        read_amc(amc, asf=asf, up="x")


def test_dof_order_is_extrinsic_as_listed():
    """Documented convention: ``dof rz rx`` applies rz first, then rx (M = Rx Rz)."""
    asf = parse_asf(ASF_SMALL.replace("dof rz\n    limits (-180 180)", "dof rz rx\n    limits (-1 1) (-1 1)"))
    text = AMC_SMALL.replace("b 90", "b 30 40").replace("b 0", "b 0 0")
    m = amc_from_text(text, asf, scale=1.0, up="z")
    want = quat.mul(quat.from_axis_angle([1, 0, 0], np.deg2rad(40)), quat.from_axis_angle([0, 0, 1], np.deg2rad(30)))
    assert quat.angle_between(m.local_rot[1, 2], want) < 1e-12


def test_load_dispatches_amc(small_files):
    amc, asf = small_files
    m = load(amc, scale=1.0)  # finds test.asf beside it (the only ASF there)
    np.testing.assert_allclose(_all_positions(m)[1], _yup_to_kinodyn(SMALL_EXPECTED[1]), atol=_TOL)
    m2 = load(amc, asf=asf, scale="m")
    np.testing.assert_allclose(m2.root_pos, m.root_pos)


def test_fast_and_slow_paths_agree(small_files):
    """Frames listing bones in another order (or with blank lines) go through the grouping reader."""
    _, asf = small_files
    skel = read_asf(asf)
    fast = amc_from_text(AMC_SMALL, skel, scale=1.0)
    shuffled = AMC_SMALL.replace("a 90 0 0\nb 90\n", "b 90\n\na 90 0 0\n")
    slow = amc_from_text(shuffled, skel, scale=1.0)
    np.testing.assert_allclose(_all_positions(slow), _all_positions(fast), atol=0)


# --------------------------------------------------------------------------- finding the ASF


@pytest.mark.parametrize("amc,asfs,want", [
    ("cmu_01_01.amc", ["cmu_01.asf", "cmu_02.asf"], "cmu_01.asf"),
    ("cmu_07_05-walk.amc", ["cmu_07-walk.asf", "cmu_09-run.asf"], "cmu_07-walk.asf"),
    ("cmu_135_06-martialArts.amc", ["cmu_135-martialArts.asf", "cmu_13.asf"], "cmu_135-martialArts.asf"),
    ("01_01.amc", ["01.asf", "02.asf"], "01.asf"),
    ("walk.amc", ["walk.asf", "run.asf"], "walk.asf"),
    ("jump.amc", ["skeleton.asf"], "skeleton.asf"),
    ("cmu_07_05-walk.amc", ["cmu_07.asf", "cmu_07-walk.asf"], "cmu_07-walk.asf"),
    ("cmu_07_05.amc", ["cmu_07-walk.asf", "cmu_17.asf"], "cmu_07-walk.asf"),
])
def test_find_asf(tmp_path, amc, asfs, want):
    (tmp_path / amc).write_text(AMC_SMALL)
    for a in asfs:
        (tmp_path / a).write_text(ASF_SMALL)
    assert find_asf(tmp_path / amc).name == want


@pytest.mark.parametrize("amc,asfs,msg", [
    ("cmu_07_05.amc", ["cmu_07-walk.asf", "cmu_07-run.asf"], "several"),
    ("cmu_07_05.amc", ["cmu_08.asf", "cmu_09.asf"], "no ASF skeleton found"),
    ("walk.amc", [], "no ASF skeleton found"),
])
def test_find_asf_errors(tmp_path, amc, asfs, msg):
    (tmp_path / amc).write_text(AMC_SMALL)
    for a in asfs:
        (tmp_path / a).write_text(ASF_SMALL)
    with pytest.raises(AMCParseError, match=msg) as ei:
        read_amc(tmp_path / amc)
    assert ei.value.path == str(tmp_path / amc)


# --------------------------------------------------------------------------- malformed files

AMC_MALFORMED = {
    "missing-bone": (AMC_SMALL.replace("a 90 0 0\n", ""), 8, "no values for bone 'a'"),
    "unknown-bone": (AMC_SMALL.replace("b 90", "c 90"), 11, "'c' is not animated"),
    "no-dof-bone": (AMC_SMALL.replace("b 90", "root 90"), 11, "twice"),
    "wrong-count": (AMC_SMALL.replace("b 90", "b 90 1"), 11, "needs 1 values, found 2"),
    "text": (AMC_SMALL.replace("a 90 0 0", "a 90 zero 0"), 10, "text 'zero'"),
    "nan": (AMC_SMALL.replace("a 90 0 0", "a nan 0 0"), 10, "non-finite value 'nan'"),
    "huge": (AMC_SMALL.replace("a 90 0 0", "a 1e400 0 0"), 10, "out of range"),
    "gap": (AMC_SMALL.replace("\n3\n", "\n5\n"), 12, "frame 5 follows frame 2"),
    "header-only": (":FULLY-SPECIFIED\n:DEGREES\n", 3, "no frames"),
    "values-first": (AMC_SMALL.replace("1\nroot", "root 0 0 0 0 0 0\n1\nroot"), 4, "expected a frame number"),
    "number-line": (AMC_SMALL.replace("b 90", "90 90"), 11, "expected a bone name"),
    "empty": ("", 1, "no frames"),
}


@pytest.mark.parametrize("name", list(AMC_MALFORMED))
def test_malformed_amc(name, small_files):
    amc, asf = small_files
    text, line, fragment = AMC_MALFORMED[name]
    amc.write_text(text)
    with pytest.raises(AMCParseError) as ei:
        read_amc(amc, asf=asf)
    e = ei.value
    assert isinstance(e, FileFormatError) and e.path == str(amc)
    assert e.line == line and fragment in str(e), str(e)


def test_binary_amc(small_files):
    amc, asf = small_files
    amc.write_bytes(b"1\nroot \x00\x01\x02")
    with pytest.raises(AMCParseError, match="binary") as ei:
        read_amc(amc, asf=asf)
    assert ei.value.line == 2
    amc.write_bytes(b"1\nroot \xff\xfe 1\n")
    with pytest.raises(AMCParseError, match="UTF-8"):
        read_amc(amc, asf=asf)


ASF_MALFORMED = {
    "unknown-in-hierarchy": (ASF_SMALL.replace("    a b\n", "    a c\n"), 39, "unknown bone 'c'"),
    "not-in-hierarchy": (ASF_SMALL.replace("    a b\n", ""), 27, "'b' is not in the hierarchy"),
    "two-parents": (ASF_SMALL.replace("    a b\n", "    a b\n    root b\n"), 40, "two parents"),
    "no-direction": (ASF_SMALL.replace("     direction 0 2 0\n", ""), 27, "has no direction"),
    "axis-order": (ASF_SMALL.replace("axis 0 0 90 XYZ", "axis 0 0 90 XXY"), 21, "permutation of XYZ"),
    "length-text": (ASF_SMALL.replace("length 2\n", "length two\n"), 20, "text 'two'"),
    "length-negative": (ASF_SMALL.replace("length 2\n", "length -2\n"), 20, "negative"),
    "direction-nan": (ASF_SMALL.replace("direction 1 0 0", "direction 1 nan 0"), 19, "non-finite"),
    "dof-translation": (ASF_SMALL.replace("dof rz\n", "dof tx\n"), 33, "not supported"),
    "dof-unknown": (ASF_SMALL.replace("dof rz\n", "dof rw\n"), 33, "unknown dof"),
    "limits-count": (ASF_SMALL.replace("    limits (-180 180)\n", "    limits (-180 180) (0 1)\n"), 33,
                     "1 dofs but 2 limits"),
    "no-end": (ASF_SMALL.replace("    limits (-180 180)\n  end\n", "    limits (-180 180)\n"), 35, "no 'end'"),
    "duplicate-name": (ASF_SMALL.replace("name b", "name a"), 27, "used twice"),
    "no-bonedata": (ASF_SMALL.split(":bonedata")[0], 14, "no :bonedata"),
    "angle-unit": (ASF_SMALL.replace("angle deg", "angle grad"), 7, "'deg' or 'rad'"),
    "empty": ("# nothing\n", 1, "empty"),
}


@pytest.mark.parametrize("name", list(ASF_MALFORMED))
def test_malformed_asf(name, tmp_path):
    text, line, fragment = ASF_MALFORMED[name]
    path = tmp_path / "bad.asf"
    path.write_text(text)
    with pytest.raises(AMCParseError) as ei:
        read_asf(path)
    e = ei.value
    assert e.path == str(path) and e.line == line and fragment in str(e), str(e)


# --------------------------------------------------------------------------- CMU data

# Joints whose parent bone the cgspeed converter collapsed to zero length (thorax, l/r wrist): their
# BVH OFFSET is 0 while the ASF puts them at the tip of the parent bone.
_COLLAPSED = ("lowerneck", "lclavicle", "rclavicle", "lhand", "lthumb", "rhand", "rthumb")


@pytest.mark.mocap
def test_cmu_01_01_amc_matches_bvh(mocap_dir):
    loc = mocap_dir / "locomotion"
    amc = read_amc(loc / "cmu_01_01.amc")
    b = read_bvh(loc / "cmu_01_01.bvh")
    assert b.num_frames == amc.num_frames + 1  # the BVH's added T-pose frame
    b = b[1:]
    assert amc.fps == b.fps == 120.0
    assert amc.skeleton.num_joints == b.skeleton.num_joints == 31
    np.testing.assert_array_equal(amc.skeleton.parents, b.skeleton.parents)
    # units: both in CMU's unit (the BVH's detected), converted to metres
    asf = read_asf(loc / "cmu_01.asf")
    assert asf.length_unit == 0.45 and asf.metres_per_unit == pytest.approx(UNIT_SCALES["cmu"])
    # bone geometry: equal except where the converter collapsed a bone
    diff = np.linalg.norm(amc.skeleton.offsets - b.skeleton.offsets, axis=1)
    collapsed = [amc.skeleton.index(n) for n in _COLLAPSED]
    np.testing.assert_allclose(np.delete(diff, collapsed), 0.0, atol=1e-5)
    np.testing.assert_allclose(b.skeleton.offsets[collapsed], 0.0, atol=1e-12)
    assert (diff[collapsed] > 0.03).all()
    # 1) global positions of every joint on every frame when the AMC motion drives the BVH's bones
    on_bvh = amc.replace(skeleton=amc.skeleton.replace(offsets=b.skeleton.offsets))
    err = np.linalg.norm(on_bvh.global_positions() - b.global_positions(), axis=-1)
    assert err.max() < _CMU_TOL, f"max {err.max():.4f} m at frame/joint {np.unravel_index(err.argmax(), err.shape)}"
    # 2) the joints below the collapsed bones agree directly, with each file's own skeleton
    below = amc.skeleton.subtree(amc.skeleton.index("lowerneck"))
    for n in ("lclavicle", "rclavicle", "lhand", "lthumb", "rhand", "rthumb"):
        below = np.union1d(below, amc.skeleton.subtree(amc.skeleton.index(n)))
    keep = np.setdiff1d(np.arange(31), below)
    assert len(keep) == 14  # root, both legs, lowerback, upperback, thorax
    err = np.linalg.norm(amc.global_positions()[:, keep] - b.global_positions()[:, keep], axis=-1)
    assert err.max() < _CMU_TOL


_ALL_AMC = mocap_files("**/*.amc")


@pytest.mark.mocap
@pytest.mark.parametrize("path", _ALL_AMC or [None], ids=[p.name for p in _ALL_AMC] or ["no-mocap"])
def test_every_shared_amc_loads(path):
    if path is None:
        pytest.skip("shared motion-capture folder not found")
    m = load(path)
    assert m.fps == 120.0 and m.num_joints == 31 and m.num_frames > 100
    gp = m.global_positions()
    assert np.isfinite(gp).all()
    assert 1.1 < np.ptp(gp[0], axis=0).max() < 2.0, path.name
    assert -0.1 < gp[:, :, 2].min() < 0.2, path.name


@pytest.mark.mocap
def test_real_amc_slow_path_agrees(mocap_dir):
    path = mocap_dir / "locomotion" / "cmu_09_06-run.amc"
    asf = read_asf(mocap_dir / "locomotion" / "cmu_09-run.asf")
    text = path.read_text()
    fast = amc_from_text(text, asf)
    lines = text.split("\n")
    k = next(i for i, ln in enumerate(lines) if ln.strip() == "2")
    lines[k + 1], lines[k + 2] = lines[k + 2], lines[k + 1]  # swap two bone lines in frame 2
    slow = amc_from_text("\n".join(lines), asf)
    np.testing.assert_array_equal(slow.local_rot, fast.local_rot)
