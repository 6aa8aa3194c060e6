"""Contact runs in the viewer: the scene's objects, simulated ones moving, penetrating segments, normals.

The page of ``kinodyn contact run SCENARIO --html`` is opened in headless Chromium (skipped, with the
reason, when Chromium, chromedriver or Selenium is missing); the arrays behind it are checked directly.
"""

from __future__ import annotations

import io
import time

import numpy as np
import pytest

from kinodyn.cli import main
from kinodyn.contact.display import contact_normals, penetrating_joints, shape_tracks
from kinodyn.contact.scenefile import load_scene, scenario_path
from kinodyn.contact.simulate import run_scene
from kinodyn.viz import browser, html

_DROP = """name: drop
description: a ball dropped on a table
fps: 60
frames: 50
objects:
  - {name: floor, material: wood, shape: {box: [2, 2, 0.05]}, pos: [0, 0, -0.05]}
  - name: table
    material: wood
    pieces:
      - {box: [0.5, 0.4, 0.025]}
      - {box: [0.03, 0.03, 0.35], pos: [0.44, 0.34, -0.375]}
    pos: [0.0, 0.0, 0.725]
  - {name: ball, kind: simulated, material: metal, shape: {sphere: 0.05}, mass: 0.2, pos: [0, 0, 1.4]}
"""


@pytest.fixture(scope="module")
def two_arms():
    scene = load_scene(scenario_path("two_arms"))
    return scene, run_scene(scene, frames=60)


def test_shapes_are_the_scenes_objects_and_the_avatar_is_not_among_them(two_arms):
    scene, result = two_arms
    tracks = shape_tracks(scene, result)
    assert [t.name for t in tracks] == [o.name for o in scene.objects]
    walls = {t.name: t for t in tracks}
    assert walls["floor"].shape == "box" and walls["floor"].positions.shape == (1, 3)
    assert walls["table"].shape == "mesh" and len(walls["table"].faces) == 5 * 12  # five boxes
    assert walls["ring"].shape == "mesh" and len(walls["ring"].faces) > 100  # convex pieces of a torus


def test_the_tracked_push_goes_into_the_wall_with_the_forearms_and_the_resolved_one_touches_it(two_arms):
    scene, result = two_arms
    hot = penetrating_joints(result.tracked, scene)
    names = result.tracked.skeleton.names
    inside = {names[j] for j in np.nonzero(hot.any(axis=0))[0]}
    assert inside and inside <= {"LeftForeArm", "LeftHand", "RightForeArm", "RightHand"}
    assert not penetrating_joints(result.motion, scene).any()
    frames, points, normals = contact_normals(result.motion, scene)
    assert len(frames) and np.allclose(np.linalg.norm(normals, axis=1), 1.0)
    at_wall = points[:, 2] > 0.5  # the hands, not the feet on the floor
    assert at_wall.any()
    # the divider is the plane x = 3.9 (its face towards the avatar): its normals point to -x
    assert np.all(normals[at_wall, 0] < -0.9)


_REASON = browser.unavailable_reason() or (None if html.bundle_available() else "viewer bundle not built (make)")


def open_page(drv, path):
    drv.get(path.resolve().as_uri())
    t0 = time.perf_counter()
    while not drv.execute_script("const v = window.kinodynViewer; return v && (v.ready || v.errors.length)"):
        assert time.perf_counter() - t0 < 60, "page did not finish loading"
        time.sleep(0.05)
    assert drv.execute_script("return window.kinodynViewer.errors") == []
    drv.execute_script("window.kinodynViewer.pause()")


def at(drv, t: float) -> dict:
    """The page's state at scene time ``t``, once it has drawn three frames there."""
    drv.execute_script(f"window.kinodynViewer.seek({t})")
    n0 = drv.execute_script("return window.kinodynViewer.renderedFrames")
    t0 = time.perf_counter()
    while drv.execute_script("return window.kinodynViewer.renderedFrames") < n0 + 3:
        assert time.perf_counter() - t0 < 20, "the page stopped drawing"
        time.sleep(0.05)
    return drv.execute_script("return window.kinodynViewer.state()")


def red_pixels(drv) -> int:
    """Red pixels (the highlight, lit and seen through a translucent wall: red with green and blue alike,
    unlike the orange of the reference's label)."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(drv.get_screenshot_as_png())).convert("RGB")).astype(np.float64)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return int(((r - g > 60) & (r - b > 50) & (np.abs(g - b) < 40)).sum())


@pytest.mark.skipif(_REASON is not None, reason=f"headless browser unavailable: {_REASON}")
def test_the_page_draws_the_scene_and_the_dropped_ball_falls(tmp_path, capsys):
    scene = tmp_path / "drop.yaml"
    scene.write_text(_DROP)
    assert main(["contact", "run", str(scene), "-o", str(tmp_path), "--html"]) == 0
    page = tmp_path / "drop.html"
    assert page.exists()
    with browser.chromium(960, 600) as drv:
        open_page(drv, page)
        first = at(drv, 0.0)
        props = first["props"]
        assert [p["shape"] for p in props] == ["box", "mesh", "sphere"]
        assert all(p["visible"] for p in props)
        assert first["characters"][0]["name"] == "ball"  # the camera follows the moving object
        later = at(drv, 0.3)["props"]
    with np.load(tmp_path / "drop_objects.npz") as z:
        ball = z["pos"][:, 2]  # the run's trajectories, (F, N, 3) at 60 fps
    assert props[2]["position"] == pytest.approx(ball[0], abs=2e-3)
    assert later[2]["position"] == pytest.approx(ball[18], abs=2e-3)  # 0.3 s: frame 18
    assert ball[0][2] - ball[18][2] > 0.4  # it falls
    assert later[0]["position"] == pytest.approx([0, 0, -0.05], abs=1e-3)  # the floor stays


@pytest.mark.skipif(_REASON is not None, reason=f"headless browser unavailable: {_REASON}")
def test_the_page_colours_the_tracked_segments_inside_the_wall(tmp_path, two_arms):
    from kinodyn.contact.command import write_page

    scene, result = two_arms
    page = tmp_path / "two_arms.html"
    write_page(page, scene, result)
    hot = penetrating_joints(result.tracked, scene)
    f_in, f_out = int(np.nonzero(hot.any(axis=1))[0][0]) + 5, 0
    with browser.chromium(960, 600) as drv:
        open_page(drv, page)
        s = at(drv, (f_in + 0.3) / result.fps)  # arrows are held one frame: those of f_in only
        tracked = next(c for c in s["characters"] if c["name"] == "tracked")
        assert tracked["ghost"] and tracked["hot"] >= 2
        assert s["forces"] == [int((contact_normals(result.motion, scene)[0] == f_in).sum())]
        red_in = red_pixels(drv)
        s = at(drv, f_out / result.fps)
        assert next(c for c in s["characters"] if c["name"] == "tracked")["hot"] == 0
        red_out = red_pixels(drv)
    # the highlight adds about 100 red pixels at 960 x 600 (measured 123-131 inside, 22 outside, the
    # count moving by a few pixels with the antialiasing from run to run): a margin of 100 failed now and then
    assert red_in > red_out + 60, (red_in, red_out)


def test_arms_crossing_through_each_other_are_marked_as_self_collision():
    scene = load_scene(scenario_path("self_collision"))
    result = run_scene(scene, frames=90)
    own = penetrating_joints(result.tracked, scene)
    assert not penetrating_joints(result.tracked, scene, self_collision=False).any()  # no wall near
    names = result.tracked.skeleton.names
    marked = {names[j] for j in np.nonzero(own.any(axis=0))[0]}
    assert {"LeftForeArm", "RightForeArm"} & marked
    assert penetrating_joints(result.motion, scene).sum() < own.sum()  # resolution removes most of it
