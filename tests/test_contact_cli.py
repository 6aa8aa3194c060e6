"""The ``kinodyn contact`` command: run, fix, list; bad input is one line and exit 2."""

import json

import numpy as np

from kinodyn.cli import main
from kinodyn.contact.fix import fix_motion, penetration_before
from kinodyn.contact.motions import scenario_motion
from kinodyn.contact.scenefile import load_scene, scenario_path
from kinodyn.io import load


def test_run_writes_motion_trajectories_report_and_frames(tmp_path, capsys):
    assert main(["contact", "run", "two_arms", "-o", str(tmp_path), "--frames", "40", "--png", "1"]) == 0
    names = {p.name for p in tmp_path.iterdir()}
    assert {"two_arms.bvh", "two_arms_objects.npz", "two_arms_frames.csv", "two_arms_summary.json"} <= names
    assert any(n.endswith(".png") for n in names)
    info = json.loads((tmp_path / "two_arms_summary.json").read_text())
    assert info["frames"] == 40 and info["max_penetration_mm"] <= 1.0
    assert load(tmp_path / "two_arms.bvh").num_frames == 40
    with np.load(tmp_path / "two_arms_objects.npz") as z:
        assert z["pos"].shape[0] == 40


def test_fix_pushes_a_clip_out_of_a_wall(tmp_path, capsys):
    """The push clip placed too close to the gallery's dividing wall: before, the hands go 20 cm and
    more into it; after fixing, nothing is deeper than 1 mm."""
    scene = load_scene(scenario_path("gallery"))
    motion = scenario_motion("push").aligned_to(np.array([3.1, -1.8, 0.0]), 0)
    before = penetration_before(motion, scene)
    fixed, rep = fix_motion(motion, scene)
    assert before.max() > 0.1
    assert penetration_before(fixed, scene).max() <= 1e-3
    assert rep["changed_deg"].max() > 5.0
    out = tmp_path / "fixed.bvh"
    assert main(["contact", "fix", "push", "--scene", "gallery", "--place", "3.1", "-1.8", "0", "-o", str(out),
                 "--report", str(tmp_path / "r.csv")]) == 0
    assert out.exists() and (tmp_path / "r.csv").exists()
    assert "frames changed" in capsys.readouterr().out


def test_bad_input_is_one_line_exit_2(tmp_path, capsys):
    assert main(["contact", "run", "no_such_scenario", "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no scenario named 'no_such_scenario'" in err[0]
    bad = tmp_path / "bad.yaml"
    bad.write_text("objects:\n  - {name: t, kind: fixed, material: glass, shape: {box: [1, 1, 1]}}\n")
    assert main(["contact", "run", str(bad), "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.yaml" in err[0] and "objects[0] 't'" in err[0]


def test_list_names_the_scenarios(capsys):
    assert main(["contact", "list"]) == 0
    out = capsys.readouterr().out
    for name in ("hand", "two_arms", "self_collision", "two_arms_leg", "arm_in_corner"):
        assert name in out


def test_a_scene_playing_motion_capture_needs_the_file(tmp_path, capsys, monkeypatch):
    """walk_into_wall plays CMU 02_01, which is never shipped: without it the run stops with one line
    naming the file and how to give it; --motion gives it directly."""
    monkeypatch.setenv("KINODYN_MOCAP", str(tmp_path / "empty"))
    assert main(["contact", "run", "walk_into_wall", "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cmu_02_01.bvh" in err[0] and "--motion" in err[0]
    assert main(["contact", "run", "walk_into_wall", "-o", str(tmp_path), "--motion", str(tmp_path / "no.bvh")]) == 2
    assert "no such motion file" in capsys.readouterr().err
    clip = tmp_path / "walk.bvh"
    from kinodyn.io import save

    save(clip, scenario_motion("walk")[:30])
    assert main(["contact", "run", "walk_into_wall", "-o", str(tmp_path), "--motion", str(clip)]) == 0
    assert load(tmp_path / "walk_into_wall.bvh").num_frames == 30
