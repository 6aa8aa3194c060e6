"""Demo part "viewer": out/demo.html with every built-in clip and earlier parts' files, out/demo.mp4."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from kinodyn.data import library
from kinodyn.io import save
from kinodyn.viz import demo, html, render


def test_clip_scenes_show_every_clip_in_rows():
    scenes = demo.clip_scenes()
    shown = [n for s in scenes for n in s.motions]
    assert sorted(shown) == sorted(library.names())
    assert all(len(s.motions) <= demo._SCENE_SIZE and s.layout == "row" for s in scenes)


def test_part_scenes_group_files_by_prefix(tmp_path):
    walk = library.load("walk")
    (tmp_path / "physics").mkdir()
    (tmp_path / "clips").mkdir()
    for name in ("fight_attacker", "fight_defender", "walk_hit"):
        save(tmp_path / "physics" / f"{name}.bvh", walk)
    save(tmp_path / "clips" / "walk.bvh", walk)  # the built-in clips are shown from the library instead
    (tmp_path / "physics" / "broken.bvh").write_text("HIERARCHY\nROOT")
    (tmp_path / "physics" / "body.xml").write_text("<mujoco/>")
    np.savez(tmp_path / "physics" / "walk_objects.npz", times=np.zeros(3))  # another archive: not a motion
    (tmp_path / "physics" / "fight_torn.npz").write_bytes(b"PK\x03\x04 torn")  # a broken one: reported
    scenes, skipped = demo.part_scenes(tmp_path)
    assert [(s.name, sorted(s.motions)) for s in scenes] == [
        ("physics: fight", ["fight_attacker", "fight_defender"]), ("physics: walk", ["walk_hit"])]
    assert len(skipped) == 2 and "broken.bvh" in skipped[0] and "fight_torn.npz" in skipped[1], skipped


@pytest.mark.skipif(not html.bundle_available() or render.available() is not None,
                    reason="viewer bundle or offscreen rendering unavailable")
def test_demo_writes_page_video_plots_and_gltf(tmp_path, monkeypatch):
    monkeypatch.setattr(demo, "_VIDEO", {"width": 160, "height": 96, "end": 0.2, "shadows": False})
    (tmp_path / "physics").mkdir()
    save(tmp_path / "physics" / "walk_hit.bvh", library.load("walk"))
    lines = demo.demo(tmp_path)
    assert any(line.startswith("demo.html") and "physics: walk" in line for line in lines)
    text = (tmp_path / "demo.html").read_text()
    data = json.loads(re.search(r'id="kinodyn-data">(.*?)</script>', text, re.DOTALL).group(1))
    assert data["scenes"][-1]["name"] == "physics: walk"
    assert (tmp_path / "demo.mp4").stat().st_size > 1000
    for name in ("support_phases.png", "support_phases.svg", "walk.glb"):
        assert (tmp_path / "viewer" / name).stat().st_size > 1000


def test_part_scenes_draw_impacts_once_per_pair(tmp_path):
    walk = library.load("walk")
    (tmp_path / "physics").mkdir()
    for name in ("fight_attacker", "fight_defender"):
        save(tmp_path / "physics" / f"{name}.bvh", walk)
    hit = {"time": 0.5, "point": [0.8, 0.0, 1.5], "impulse": [12.0, 1.0, 9.0], "character": "defender", "body": "Head"}
    reaction = dict(hit, impulse=[-12.0, -1.0, -9.0], character="attacker", body="RightHand")
    (tmp_path / "physics" / "impacts.json").write_text(json.dumps({"fight": [hit, reaction]}))
    (scene,), skipped = demo.part_scenes(tmp_path)
    impacts = [o for o in scene.overlays if not isinstance(o, str)]
    assert skipped == [] and len(impacts) == 1
    assert impacts[0].character == 1 and impacts[0].label == "Head" and impacts[0].time == 0.5
