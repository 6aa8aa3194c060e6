"""BVH reading and writing: closed-form fixtures, an independent FK oracle, round trips, real files,
malformed files and a third-party reader."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import mocap_files
from kinodyn.errors import BVHParseError, FileFormatError, ParameterError
from kinodyn.io import bvh
from kinodyn.io.bvh import (
    UNIT_SCALES,
    bvh_from_bytes,
    detect_scale,
    parse_bvh,
    read_bvh,
    to_bvh_text,
    write_bvh,
)
from kinodyn.io.tpose import has_added_tpose
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

_TOL = 1e-9  # closed-form fixtures (exact arithmetic up to rounding)
_RT_TOL = 1e-6  # write -> read, metres (the bound)


def _yup_to_kinodyn(p):
    """File Y-up coordinates (x, y, z) -> kinodyn Z-up (z, x, y)."""
    p = np.asarray(p, dtype=float)
    return p[..., [2, 0, 1]]


# --------------------------------------------------------------------------- closed-form fixtures

# Hips -> Chest -> Neck (+ end site), centimetres, Y up, ZXY channels (as the SNU files).
CHAIN = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT Chest
\t{
\t\tOFFSET 0 10 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tJOINT Neck
\t\t{
\t\t\tOFFSET 0 10 0
\t\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\t\tEnd Site
\t\t\t{
\t\t\t\tOFFSET 0 5 0
\t\t\t}
\t\t}
\t}
}
MOTION
Frames: 4
Frame Time: 0.0333333
100 90 -50 0 0 0 0 0 0 0 0 0
100 90 -50 90 0 0 0 0 0 0 0 0
100 90 -50 0 0 0 0 90 0 0 0 0
100 90 -50 90 90 0 0 0 0 0 0 0
"""

# Expected file-frame (Y-up, cm) positions of Hips, Chest, Neck, end site for each frame.
CHAIN_EXPECTED = np.array([
    [[100, 90, -50], [100, 100, -50], [100, 110, -50], [100, 115, -50]],  # rest
    [[100, 90, -50], [90, 90, -50], [80, 90, -50], [75, 90, -50]],  # root Rz(90): +y -> -x
    [[100, 90, -50], [100, 100, -50], [100, 100, -40], [100, 100, -35]],  # chest Rx(90): +y -> +z
    [[100, 90, -50], [100, 90, -40], [100, 90, -30], [100, 90, -25]],  # root Rz(90) Rx(90): +y -> +z
], dtype=float)


def _positions_with_end(m: Motion) -> np.ndarray:
    from kinodyn.kinematics import end_site_positions

    gr, gp = m.fk()
    return np.concatenate([gp, end_site_positions(m, gr, gp)], axis=1)


def test_chain_closed_form():
    """Root translation, a root turn, a child bend and the ZXY order, each with exact positions."""
    m = bvh_from_bytes(CHAIN.encode(), "chain.bvh", scale="cm")
    assert m.skeleton.names == ("Hips", "Chest", "Neck")
    assert m.fps == pytest.approx(30.0, abs=1e-9)  # .0333333 snaps to 1/30 s
    got = _positions_with_end(m)
    want = _yup_to_kinodyn(CHAIN_EXPECTED) * 0.01
    for f in range(4):
        np.testing.assert_allclose(got[f], want[f], atol=_TOL, err_msg=f"frame {f}")


def test_chain_z_up_file_is_not_turned():
    m = bvh_from_bytes(CHAIN.encode(), "chain.bvh", scale=1.0, up="z")
    np.testing.assert_allclose(m.global_positions()[1], CHAIN_EXPECTED[1, :3], atol=_TOL)


def test_unit_detection():
    for unit, s in UNIT_SCALES.items():
        assert detect_scale(1.7 / s) == (unit, s)
    # The chain is 25 units tall: as centimetres it is tiny, but the explicit scale always wins.
    m = bvh_from_bytes(CHAIN.encode(), "chain.bvh", scale=0.02)
    assert m.skeleton.offsets[1] == pytest.approx(_yup_to_kinodyn([0, 0.2, 0]))


@pytest.mark.parametrize("variant", ["crlf", "trailing-space", "blank-lines", "bom", "cr-only", "tabs-lower"])
def test_text_variants_read_the_same(variant):
    text = CHAIN
    if variant == "crlf":
        text = text.replace("\n", "\r\n")
    elif variant == "trailing-space":
        text = text.replace("\n", " \t \n")
    elif variant == "blank-lines":
        text = text.replace("MOTION\n", "\n\nMOTION\n\n").replace("0.0333333\n", "0.0333333\n\n") + "\n\n  \n"
    elif variant == "bom":
        text = "\ufeff" + text
    elif variant == "cr-only":
        text = text.replace("\n", "\r")
    elif variant == "tabs-lower":
        text = text.replace("End Site", "End site").replace("Zrotation", "zROTATION").replace("OFFSET", "offset")
    a = bvh_from_bytes(CHAIN.encode(), "a.bvh", scale="cm")
    b = bvh_from_bytes(text.encode(), "b.bvh", scale="cm")
    np.testing.assert_allclose(b.global_positions(), a.global_positions(), atol=_TOL, err_msg=variant)


def test_six_channels_on_every_joint():
    """Non-root position channels become animated translations (and equal offsets are dropped)."""
    text = CHAIN.replace("CHANNELS 3 Zrotation Xrotation Yrotation",
                         "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation")
    lines = text.split("\n")
    i = lines.index("MOTION")
    rows = ["100 90 -50 0 0 0 0 10 0 0 0 0 0 10 0 0 0 0",  # positions equal to the offsets
            "100 90 -50 0 0 0 0 20 0 0 0 0 0 10 0 0 0 0"]  # chest moved up 10 more
    data = "\n".join(lines[:i] + ["MOTION", "Frames: 2", "Frame Time: 0.01"] + rows) + "\n"
    m = bvh_from_bytes(data.encode(), "six.bvh", scale="cm")
    assert m.translations is not None
    gp = m.global_positions()
    np.testing.assert_allclose(gp[0, 2], _yup_to_kinodyn([100, 110, -50]) * 0.01, atol=_TOL)
    np.testing.assert_allclose(gp[1, 2], _yup_to_kinodyn([100, 120, -50]) * 0.01, atol=_TOL)
    same = data.replace("0 20 0 0 0 0 0 10", "0 10 0 0 0 0 0 10")
    assert bvh_from_bytes(same.encode(), "six.bvh", scale="cm").translations is None


def test_position_only_and_rotation_only_root():
    text = CHAIN.replace("CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
                         "CHANNELS 3 Zrotation Xrotation Yrotation")
    lines = text.split("\n")
    i = lines.index("MOTION")
    data = "\n".join(lines[:i] + ["MOTION", "Frames: 1", "Frame Time: 0.01", "90 0 0 0 0 0 0 0 0"]) + "\n"
    m = bvh_from_bytes(data.encode(), "rot.bvh", scale="cm")
    np.testing.assert_allclose(m.root_pos[0], 0.0, atol=_TOL)  # root at its OFFSET (0)
    np.testing.assert_allclose(m.global_positions()[0, 1], _yup_to_kinodyn([-10, 0, 0]) * 0.01, atol=_TOL)


# --------------------------------------------------------------------------- an independent oracle


def _oracle_positions(d: bvh.BVHData, frames) -> np.ndarray:
    """Joint positions in file axes and units, by a plain loop with scipy rotations (no kinodyn math)."""
    out = np.zeros((len(frames), len(d.names), 3))
    col0 = np.cumsum([0] + [len(c) for c in d.channels])
    for fi, f in enumerate(frames):
        rots = []
        for j, chans in enumerate(d.channels):
            vals = d.values[f, col0[j]:col0[j + 1]]
            rot_axes = "".join(c[0].upper() for c in chans if c.endswith("rotation"))
            rot_vals = [v for c, v in zip(chans, vals) if c.endswith("rotation")]
            pos = {c[0].lower(): v for c, v in zip(chans, vals) if c.endswith("position")}
            r = Rotation.from_euler(rot_axes, rot_vals, degrees=True) if rot_axes else Rotation.identity()
            local = np.array([pos["x"], pos["y"], pos["z"]]) if pos else d.offsets[j]
            p = d.parents[j]
            if p < 0:
                rots.append(r)
                out[fi, j] = local if pos else d.offsets[j]
            else:
                rots.append(rots[p] * r)
                out[fi, j] = out[fi, p] + rots[p].apply(local)
    return out


@pytest.mark.mocap
@pytest.mark.parametrize("pattern", ["**/snu-retarget_69_01_1.bvh", "**/cmu_02_01.bvh", "**/cmu3dsmax_131_01.bvh"])
def test_real_files_match_scipy_oracle(pattern, mocap_dir):
    """ZXY (SNU) and ZYX (CMU) channel orders against an independent scipy forward kinematics."""
    path = mocap_files(pattern)[0]
    d = parse_bvh(path.read_bytes(), path)
    m = read_bvh(path)
    s = UNIT_SCALES["cm"] if path.name.startswith("snu") else UNIT_SCALES["cmu"]
    frames = np.linspace(0, len(d.values) - 1, 25).astype(int)
    want = _yup_to_kinodyn(_oracle_positions(d, frames)) * s
    np.testing.assert_allclose(m.global_positions()[frames], want, atol=1e-9, err_msg=path.name)


# --------------------------------------------------------------------------- round trips


def _random_motion(rng, n_frames=7, n_joints=9, six=False) -> Motion:
    parents = [-1]
    for j in range(1, n_joints):
        parents.append(int(rng.integers(0, j)))
    # depth-first order is required by BVH: relabel by a DFS of the random tree
    children = {j: [k for k in range(n_joints) if parents[k] == j] for j in range(n_joints)}
    order, stack = [], [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(children[j]))
    new = {old: i for i, old in enumerate(order)}
    par = np.array([-1] + [new[parents[old]] for old in order[1:]])
    offsets = rng.normal(0, 0.15, (n_joints, 3))
    leaves = [j for j in range(n_joints) if j not in par]
    sk = Skeleton(tuple(f"j{j}" for j in range(n_joints)), par, offsets, np.array(leaves),
                  rng.normal(0, 0.1, (len(leaves), 3)))
    rot = quat.normalize(rng.normal(size=(n_frames, n_joints, 4)))
    root = rng.normal(0, 1.0, (n_frames, 3))
    tr = offsets + rng.normal(0, 0.05, (n_frames, n_joints, 3)) if six else None
    return Motion(sk, root, rot, 60.0, tr, "random")


@pytest.mark.parametrize("order", ["xyz", "xzy", "yxz", "yzx", "zxy", "zyx"])
@pytest.mark.parametrize("up", ["y", "z"])
@pytest.mark.parametrize("unit", ["m", "cm", "mm", "inch", "cmu", 0.37])
def test_write_read_round_trip(order, up, unit, tmp_path):
    rng = np.random.default_rng(hash((order, up, str(unit))) % 2**32)
    m = _random_motion(rng)
    path = tmp_path / "rt.bvh"
    write_bvh(path, m, scale=unit, up=up, order=order)
    r = read_bvh(path, scale=unit, up=up)
    assert r.skeleton.names == m.skeleton.names
    np.testing.assert_array_equal(r.skeleton.parents, m.skeleton.parents)
    assert r.num_frames == m.num_frames and r.fps == pytest.approx(m.fps, rel=1e-9)
    np.testing.assert_allclose(_positions_with_end(r), _positions_with_end(m), atol=_RT_TOL,
                               err_msg=f"{order} {up} {unit}")
    assert np.abs(_positions_with_end(r) - _positions_with_end(m)).max() < _RT_TOL


def test_round_trip_with_translations_and_poles(tmp_path):
    """Six-channel joints, and rotations at the Euler singularities (gimbal lock) and by pi."""
    rng = np.random.default_rng(3)
    m = _random_motion(rng, n_frames=6, six=True)
    rot = np.array(m.local_rot)
    rot[0] = quat.from_euler(np.array([0.3, np.pi / 2, -0.2]), "zyx")  # pole of zyx
    rot[1] = quat.from_euler(np.array([0.3, -np.pi / 2, 1.2]), "zyx")
    rot[2] = np.array([0.0, 1.0, 0.0, 0.0])  # pi about x
    rot[3] = np.array([0.0, 0.0, 0.0, 1.0])  # pi about z
    m = m.replace(local_rot=rot)
    for order in ("zyx", "xyz"):
        path = tmp_path / f"poles_{order}.bvh"
        write_bvh(path, m, order=order)
        r = read_bvh(path, scale="cm")
        assert r.translations is not None
        np.testing.assert_allclose(_positions_with_end(r), _positions_with_end(m), atol=_RT_TOL, err_msg=order)


def test_written_file_is_standard(tmp_path):
    rng = np.random.default_rng(5)
    m = _random_motion(rng)
    text = to_bvh_text(m)
    assert text.startswith("HIERARCHY\nROOT j0\n{\n")
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation" in text
    assert "\nMOTION\nFrames: 7\nFrame Time: 0.0166666667\n" in text
    assert "-0.000000 " not in text
    assert text.endswith("\n") and "\r" not in text
    assert to_bvh_text(m, scale="m").split("\n")[3].split()[1].count(".") == 1  # auto precision
    assert len(to_bvh_text(m, scale="m").split("MOTION")[1].split("\n")[3].split()[0].split(".")[1]) == 8


def test_writer_rejects_unwritable_input():
    rng = np.random.default_rng(1)
    m = _random_motion(rng)
    sk = m.skeleton
    with pytest.raises(ParameterError, match="whitespace"):
        to_bvh_text(m.replace(skeleton=sk.replace(names=("a b",) + sk.names[1:])))
    with pytest.raises(ParameterError):
        to_bvh_text(m, order="xxy")
    with pytest.raises(ParameterError):
        to_bvh_text(m, scale="furlong")
    with pytest.raises(ParameterError):
        to_bvh_text(m, up="x")
    # not depth-first: joint 2's subtree is interrupted
    bad = Skeleton(("a", "b", "c", "d"), np.array([-1, 0, 0, 1]), np.ones((4, 3)))
    with pytest.raises(ParameterError, match="depth-first"):
        to_bvh_text(Motion(bad, np.zeros((1, 3)), quat.identity((1, 4)), 30.0))


def test_deep_hierarchy_reads_and_writes(tmp_path):
    """A 3,000-joint chain: neither the reader nor the writer recurses."""
    n = 3000
    sk = Skeleton(tuple(f"j{k}" for k in range(n)), np.arange(-1, n - 1), np.tile([0.0, 0.0, 0.001], (n, 1)))
    m = Motion(sk, np.zeros((2, 3)), quat.identity((2, n)), 30.0)
    write_bvh(tmp_path / "deep.bvh", m, scale="mm")
    r = read_bvh(tmp_path / "deep.bvh", scale="mm")
    assert r.num_joints == n
    np.testing.assert_allclose(r.global_positions()[:, -1], [[0, 0, (n - 1) * 0.001]] * 2, atol=1e-9)


# --------------------------------------------------------------------------- real files


_ALL_BVH = mocap_files("**/*.bvh")


@pytest.mark.mocap
@pytest.mark.parametrize("path", _ALL_BVH or [None], ids=[p.name for p in _ALL_BVH] or ["no-mocap"])
def test_every_shared_bvh_loads_and_round_trips(path, tmp_path):
    if path is None:
        pytest.skip("shared motion-capture folder not found")
    m = read_bvh(path)
    d = parse_bvh(path.read_bytes(), path)
    assert m.num_frames == len(d.values) and m.num_joints == len(d.names)
    want_unit = "cm" if path.name.startswith("snu") else "cmu"
    s = UNIT_SCALES[want_unit]
    np.testing.assert_allclose(m.skeleton.offsets, _yup_to_kinodyn(d.offsets) * s, atol=1e-12)
    gp = m.global_positions()
    assert np.isfinite(gp).all()
    assert 1.1 < np.ptp(gp, axis=1).max() < 2.0, path.name  # a person-sized body, in metres
    # Z up: the lowest joint reaches the floor, standing or lying, in the captured frames (an added
    # T-pose stands at the first frame's root height, legs through the floor when the take starts lying)
    captured = gp[1:] if has_added_tpose(m) else gp
    assert -0.1 < captured[:, :, 2].min() < 0.2, path.name
    out = tmp_path / path.name
    write_bvh(out, m)
    r = read_bvh(out)
    assert r.num_frames == m.num_frames and r.fps == pytest.approx(m.fps, rel=1e-9)
    assert np.abs(_positions_with_end(r) - _positions_with_end(m)).max() < _RT_TOL


@pytest.mark.mocap
def test_cmu_frame_rate_and_unit(mocap_dir):
    m = read_bvh(mocap_dir / "locomotion" / "cmu_01_01.bvh")
    assert m.fps == pytest.approx(120.0, abs=1e-9)
    assert m.num_frames == 2752
    # the CMU unit: hips about 17 units = 0.96 m above the floor in the T-pose
    assert m.root_pos[0, 2] == pytest.approx(17.8693 * 0.0254 / 0.45, abs=1e-9)


# --------------------------------------------------------------------------- malformed files


def _body(frames: str, n: int | str = 1) -> str:
    head = CHAIN.split("MOTION")[0]
    return f"{head}MOTION\nFrames: {n}\nFrame Time: 0.01\n{frames}"


_ROW = "0 0 0 0 0 0 0 0 0 0 0 0\n"
# name -> (text or bytes, expected line, fragment of the message)
MALFORMED = {
    "empty": ("", 1, "empty"),
    "whitespace-only": ("  \n\n \t\n", 1, "empty"),
    "only-hierarchy": ("HIERARCHY", 1, "no MOTION"),
    "binary-garbage": (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(range(256)) * 4, 1, "not a BVH"),
    "binary-after-header": (b"HIERARCHY\nROOT \xff\xfe\nMOTION\n", 2, "UTF-8"),
    "missing-motion": (CHAIN.split("MOTION")[0], 20, "no MOTION"),
    "missing-root": ("HIERARCHY\nJOINT a\n{\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n0\n", 2, "ROOT"),
    "unclosed-joint": (CHAIN.split("MOTION")[0].rsplit("}", 1)[0] + "MOTION\nFrames: 1\nFrame Time: 0.1\n" + _ROW,
                       19, "unexpected end"),
    "extra-brace": (CHAIN.replace("MOTION", "}\nMOTION"), 21, "after the hierarchy"),
    "two-roots": (CHAIN.replace("MOTION", "ROOT b\n{\nOFFSET 0 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\n}\n"
                                "MOTION"), 21, "more than one ROOT"),
    "channels-billions": (CHAIN.replace("CHANNELS 3", "CHANNELS 3000000000", 1), 9, "3000000000 channels"),
    "channels-4": (CHAIN.replace("CHANNELS 3 Zrotation", "CHANNELS 4 Zrotation", 1), 9, "expected 3 or 6"),
    "channels-text": (CHAIN.replace("CHANNELS 3", "CHANNELS three", 1), 9, "must be an integer"),
    "channels-unicode-digit": (CHAIN.replace("CHANNELS 3", "CHANNELS \u0663", 1), 9, "must be an integer"),
    "channel-unknown": (CHAIN.replace("Zrotation Xrotation Yrotation\n\t\tJOINT",
                                      "Zrotation Wrotation Yrotation\n\t\tJOINT", 1), 9, "unknown channel"),
    "channel-repeated": (CHAIN.replace("Zrotation Xrotation Yrotation\n\t\tJOINT",
                                       "Zrotation Zrotation Yrotation\n\t\tJOINT", 1), 9, "distinct"),
    "duplicate-joint": (CHAIN.replace("JOINT Neck", "JOINT Chest"), 10, "used twice"),
    "offset-text": (CHAIN.replace("OFFSET 0 10 0", "OFFSET 0 ten 0", 1), 8, "found text 'ten'"),
    "offset-nan": (CHAIN.replace("OFFSET 0 10 0", "OFFSET 0 nan 0", 1), 8, "non-finite"),
    "offset-underscore": (CHAIN.replace("OFFSET 0 10 0", "OFFSET 0 1_0 0", 1), 8, "text"),
    "offset-huge": (CHAIN.replace("OFFSET 0 10 0", "OFFSET 0 1e300 0", 1), 8, "out of range"),
    "offset-short": (CHAIN.replace("OFFSET 0 10 0", "OFFSET 0 10", 1), 9, "expected a number"),
    "no-frames-line": (CHAIN.split("Frames:")[0], 22, "'Frames:'"),
    "frames-text": (_body(_ROW, "ten"), 22, "non-negative integer"),
    "frames-negative": (_body(_ROW, -1), 22, "non-negative integer"),
    "frames-zero": (_body("", 0), 22, "no frames"),
    "frames-absurd": (_body(_ROW, 10 ** 12), 22, "absurd"),
    "frames-huge-claim": (_body(_ROW, 40_000_000), 25, "truncated"),  # multi-gigabyte claim, one row
    "frames-more-than-data": (_body(_ROW * 3, 5), 27, "truncated"),
    "frames-fewer-than-data": (_body(_ROW * 3, 2), 26, "more frame lines"),
    "frame-time-missing": (CHAIN.split("Frame Time")[0], 23, "'Frame Time:'"),
    "frame-time-text": (CHAIN.replace("0.0333333", "fast"), 23, "must be a number"),
    "frame-time-zero": (CHAIN.replace("0.0333333", "0"), 23, "positive"),
    "frame-time-negative": (CHAIN.replace("0.0333333", "-0.1"), 23, "positive"),
    "frame-time-nan": (CHAIN.replace("0.0333333", "nan"), 23, "must be a number"),
    "row-short": (_body("0 0 0\n"), 24, "has 3 values"),
    "row-long": (_body(_ROW.strip() + " 7\n"), 24, "13 values"),
    "row-text": (_body("0 0 0 0 0 zero 0 0 0 0 0 0\n"), 24, "text 'zero'"),
    "row-nan": (_body("0 0 0 0 0 nan 0 0 0 0 0 0\n"), 24, "non-finite value 'nan'"),
    "row-inf": (_body("0 0 0 0 0 -inf 0 0 0 0 0 0\n"), 24, "non-finite value '-inf'"),
    "row-huge": (_body("0 0 0 0 0 1e400 0 0 0 0 0 0\n"), 24, "out of range"),
    "row-19-digits": (_body("0 0 0 0 0 9999999999999999999 0 0 0 0 0 0\n"), 24, "out of range"),
    "row-comma": (_body("0 0 0 0 0 1,5 0 0 0 0 0 0\n"), 24, "text '1,5'"),
    "row-second-bad": (_body(_ROW + "0 0 0 0 0 0 0 0 0 0 0 x\n", 2), 25, "text 'x'"),
    "row-binary": (_body("").encode() + b"0 0 0 \xff\xfe 0\n", 24, "text"),
    "truncated-mid-row": (_body(_ROW + "0 0 0 0", 2), 25, "has 4 values"),
}


@pytest.mark.parametrize("name", list(MALFORMED))
def test_malformed_files_name_file_and_line(name, tmp_path):
    content, line, fragment = MALFORMED[name]
    data = content if isinstance(content, bytes) else content.encode("utf-8")
    path = tmp_path / f"{name}.bvh"
    path.write_bytes(data)
    with pytest.raises(BVHParseError) as ei:
        read_bvh(path)
    e = ei.value
    assert isinstance(e, FileFormatError)
    assert e.path == str(path) and e.line == line, (str(e), line)
    assert fragment in str(e), str(e)
    assert str(e).startswith(f"{path}:{line}: ")


def test_huge_header_without_motion_is_rejected(tmp_path):
    """A 20 MB hierarchy without MOTION is rejected by its size, naming the limit (how fast is
    `kinodyn bench io`'s bvh_huge_header_reject_s)."""
    path = tmp_path / "huge.bvh"
    data = b"HIERARCHY\n" + b"JOINT x { OFFSET 0 0 0 }\n" * 800_000
    path.write_bytes(data)
    with pytest.raises(BVHParseError, match="no MOTION section in the first 16 MiB") as ei:
        read_bvh(path)
    assert ei.value.line == data[: 16 << 20].count(b"\n") + 1  # where the reader stopped looking


def test_too_many_joints(tmp_path):
    j = "JOINT a{k}\n{{\nOFFSET 0 0 0\nCHANNELS 0\n}}\n"
    text = ("HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\n"
            + "".join(j.format(k=k) for k in range(bvh.MAX_JOINTS)) + "}\nMOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0\n")
    with pytest.raises(BVHParseError, match=f"more than {bvh.MAX_JOINTS} joints"):
        parse_bvh(text.encode(), "many.bvh")


def test_missing_file_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_bvh(tmp_path / "nope.bvh")


def test_bad_options():
    with pytest.raises(ParameterError):
        bvh_from_bytes(CHAIN.encode(), scale="furlong")
    with pytest.raises(ParameterError):
        bvh_from_bytes(CHAIN.encode(), scale=-1.0)
    with pytest.raises(ParameterError):
        bvh_from_bytes(CHAIN.encode(), up="x")


# --------------------------------------------------------------------------- a third-party reader


def test_third_party_reader_accepts_written_file(tmp_path):
    """The `bvh` package (PyPI) reads our output: names, frames, frame time, and its channel values
    reproduce our joint positions through an independent scipy FK."""
    bvh_pkg = pytest.importorskip("bvh")
    rng = np.random.default_rng(11)
    m = _random_motion(rng, n_frames=5, n_joints=12)
    path = tmp_path / "third.bvh"
    write_bvh(path, m, scale="cm", order="zxy")
    doc = bvh_pkg.Bvh(path.read_text())
    names = doc.get_joints_names()
    assert tuple(names) == m.skeleton.names
    assert doc.nframes == m.num_frames
    assert doc.frame_time == pytest.approx(1.0 / m.fps, rel=1e-8)
    ours = m.global_positions()
    for f in range(m.num_frames):
        world = {}
        for j, n in enumerate(names):
            chans = doc.joint_channels(n)
            vals = doc.frame_joint_channels(f, n, chans)
            rot_axes = "".join(c[0] for c in chans if c.endswith("rotation"))
            r = Rotation.from_euler(rot_axes, [v for c, v in zip(chans, vals) if c.endswith("rotation")],
                                    degrees=True)
            parent = doc.joint_parent(n)
            if parent is None:
                pos = np.array(vals[:3])
                world[n] = (r, pos)
            else:
                pr, pp = world[parent.name]
                world[n] = (pr * r, pp + pr.apply(np.array(doc.joint_offset(n))))
            np.testing.assert_allclose(_yup_to_kinodyn(world[n][1]) * 0.01, ours[f, j], atol=1e-6,
                                       err_msg=f"frame {f} joint {n}")
