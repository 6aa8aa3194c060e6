"""``kinodyn view`` and ``kinodyn render``: files or built-in clips in, a page / video / glTF out."""

from __future__ import annotations

import json
import re

import pytest

from kinodyn.cli import main
from kinodyn.data import library
from kinodyn.io import save
from kinodyn.viz import html, render


@pytest.fixture
def walk_bvh(tmp_path):
    path = tmp_path / "walk.bvh"
    save(path, library.load("walk"))
    return path


@pytest.mark.skipif(not html.bundle_available(), reason="viewer bundle not built (run make)")
def test_view_files_and_clips(tmp_path, walk_bvh, capsys):
    out = tmp_path / "page.html"
    rc = main(["view", str(walk_bvh), "punch", "-o", str(out), "--names", "w,p", "--overlays", "contacts,phases",
               "--layout", "row", "--body", "bones", "--paused"])
    assert rc == 0
    assert re.match(r"wrote .*page\.html: 2 characters, 121 frames, [\d.]+ MB", capsys.readouterr().out)
    data = json.loads(re.search(r'id="kinodyn-data">(.*?)</script>', out.read_text(), re.DOTALL).group(1))
    assert [c["name"] for c in data["scenes"][0]["characters"]] == ["w", "p"]
    assert data["options"]["style"] == "bones" and data["options"]["autoplay"] is False


def test_view_writes_gltf(tmp_path, capsys):
    pytest.importorskip("pygltflib")
    out = tmp_path / "walk.glb"
    assert main(["view", "walk", "-o", str(out)]) == 0
    assert out.read_bytes()[:4] == b"glTF"
    assert main(["view", "walk", "run", "-o", str(tmp_path / "two.glb")]) == 2
    assert "a glTF export takes one motion" in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["view", "no_such_clip"], "no such file, and not a built-in clip"),
    (["view", "walk", "-o", "x.mp4"], "kinodyn render"),
    (["view", "walk", "--overlays", "sparkles"], "unknown overlay 'sparkles'"),
    (["view", "walk", "--drop-first", "1000"], "leaves no frames"),
    (["render", "walk", "-o", "x.avi"], "must end in .mp4, .gif, .png"),
    (["render", "walk", "--width", "2"], "width and height"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys, args, message):
    monkeypatch.chdir(tmp_path)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


@pytest.mark.skipif(render.available() is not None, reason="offscreen rendering unavailable")
def test_render_gif(tmp_path, walk_bvh, capsys):
    out = tmp_path / "walk.gif"
    rc = main(["render", str(walk_bvh), "-o", str(out), "--width", "96", "--height", "64", "--fps", "10",
               "--end", "0.3", "--fast"])
    assert rc == 0
    assert "4 frames at 10 fps, 96x64" in capsys.readouterr().out
    from PIL import Image

    assert Image.open(out).n_frames == 4
