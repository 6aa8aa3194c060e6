"""The viewer's features in headless Chromium, each checked through the page's state and its pictures.

The world (props and the ball of a hit, forces, centre of mass and support polygon, stages), reading a
character (left/right tints, nose, trails, onion skins, curves), comparing (lanes, references, labels that
do not overlap), cameras (presets, orthographic, follow framing, loop, loop range, markers), a dropped BVH
file, in-place and snap-to-floor, a crowd, and a browser without WebGL. Skipped, with the reason, when
Chromium, chromedriver or Selenium is missing. WebGL is SwiftShader (software) there.
"""

from __future__ import annotations

import io
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose

from kinodyn.data import library
from kinodyn.plotting import style
from kinodyn.viz import browser, html, world
from kinodyn.viz.objects import Marker, Prop, Stages, centre_of_mass

_REASON = browser.unavailable_reason() or (None if html.bundle_available() else "viewer bundle not built (make)")
pytestmark = pytest.mark.skipif(_REASON is not None, reason=f"headless browser unavailable: {_REASON}")

_PAGE_TIMEOUT_S = 60.0
_QUANT = 2e-3  # positions in the page: int16 over the scene's box, float32


@pytest.fixture(scope="module")
def drv():
    with browser.chromium(1280, 720) as d:
        yield d


def open_page(drv, path, js: str = ""):
    drv.get(path.resolve().as_uri())
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < _PAGE_TIMEOUT_S:
        state = drv.execute_script("const v = window.kinodynViewer; return v ? [v.ready, v.errors.length] : [false, 0]")
        if state[0] or state[1]:
            break
        time.sleep(0.05)
    assert drv.execute_script("return window.kinodynViewer.errors") == []
    assert drv.execute_script("return window.kinodynViewer.ready"), "page did not finish loading"
    drv.execute_script(f"window.kinodynViewer.pause(); {js}")


def frames(drv, n: int = 3, timeout: float = 20.0):
    """Wait until the page has drawn ``n`` more frames (a frame a few hundred ms under SwiftShader)."""
    n0 = drv.execute_script("return window.kinodynViewer.renderedFrames")
    t0 = time.perf_counter()
    while drv.execute_script("return window.kinodynViewer.renderedFrames") < n0 + n:
        assert time.perf_counter() - t0 < timeout, "the page stopped drawing"
        time.sleep(0.05)


def state(drv) -> dict:
    return drv.execute_script("return window.kinodynViewer.state()")


def at(drv, t: float, n: int = 3) -> dict:
    drv.execute_script(f"window.kinodynViewer.seek({t})")
    frames(drv, n)
    return state(drv)


def image(drv) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(drv.get_screenshot_as_png())).convert("RGB")).astype(np.float64)


def near_color(img: np.ndarray, color: str, tol: float = 30.0) -> int:
    """Pixels within ``tol`` (0..255 per channel, Euclidean) of a colour."""
    return int((np.linalg.norm(img - style.rgb(color) * 255, axis=2) < tol).sum())


def severe(drv) -> list[str]:
    return [e["message"] for e in drv.get_log("browser") if e.get("level") == "SEVERE"]


@pytest.fixture(scope="module")
def walk():
    return library.load("walk")


@pytest.fixture(scope="module")
def hit(tmp_path_factory, walk):
    """A ball thrown at a walking character in the physics world, the simulated walk and its kinematic twin."""
    pytest.importorskip("mujoco")
    from kinodyn.data.skeleton import humanoid
    from kinodyn.physics.world import World
    from kinodyn.viz.recording import ObjectRecorder

    w = World()
    c = w.add_character(humanoid(), name="walker")
    c.play(walk, loop=True)
    w.throw(c, "chest", mass=4.0, radius=0.11, speed=9.0, direction=np.pi / 2, height=1.5, at=1.0)
    rec = ObjectRecorder(w)
    rec.run(2.0)
    sim = c.trajectory()
    ov = rec.overlays(["walker"], forces=True)
    stages = Stages([(0.0, c.switch_time, "motion data"), (c.switch_time, 2.0, "simulation")], 0)
    path = tmp_path_factory.mktemp("viz") / "hit.html"
    html.write(path, {"walker": sim, "kinematic": html.Actor(walk.resample(60), ghost=True)},
               ["contacts", "phases", stages, *ov])
    impacts = [o for o in ov if isinstance(o, world.Impact)]
    return path, impacts[0], next(o for o in ov if isinstance(o, Prop))


# --------------------------------------------------------------------------- robustness


def test_a_browser_without_webgl_shows_a_clear_message(tmp_path, walk):
    path = tmp_path / "walk.html"
    html.write(path, walk)
    with browser.chromium(800, 500, args=("--disable-webgl", "--disable-3d-apis")) as d:
        d.get(path.resolve().as_uri())
        t0 = time.perf_counter()
        while d.execute_script("return !window.kinodynViewer || window.kinodynViewer.webgl !== false"):
            assert time.perf_counter() - t0 < _PAGE_TIMEOUT_S, "the page did not notice WebGL is missing"
            time.sleep(0.05)
        status = d.find_element("id", "kd-status")
        assert status.is_displayed()
        assert "needs WebGL" in status.text and "hardware acceleration" in status.text
        assert d.execute_script("return window.kinodynViewer.ready") is False
        from PIL import Image

        img = np.asarray(Image.open(io.BytesIO(d.get_screenshot_as_png())).convert("RGB")).astype(np.float64)
        assert near_color(img, "#d62728", 40) > 300, "the message's red frame is on screen"
        assert severe(d) == []


# --------------------------------------------------------------------------- the world


def test_the_ball_of_a_hit_is_drawn_where_it_lands(drv, hit):
    path, impact, ball = hit
    open_page(drv, path)
    before = at(drv, ball.start - 0.05)
    assert [p["visible"] for p in before["props"]] == [False], "the ball is hidden before its launch"
    s = at(drv, impact.time)
    assert s["props"][0]["visible"] and s["props"][0]["shape"] == "sphere"
    assert np.linalg.norm(np.array(s["props"][0]["position"]) - impact.point) < 0.11 + 0.05
    with_ball = near_color(image(drv), "#8c6d4f", 25)
    drv.execute_script("window.kinodynViewer.set('props', false)")
    frames(drv)
    without = near_color(image(drv), "#8c6d4f", 25)
    drv.execute_script("window.kinodynViewer.set('props', true)")
    assert with_ball > without + 150, f"ball pixels {with_ball} vs {without} with props off"
    assert s["forces"] and max(s["forces"]) >= 1, "the contact force arrow is drawn at the impact"
    late = at(drv, impact.time + 0.6)
    assert late["forces"] == [0] * len(late["forces"]), "force arrows last their hold time only"


def test_stages_colour_the_timeline(drv, hit):
    path, impact, _ = hit
    open_page(drv, path)
    frames(drv)
    js = """const cv = document.getElementById('kd-timeline'), v = window.kinodynViewer.viewer;
    const rows = v.timelineRows(), i = rows.findIndex((r) => r.label === 'stages');
    const dpr = window.devicePixelRatio || 1, y = (4 + i * 19 + 8) * dpr;
    const px = (t) => Array.from(cv.getContext('2d').getImageData(Math.round((v.tlX0 + (v.tlX1 - v.tlX0) * t / v.duration) * dpr), Math.round(y), 1, 1).data).slice(0, 3);
    return [i, px(arguments[0] / 2), px((arguments[0] + v.duration) / 2)];"""
    i, early, late = drv.execute_script(js, impact.time)
    assert i >= 0, "a stages row"
    assert_allclose(early, style.rgb(style.STAGE_COLORS["motion data"]) * 255, atol=3)
    assert_allclose(late, style.rgb(style.STAGE_COLORS["simulation"]) * 255, atol=3)


@pytest.fixture(scope="module")
def walk_page(tmp_path_factory, walk):
    path = tmp_path_factory.mktemp("viz") / "walk.html"
    html.write(path, walk, ["contacts", "com", "support", Marker(0.5, "half a second")])
    return path


def test_centre_of_mass_and_support_polygon(drv, walk_page, walk):
    open_page(drv, walk_page)
    pos, parents, names = world.body_points(walk)
    com = centre_of_mass(pos, parents, world.bone_radii(names, parents, walk.skeleton.height()))
    labels = world.build_world(walk).characters[0]
    from kinodyn import contacts

    on = contacts.detect(walk).as_array()
    feet = labels.feet
    for f in (10, 40, 75):
        s = at(drv, f / walk.fps)["characters"][0]
        assert_allclose(s["com"], com[f], atol=_QUANT, err_msg=f"frame {f}")
        hull = np.array(s["support"])
        planted = np.concatenate([pos[f, feet[side], :2] for k, side in enumerate(("left", "right")) if on[f, k]])
        assert len(hull) >= 3
        assert_allclose(hull.min(axis=0), planted.min(axis=0), atol=_QUANT)
        assert_allclose(hull.max(axis=0), planted.max(axis=0), atol=_QUANT)
        both = on[f].all()
        if both:
            assert s["comInside"], f"frame {f}: in double support the centre of mass is over the polygon"


# --------------------------------------------------------------------------- reading a character


def test_left_and_right_tints_and_a_nose(drv, walk_page):
    open_page(drv, walk_page, "window.kinodynViewer.setView('front')")
    # from the front both sides show (from the side the far limbs hide behind the near ones: a few hundred
    # lighter pixels there, too near any fixed bound); paused so the frame is the same on every run
    drv.execute_script("window.kinodynViewer.pause()")
    at(drv, 0.25, 4)
    img = image(drv)
    base = style.rgb(style.PALETTE[0])
    light = base + (1 - base) * 0.38
    dark = base * 0.62
    n_light = int((np.linalg.norm(img / 255 - light, axis=2) < 0.12).sum())
    n_dark = int((np.linalg.norm(img / 255 - dark, axis=2) < 0.12).sum())
    assert n_light > 200 and n_dark > 200, f"left (lighter) {n_light} px, right (darker) {n_dark} px"
    assert state(drv)["noses"] == 1


def test_trails_and_onion_skins_draw_more(drv, walk_page):
    open_page(drv, walk_page)
    s0 = at(drv, 1.0)
    img0 = image(drv)
    for opt in ("trails", "onion"):
        drv.execute_script(f"window.kinodynViewer.set('{opt}', true)")
        frames(drv)
        img = image(drv)
        changed = int((np.abs(img - img0).max(axis=2) > 40).sum())
        assert changed > 400, f"{opt}: {changed} pixels changed"
        visible = drv.execute_script(f"return window.kinodynViewer.viewer.chars[0].extras.{'trails' if opt == 'trails' else 'onion'}.group.visible")
        assert visible
        drv.execute_script(f"window.kinodynViewer.set('{opt}', false)")
    assert s0["characters"][0]["frame"] == 60


def test_curves_panel_shows_speeds_and_heights_at_the_current_time(drv, walk_page, walk):
    open_page(drv, walk_page, "window.kinodynViewer.set('curves', true)")
    pos, _, names = world.body_points(walk)
    feet = world.build_world(walk).characters[0].feet
    marks = []
    for f in (20, 70):
        s = at(drv, f / walk.fps)["curves"]
        v = s["values"]
        assert_allclose(v["height root"], pos[f, 0, 2], atol=_QUANT)
        assert_allclose(v["height left foot"], pos[f, feet["left"], 2].min(), atol=_QUANT)
        hand = names.index("LeftHand_end") if "LeftHand_end" in names else names.index("LeftHand")
        speed = np.linalg.norm(pos[f + 1, hand] - pos[f - 1, hand]) * walk.fps / 2
        assert_allclose(v["speed LeftHand"], speed, atol=0.05, rtol=0.02)
        marks.append(s["markX"])
    assert marks[1] > marks[0], "the time mark moves with the time"
    panel = drv.find_element("id", "kd-curves")
    assert panel.is_displayed()
    r = panel.rect
    img = image(drv)[int(r["y"]):int(r["y"] + r["height"]), int(r["x"]):int(r["x"] + r["width"])]
    assert near_color(img, "#111111", 30) > 100, "the current-time mark is drawn"
    assert (img.max(axis=2) - img.min(axis=2) > 60).sum() > 300, "coloured curves are drawn"


# --------------------------------------------------------------------------- comparing


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def test_lanes_put_a_comparison_side_by_side(drv, tmp_path, walk):
    path = tmp_path / "lanes.html"
    html.write(path, {"synced": walk, "unsynced": walk}, ["contacts"], layout="lanes")
    open_page(drv, path)
    s = at(drv, 1.0, 4)
    a, b = (np.array(c["root"]) for c in s["characters"])
    travel = np.array(world.body_points(walk)[0][-1, 0] - world.body_points(walk)[0][0, 0])[:2]
    d = travel / np.linalg.norm(travel)
    assert abs((a - b)[:2] @ d) < 1e-3 and abs((a - b)[:2] @ np.array([d[1], -d[0]])) > 0.5
    rects = [c["label"] for c in s["characters"]]
    assert all(rects) and not _overlap(*rects)
    img = image(drv)
    assert near_color(img, style.PALETTE[0], 40) > 300 and near_color(img, style.PALETTE[1], 40) > 300


def test_an_overlaid_reference_is_ghosted_and_labels_do_not_overlap(drv, tmp_path, walk):
    """Regression: two characters in one place had their labels drawn on top of each other."""
    path = tmp_path / "overlay.html"
    html.write(path, {"hit": walk, "kinematic": html.Actor(walk, ghost=True)}, None)
    open_page(drv, path)
    s = at(drv, 0.5, 4)
    assert [c["ghost"] for c in s["characters"]] == [False, True]
    rects = [c["label"] for c in s["characters"]]
    assert all(rects) and not _overlap(*rects), rects
    assert drv.execute_script("return window.kinodynViewer.viewer.world.ghosts.mesh.material[0].opacity") < 0.5


# --------------------------------------------------------------------------- cameras, loop, markers


def test_camera_presets_and_orthographic(drv, walk_page):
    open_page(drv, walk_page)
    at(drv, 1.0)
    for view, check in (("front", lambda back, f: back[:2] @ f > 0.9), ("side", lambda back, f: abs(back[:2] @ f) < 0.2),
                        ("top", lambda back, f: back[2] > 0.99)):
        drv.execute_script(f"window.kinodynViewer.setView('{view}')")
        frames(drv)
        s = state(drv)
        back = np.array(s["camera"]["position"]) - np.array(s["camera"]["target"])
        back /= np.linalg.norm(back)
        f = drv.execute_script("const v = window.kinodynViewer.viewer; return v.facing(v.camera.position.clone()).toArray()")
        assert check(back, np.array(f[:2])), f"{view}: camera direction {back}, facing {f}"
    drv.execute_script("window.kinodynViewer.set('ortho', true)")
    frames(drv)
    assert state(drv)["camera"]["ortho"]
    assert (image(drv).max(axis=2) - image(drv).min(axis=2) > 60).sum() > 300, "the orthographic view draws"
    drv.execute_script("window.kinodynViewer.set('ortho', false)")


_IN_VIEW = """const v = window.kinodynViewer.viewer, cam = v.activeCamera(), p = new v.camera.position.constructor();
let n = 0, k = 0;
for (const ch of v.chars) for (let i = 0; i < ch.P; i++) {
  p.set(ch.cur[3 * i], ch.cur[3 * i + 1], ch.cur[3 * i + 2]).project(cam);
  n++; if (Math.abs(p.x) <= 1 && Math.abs(p.y) <= 1) k++;
}
return k / n;"""


def test_follow_camera_frames_everyone_after_a_jump(drv, tmp_path, walk):
    """Regression: after scrubbing, the follow camera kept its distance and cut the feet off."""
    far = walk.transformed(np.array([0.0, 4.0, 0.0]))
    path = tmp_path / "spread.html"
    html.write(path, {"a": walk, "b": walk.concatenate(walk).concatenate(walk), "c": far}, None)
    open_page(drv, path)
    at(drv, 0.0, 8)
    assert drv.execute_script(_IN_VIEW) == 1.0
    at(drv, 5.9, 30)  # b has walked 8 m away from the others
    assert drv.execute_script(_IN_VIEW) == 1.0, "every point of every character is in the picture"


def test_loop_toggle_loop_range_and_markers(drv, walk_page):
    open_page(drv, walk_page, "window.kinodynViewer.set('loop', false)")
    drv.execute_script("window.kinodynViewer.seek(1.7); window.kinodynViewer.play()")
    t0 = time.perf_counter()
    while drv.execute_script("return window.kinodynViewer.playing"):
        assert time.perf_counter() - t0 < 20, "a page that does not loop stops at the end"
        time.sleep(0.05)
    assert drv.execute_script("return window.kinodynViewer.time") == pytest.approx(2.0)
    drv.execute_script("window.kinodynViewer.set('loop', true); window.kinodynViewer.setLoopRange(0.5, 0.9);"
                       "window.kinodynViewer.setSpeed(2); window.kinodynViewer.play()")
    seen = set()
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < 3.0:
        seen.add(round(drv.execute_script("return window.kinodynViewer.time"), 3))
        time.sleep(0.05)
    drv.execute_script("window.kinodynViewer.pause(); window.kinodynViewer.setSpeed(1)")
    assert min(seen) >= 0.5 - 1e-6 and max(seen) <= 0.9 + 1e-6, (min(seen), max(seen))
    drv.execute_script("window.kinodynViewer.addMarker(1.25, 'mine')")
    s = state(drv)
    assert [m["t"] for m in s["markers"]] == [0.5, 1.25] and s["loopRange"] == [0.5, 0.9]
    assert [r["label"] for r in drv.execute_script("return window.kinodynViewer.viewer.timelineRows()")][-1] == "markers"


# --------------------------------------------------------------------------- your own files


def test_a_dropped_bvh_file_appears_and_plays(drv, walk_page, walk, tmp_path):
    from kinodyn.io.bvh import write_bvh

    run = library.load("run")
    write_bvh(tmp_path / "run.bvh", run)
    text = (tmp_path / "run.bvh").read_text()
    open_page(drv, walk_page)
    drv.execute_script("""const dt = new DataTransfer();
    dt.items.add(new File([arguments[0]], 'run.bvh', {type: 'text/plain'}));
    window.dispatchEvent(new DragEvent('drop', {dataTransfer: dt, bubbles: true, cancelable: true}));""", text)
    t0 = time.perf_counter()
    while drv.execute_script("return window.kinodynViewer.viewer.chars.length") < 2:
        assert time.perf_counter() - t0 < 20, "the dropped file did not appear"
        time.sleep(0.05)
    s = at(drv, 0.5)
    assert [c["name"] for c in s["characters"]] == ["walk", "run"] and s["characters"][1]["dropped"]
    pos, _, names = world.body_points(run)
    js_names = drv.execute_script("return window.kinodynViewer.viewer.chars[1].spec.pointNames")
    js = np.array(drv.execute_script("return Array.from(window.kinodynViewer.viewer.chars[1].pos)"))
    js = js.reshape(run.num_frames, len(js_names), 3)
    order = [js_names.index(n) for n in names if n in js_names]
    assert len(order) >= run.num_joints
    assert_allclose(js[:, order], pos[:, [n in js_names for n in names]], atol=2e-3)  # cm with 6 decimals
    _, parents, _ = world.body_points(run)
    want = world.bone_radii(names, parents, run.skeleton.height())
    js_r = drv.execute_script("return window.kinodynViewer.viewer.chars[1].spec.radius")
    assert_allclose([js_r[js_names.index(n)] for n in names], want, atol=2e-3, err_msg="the same capsules as Python's")
    drv.execute_script("window.kinodynViewer.seek(0); window.kinodynViewer.play()")
    t0 = time.perf_counter()
    while drv.execute_script("return window.kinodynViewer.viewer.chars[1].frame") < 10:
        assert time.perf_counter() - t0 < 20, "the dropped clip does not play"
        time.sleep(0.05)
    drv.execute_script("window.kinodynViewer.pause()")
    assert severe(drv) == []


def test_in_place_and_snap_to_floor(drv, tmp_path, walk):
    lifted = walk.replace(root_pos=walk.root_pos + np.array([0.0, 0.0, 0.5]))  # floating half a metre up
    path = tmp_path / "lifted.html"
    html.write(path, lifted, None)
    open_page(drv, path, "window.kinodynViewer.set('inPlace', true); window.kinodynViewer.set('snap', true)")
    pos = world.body_points(lifted)[0]
    lowest = pos[..., 2].min()
    roots = [np.array(at(drv, t)["characters"][0]["root"]) for t in (0.2, 1.0, 1.8)]
    for r in roots:
        assert_allclose(r[:2], pos[0, 0, :2], atol=_QUANT, err_msg="in place: the root stays where it starts")
    f = 60
    assert_allclose(roots[1][2], pos[f, 0, 2] - lowest, atol=_QUANT, err_msg="snap: the lowest point is on the floor")


# --------------------------------------------------------------------------- crowds


def test_hundreds_of_characters_play_in_a_few_draw_calls(drv, tmp_path):
    from kinodyn.viz.bench import crowd_scene

    path = tmp_path / "crowd.html"
    html.write(path, crowd_scene(300, 60), ["contacts"], layout="grid")
    open_page(drv, path, "window.kinodynViewer.play()")
    f0 = drv.execute_script("return window.kinodynViewer.renderedFrames")
    frames(drv, 3, timeout=60)
    s = state(drv)
    assert len(s["characters"]) == 300 and s["noses"] == 300
    assert s["drawCalls"] < 40, f"{s['drawCalls']} draw calls for 300 characters"
    assert s["opts"]["labels"] is False, "a crowd's names are off until asked for"
    assert drv.execute_script("return window.kinodynViewer.renderedFrames") > f0
    assert (image(drv).max(axis=2) - image(drv).min(axis=2) > 60).sum() > 2000, "the crowd is drawn"
