"""kinodyn.viz.render: offscreen CPU rendering (MuJoCo + OSMesa) to MP4, GIF and PNG.

Skipped when no offscreen OpenGL context can be made (Debian: apt-get install libosmesa6).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from kinodyn.data import library
from kinodyn.errors import ParameterError
from kinodyn.viz import render
from kinodyn.viz.world import Impact, build_world

_REASON = render.available()
pytestmark = pytest.mark.skipif(_REASON is not None, reason=f"offscreen rendering unavailable: {_REASON}")

_W, _H = 160, 96  # small frames keep the tests fast
_FAST = {"width": _W, "height": _H, "shadows": False}


@pytest.fixture(scope="module")
def clips():
    return {"walk": library.load("walk"), "punch": library.load("punch")}


def read_mp4(path) -> tuple[dict, list[np.ndarray]]:
    import imageio_ffmpeg

    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    w, h = meta["size"]
    return meta, [np.frombuffer(f, dtype=np.uint8).reshape(h, w, 3) for f in gen]


def test_mp4_frame_count_size_and_motion(tmp_path, clips):
    walk = clips["walk"][:31]  # 0.5 s at 60 fps
    res = render.render(tmp_path / "walk.mp4", walk, fps=20, **_FAST)
    assert res.frames == 11  # 0, 0.05, ..., 0.5 s
    meta, frames = read_mp4(res.path)
    assert len(frames) == res.frames
    assert meta["size"] == (_W, _H) and meta["fps"] == pytest.approx(20)
    diff = np.abs(frames[0].astype(int) - frames[-1].astype(int)).mean()
    assert diff > 0.5, "first and last frames are the same: nothing moved"
    assert frames[0].std() > 5, "blank frame"


def test_gif_frame_count_and_frames_differ(tmp_path, clips):
    from PIL import Image, ImageSequence

    res = render.render(tmp_path / "two.gif", clips, ["contacts", "phases"], fps=10, end=0.6, **_FAST)
    assert res.frames == 7
    img = Image.open(res.path)
    frames = [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(img)]
    assert len(frames) == 7 and frames[0].shape == (_H, _W, 3)
    assert any(np.abs(a.astype(int) - b.astype(int)).mean() > 0.3 for a, b in itertools.pairwise(frames))


def test_png_still_shows_the_characters_in_their_colours(tmp_path, clips):
    from PIL import Image

    res = render.render(tmp_path / "still.png", clips, None, layout="row", start=0.5, width=320, height=180,
                        hud=False)
    assert res.frames == 1
    img = np.asarray(Image.open(res.path).convert("RGB")).astype(float) / 255
    sat = img.max(axis=2) - img.min(axis=2)
    assert (sat > 0.25).sum() > 300, "no saturated character pixels"
    # Bluish pixels of the first palette colour (#4e79a7) and orange ones of the second (#f28e2b).
    blue = (img[..., 2] > img[..., 0] + 0.15).sum()
    orange = (img[..., 0] > img[..., 2] + 0.3).sum()
    assert blue > 50 and orange > 50


def test_frames_follow_the_scene_clock(clips):
    w = build_world(clips["walk"], [Impact(0.1, (0.5, 0.0, 1.0), (0.0, 20.0, 0.0))])
    cfg = render.RenderConfig(fps=30, end=0.2, **_FAST)
    imgs = list(render.frames(w, cfg))
    assert len(imgs) == 7
    assert all(i.shape == (_H, _W, 3) and i.dtype == np.uint8 for i in imgs)


def test_orbit_camera_and_bones_body(tmp_path, clips):
    res = render.render(tmp_path / "orbit.gif", clips["punch"], camera="orbit", body="bones", fps=5, end=0.4,
                        **_FAST)
    assert res.frames == 3


def test_config_and_format_errors(tmp_path, clips):
    with pytest.raises(ParameterError, match="width and height"):
        render.RenderConfig(width=2)
    with pytest.raises(ParameterError, match="camera must be"):
        render.RenderConfig(camera="top")
    with pytest.raises(ParameterError, match="end must be a time"):
        render.RenderConfig(start=1.0, end=0.5)
    with pytest.raises(ParameterError, match=r"must end in \.mp4, \.gif, \.png"):
        render.render(tmp_path / "x.avi", clips["walk"], **_FAST)
    assert not (tmp_path / "x.avi").exists()
