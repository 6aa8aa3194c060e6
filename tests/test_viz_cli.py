"""``kinodyn view`` and ``kinodyn render``: files or built-in clips in, a page / video / glTF out."""

from __future__ import annotations

import json
import re

import numpy as np
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
    (["view", "walk", "run", "--names", "a"], "--names: one entry per input (2), got 1"),
    (["view", "walk", "--ghost", "no_such_clip"], "no such file, and not a built-in clip"),
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


@pytest.mark.parametrize("args, message", [
    (["view", "walk", "--loop", "--hold"], "argument --hold: not allowed with argument --loop"),
    (["render", "walk", "--layout", "spiral"], "argument --layout: invalid choice: 'spiral'"),
])
def test_option_errors_are_one_line_and_exit_2(args, message, capsys):
    with pytest.raises(SystemExit) as e:
        main(args)
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2 and message in err[-1]


def _page(path) -> dict:
    return json.loads(re.search(r'id="kinodyn-data">(.*?)</script>', path.read_text(), re.DOTALL).group(1))


@pytest.mark.skipif(not html.bundle_available(), reason="viewer bundle not built (run make)")
def test_view_lanes_loop_curves_and_a_ghost(tmp_path, walk_bvh, capsys):
    """``--layout lanes`` puts the walk and the run side by side across their direction of travel (X),
    ``--loop`` makes both loop, ``--curves`` opens the panel, ``--ghost`` adds a translucent reference."""
    from kinodyn.viz import world

    assert set(world.LAYOUTS) >= {"world", "row", "grid", "lanes"}
    out = tmp_path / "lanes.html"
    assert main(["view", str(walk_bvh), "run", "-o", str(out), "--layout", "lanes", "--loop", "--curves",
                 "--ghost", "walk"]) == 0
    assert "3 characters" in capsys.readouterr().out
    data = _page(out)
    (scene,) = data["scenes"]
    chars = scene["characters"]
    assert [c["name"] for c in chars] == ["walk", "run", "walk"]
    assert [c["ghost"] for c in chars] == [False, False, True] and all(c["loop"] for c in chars)
    assert data["options"]["curves"] is True and scene["view"] is not None  # lanes film from the front
    roots = [html.decode_positions(c["pos"], c["frames"], len(c["parents"]))[0, 0] for c in chars]
    assert abs(roots[0][1] - roots[1][1]) > 0.5  # lanes apart across the direction of travel (Y)
    plain = tmp_path / "plain.html"
    assert main(["view", str(walk_bvh), "run", "-o", str(plain), "--hold"]) == 0
    data = _page(plain)
    assert not any(c["loop"] for c in data["scenes"][0]["characters"]) and data["options"]["curves"] is False
    assert data["scenes"][0]["view"] is None


@pytest.mark.skipif(render.available() is not None, reason="offscreen rendering unavailable")
def test_render_loops_or_holds_a_short_clip(tmp_path, capsys):
    """At 1.9 s the run (1.4 s long) holds its last pose with ``--hold`` and is half a second into its
    second pass with ``--loop``: the two stills differ only there."""
    from PIL import Image

    stills = {}
    for flag in ("--hold", "--loop"):
        out = tmp_path / f"{flag[2:]}.png"
        assert main(["render", "walk", "run", "-o", str(out), "--layout", "row", "--start", "1.9", "--width", "160",
                     "--height", "96", "--fast", "--no-hud", "--camera", "fixed", flag]) == 0
        stills[flag] = np.asarray(Image.open(out).convert("RGB")).astype(int)
    again = tmp_path / "again.png"
    assert main(["render", "walk", "run", "-o", str(again), "--layout", "row", "--start", "1.9", "--width", "160",
                 "--height", "96", "--fast", "--no-hud", "--camera", "fixed"]) == 0
    assert np.array_equal(np.asarray(Image.open(again).convert("RGB")).astype(int), stills["--hold"])  # the default
    assert np.abs(stills["--hold"] - stills["--loop"]).sum(axis=2).astype(bool).sum() > 50
