"""kinodyn.viz.render: offscreen rendering (MuJoCo through kinodyn.physics.render) to MP4, GIF and PNG.

Skipped when no offscreen OpenGL backend can make a context here (the reason names each one tried).
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


def _pixels(img: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """``(N, 3)`` colours in [0, 1] of the pixels under image points ``(N, 2)`` (x right, y down)."""
    h, w = img.shape[:2]
    ix = np.clip(np.floor(xy[:, 0]).astype(int), 0, w - 1)
    iy = np.clip(np.floor(xy[:, 1]).astype(int), 0, h - 1)
    return img[iy, ix].astype(float) / 255


def test_frames_follow_the_scene_clock(clips):
    """Each frame shows the scene at its time: the character's silhouette lies over its projected bones
    at that time (not where it stands a second later), the floor colour beside it, and an impact marker
    appears at its point from the impact's time on."""
    from kinodyn.plotting import style

    w = build_world(clips["walk"], [Impact(0.1, (0.5, 0.0, 1.0), (0.0, 20.0, 0.0))])
    cfg = render.RenderConfig(width=320, height=192, fps=30, end=0.2, shadows=False, hud=False, camera="fixed")
    ch = w.characters[0]
    floor = np.array(style.rgb(style.GROUND_COLOR))
    red = np.array(style.rgb(style.IMPACT_COLOR))
    with render.Renderer(w, cfg) as r:
        for t in np.arange(7) / 30.0:
            img = r.frame(float(t))
            assert img.shape == (192, 320, 3) and img.dtype == np.uint8

            def bones(time):
                p = ch.positions[min(round(time * ch.fps), ch.num_frames - 1)]
                return 0.5 * (p[ch.parents[1:]] + p[1:])  # bone midpoints

            sat = np.ptp(_pixels(img, r.project(bones(t))), axis=1)
            assert (sat > 0.12).mean() > 0.9, f"t={t:.2f}: the character is not where its bones are"
            later = np.ptp(_pixels(img, r.project(bones(t + 1.0))), axis=1)
            assert (later > 0.12).mean() < 0.3, f"t={t:.2f}: the frame shows the character a second later"
            side = bones(t) * [1, 1, 0] + [0.0, 1.5, 0.0]  # on the floor 1.5 m beside it
            beside = _pixels(img, r.project(side))
            assert np.ptp(beside, axis=1).max() < 0.08 and beside.min() > 0.6, f"t={t:.2f}: no floor beside"
            marker = _pixels(img, r.project([[0.5, 0.0, 1.0]]))[0]
            if t < 0.1 - 0.02 - 1e-9:
                assert np.abs(marker - floor).max() < 0.1, f"t={t:.2f}: the impact shows before it happens"
            else:
                assert np.abs(marker - red).max() < 0.25, f"t={t:.2f}: no impact marker at its point"


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
