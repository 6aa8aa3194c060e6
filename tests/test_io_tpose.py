"""The added T-pose frame of cgspeed CMU conversions: detected where it is, never where it is not."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from conftest import mocap_files
from kinodyn.cli import main
from kinodyn.data import library
from kinodyn.io import drop_added_tpose, has_added_tpose, load, save
from kinodyn.math import quat
from kinodyn.motion import Motion

# cgspeed MotionBuilder-friendly conversions (`cmu_*.bvh`) carry the added frame; the 3dsMax-friendly
# conversion, the SNU retargets and the original ASF/AMC files do not (see the mocap MANIFEST).
_WITH = [p for p in mocap_files("**/*.bvh") if p.name.startswith("cmu_")]
_WITHOUT = [p for p in mocap_files("**/*.bvh") + mocap_files("**/*.amc") if not p.name.startswith("cmu_")
            or p.suffix == ".amc"]


@pytest.mark.mocap
@pytest.mark.parametrize("path", _WITH or [None], ids=[p.name for p in _WITH] or ["no-mocap"])
def test_cgspeed_tpose_is_detected_and_dropped(path):
    if path is None:
        pytest.skip("shared motion-capture folder not found")
    m = load(path)
    assert has_added_tpose(m), path.name
    d, dropped = drop_added_tpose(m)
    assert dropped and d.num_frames == m.num_frames - 1
    np.testing.assert_array_equal(d.local_rot, m.local_rot[1:])
    assert not has_added_tpose(d), path.name  # the first captured frame is not taken for another


@pytest.mark.mocap
@pytest.mark.parametrize("path", _WITHOUT or [None], ids=[p.name for p in _WITHOUT] or ["no-mocap"])
def test_files_without_an_added_tpose_are_kept_whole(path):
    if path is None:
        pytest.skip("shared motion-capture folder not found")
    m = load(path)
    d, dropped = drop_added_tpose(m)
    assert not dropped and d is m, path.name


@pytest.mark.parametrize("name", library.names())
def test_builtin_clips_have_no_added_tpose(name):
    assert not has_added_tpose(library.load(name))


def _tpose_then(clip: Motion, n_hold: int = 1) -> Motion:
    """``clip`` preceded by ``n_hold`` frames of its skeleton's rest pose (a T-pose for the built-in
    skeleton's arms once they are raised sideways) at its first root position."""
    sk = clip.skeleton
    rest = quat.identity((n_hold, sk.num_joints))
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        # the built-in skeleton's arms hang down in its rest pose: raise them to horizontal
        j = sk.names.index(f"{side}Arm")
        rest[:, j] = quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), sign * np.pi / 2)
    rp = np.repeat(clip.root_pos[:1], n_hold, axis=0)
    return clip.replace(root_pos=np.concatenate([rp, clip.root_pos]),
                        local_rot=np.concatenate([rest, clip.local_rot]))


def test_synthetic_tpose_before_a_clip_is_detected():
    clip = library.load("walk")
    m = _tpose_then(clip)
    assert has_added_tpose(m)
    d, dropped = drop_added_tpose(m)
    assert dropped and d.num_frames == clip.num_frames


def test_a_held_tpose_is_captured_motion_not_an_added_frame():
    """A take that starts in a T-pose held for several frames keeps its first frame."""
    m = _tpose_then(library.load("walk"), n_hold=10)
    assert not has_added_tpose(m)


def test_too_short_motions_have_no_added_tpose():
    m = _tpose_then(library.load("walk"))
    assert not has_added_tpose(m[:1]) and not has_added_tpose(m[:0])


# --------------------------------------------------------------------------- the commands


@pytest.fixture
def tpose_bvh(tmp_path):
    """A BVH file whose frame 0 is an added T-pose (the built-in walk after one)."""
    path = tmp_path / "tpose_walk.bvh"
    save(path, _tpose_then(library.load("walk")))
    return path


def test_info_reports_the_added_tpose(tpose_bvh, capsys):
    assert main(["info", str(tpose_bvh)]) == 0
    out = capsys.readouterr().out
    assert "T-pose" in out and "added by the file's converter" in out
    assert main(["info", str(tpose_bvh), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["added_tpose"] is True


def test_info_is_silent_without_an_added_tpose(tmp_path, capsys):
    path = tmp_path / "walk.bvh"
    save(path, library.load("walk"))
    assert main(["info", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["added_tpose"] is False
    assert main(["info", str(path)]) == 0
    assert "T-pose" not in capsys.readouterr().out


def test_convert_keeps_every_frame_unless_asked(tpose_bvh, tmp_path, capsys):
    n = load(tpose_bvh).num_frames
    assert main(["convert", str(tpose_bvh), str(tmp_path / "all.npz")]) == 0
    assert load(tmp_path / "all.npz").num_frames == n
    assert main(["convert", str(tpose_bvh), str(tmp_path / "cut.npz"), "--drop-tpose"]) == 0
    assert load(tmp_path / "cut.npz").num_frames == n - 1


def test_view_and_render_inputs_skip_the_tpose_with_a_note(tpose_bvh, capsys):
    """``kinodyn view`` and ``kinodyn render`` read their inputs through one loader."""
    from kinodyn.commands.view import add_input_arguments, load_inputs

    n = load(tpose_bvh).num_frames
    p = argparse.ArgumentParser()
    add_input_arguments(p)
    (m,) = load_inputs(p.parse_args([str(tpose_bvh)]))
    assert m.num_frames == n - 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(tpose_bvh) in err and "T-pose" in err and "--keep-tpose" in err
    (m,) = load_inputs(p.parse_args([str(tpose_bvh), "--keep-tpose"]))
    assert m.num_frames == n and capsys.readouterr().err == ""
    (m,) = load_inputs(p.parse_args([str(tpose_bvh), "--drop-first", "2"]))
    assert m.num_frames == n - 2  # an explicit --drop-first replaces the detection


def test_view_writes_the_page_without_the_tpose(tpose_bvh, tmp_path, capsys):
    out = tmp_path / "v.html"
    assert main(["view", str(tpose_bvh), "-o", str(out)]) == 0
    assert f"{load(tpose_bvh).num_frames - 1} frames" in capsys.readouterr().out
