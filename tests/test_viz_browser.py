"""The viewer page in headless Chromium (Debian's chromium + chromedriver through Selenium).

Skipped, with the reason, when Chromium, chromedriver or Selenium is missing; .ci/run installs them.
WebGL runs on SwiftShader there, so frame rates are those of software rendering.
"""

from __future__ import annotations

import io
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose

from kinodyn.data import library
from kinodyn.viz import browser, html, world
from kinodyn.viz.world import Impact

_REASON = browser.unavailable_reason() or (None if html.bundle_available() else "viewer bundle not built (make)")
pytestmark = pytest.mark.skipif(_REASON is not None, reason=f"headless browser unavailable: {_REASON}")

_PAGE_TIMEOUT_S = 60.0


@pytest.fixture(scope="module")
def drv():
    with browser.chromium(1280, 720) as d:
        yield d


def open_page(drv, path):
    drv.get(path.resolve().as_uri())
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < _PAGE_TIMEOUT_S:
        state = drv.execute_script("const v = window.kinodynViewer; return v ? [v.ready, v.errors.length] : [false, 0]")
        if state[0] or state[1]:
            break
        time.sleep(0.05)
    errors = drv.execute_script("return window.kinodynViewer ? window.kinodynViewer.errors : ['no viewer']")
    assert not errors, errors
    assert drv.execute_script("return window.kinodynViewer.ready"), "page did not finish loading"


def wait_for(drv, js: str, timeout: float = 10.0):
    """Poll ``js`` (an expression) until it is truthy; the page may render a few frames a second only."""
    t0 = time.perf_counter()
    while True:
        v = drv.execute_script(f"return {js}")
        if v or time.perf_counter() - t0 > timeout:
            return v
        time.sleep(0.05)


def severe(drv) -> list[str]:
    return [e["message"] for e in drv.get_log("browser") if e.get("level") == "SEVERE"]


def saturated_pixels(png: bytes) -> int:
    """Pixels with a clearly saturated colour: characters, markers (the floor, sky and UI are greys)."""
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(np.float64) / 255
    sat = img.max(axis=2) - img.min(axis=2)
    return int((sat > 0.25).sum())


@pytest.fixture(scope="module")
def pair_page(tmp_path_factory):
    walk, run = library.load("walk"), library.load("run")
    path = tmp_path_factory.mktemp("viz") / "pair.html"
    html.write(path, {"walk": walk, "run": run.transformed(np.array([0.0, 1.5, 0.0]))},
               ["contacts", "phases", "trajectories", Impact(0.5, (0.5, 1.5, 1.3), (-20.0, 0.0, 0.0), 1)])
    return path


def test_page_plays_without_console_errors(pair_page):
    check = browser.check_page(pair_page, seconds=4.0)  # 4 s: a few frames a second on a busy machine
    assert check.ready
    assert check.console_errors == ()
    assert check.frames_advanced > 10, f"the page played {check.frames_advanced} frames in 4 s"
    assert check.distinct_frames >= 3, "the frame counter did not move"
    assert check.fps > 0, "the page rendered no frame"  # how fast: kinodyn bench viz (page_fps)
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(check.screenshot)).convert("L"))
    assert img.std() > 10, "screenshot is blank"
    assert saturated_pixels(check.screenshot) > 800, "no character drawn"


def test_frame_counter_text_and_controls(drv, pair_page):
    open_page(drv, pair_page)
    drv.execute_script("window.kinodynViewer.pause(); window.kinodynViewer.seekFrame(30)")
    assert drv.execute_script("return window.kinodynViewer.frame") == 30
    counter = "document.getElementById('kd-counter').textContent.replace(/\\s+/g, ' ')"
    assert "frame 30 / 120" in wait_for(drv, f"{counter}.includes('frame 30 /') && {counter}"), "counter text"
    time.sleep(0.5)
    assert drv.execute_script("return window.kinodynViewer.frame") == 30, "paused page advanced"
    drv.find_element("id", "kd-play").click()  # the button plays again
    assert wait_for(drv, "window.kinodynViewer.frame > 30"), "the play button did not restart playback"
    drv.execute_script("window.kinodynViewer.set('style', 'bones'); window.kinodynViewer.set('camera', 'orbit')")
    drv.execute_script("window.kinodynViewer.setSpeed(0.25)")
    time.sleep(0.5)
    assert severe(drv) == []
    assert drv.execute_script("return window.kinodynViewer.errors") == []


def test_page_decodes_the_python_positions(drv, pair_page):
    open_page(drv, pair_page)
    walk = library.load("walk")
    pos, _, _ = world.body_points(walk)
    js = np.array(drv.execute_script("return Array.from(window.kinodynViewer.viewer.chars[0].pos)"))
    js = js.reshape(pos.shape)
    data_scale = drv.execute_script(
        "return JSON.parse(document.getElementById('kinodyn-data').textContent).scenes[0].characters[0].pos.scale")
    assert_allclose(js, pos, atol=0.5 * max(data_scale) + 1e-6)  # float32 in the page


def test_scene_selector(drv, tmp_path):
    walk = library.load("walk")
    path = tmp_path / "scenes.html"
    html.write(path, scenes=[html.Scene(walk, name="one"), html.Scene([walk, walk], None, "two", layout="row")])
    open_page(drv, path)
    from selenium.webdriver.support.ui import Select

    sel = Select(drv.find_element("id", "kd-scene"))
    assert [o.text for o in sel.options] == ["one", "two"]
    sel.select_by_index(1)
    t0 = time.perf_counter()
    while drv.execute_script("return window.kinodynViewer.viewer.chars.length") != 2:
        assert time.perf_counter() - t0 < 10, "second scene did not load"
        time.sleep(0.05)
    assert severe(drv) == []


@pytest.mark.slow
def test_10k_frames_3_characters_under_15_mb_and_plays(tmp_path):
    """The issue's size goal: 10,000 frames x 3 characters in one page < 15 MB that plays in Chromium."""
    from kinodyn.viz.bench import GOAL_HTML_BYTES, long_scene

    motions = long_scene(10_000, 3)
    page = html.write(tmp_path / "10k.html", motions, ("contacts", "phases"))
    assert page.bytes < GOAL_HTML_BYTES, f"{page.bytes / 1e6:.1f} MB"
    check = browser.check_page(page.path, seconds=4.0)
    print(f"\n10k x 3 page: {page.bytes / 1e6:.2f} MB, loads in {check.load_s:.1f} s, "
          f"renders {check.fps:.1f} frames/s in headless Chromium (software WebGL)")
    assert check.ready and check.console_errors == ()
    assert check.total_frames == 10_000
    assert check.frames_advanced > 150, "the 60 fps clock should advance ~240 frames in 4 s"
    assert check.distinct_frames >= 5
    assert check.fps > 0, "the page rendered no frame"  # how fast: kinodyn bench viz (page_fps)
    assert saturated_pixels(check.screenshot) > 300


def test_a_tinted_stage_bar_colours_the_body_by_stage(drv, tmp_path):
    from kinodyn.plotting import style
    from kinodyn.viz.objects import Stages

    walk = library.load("walk")
    path = tmp_path / "stages.html"
    spans = [(0.0, 0.5, "motion data"), (0.5, 1.0, "simulation"), (1.0, 1.5, "transition")]
    html.write(path, walk, [Stages(spans, 0, tint=True)])
    open_page(drv, path)
    own = drv.execute_script("return window.kinodynViewer.viewer.chars[0].spec.color")
    body = "Array.from(window.kinodynViewer.viewer.world.bodies.geometry.attributes.color.array.slice(0, 3))"
    seen = {}
    for t, want in ((0.75, style.STAGE_COLORS["simulation"]), (0.25, style.STAGE_COLORS["motion data"]),
                    (1.8, own)):
        drv.execute_script(f"window.kinodynViewer.pause(); window.kinodynViewer.seek({t})")
        assert wait_for(drv, f"window.kinodynViewer.viewer.chars[0].tintNow === '{want}'"), (t, want)
        seen[t] = drv.execute_script(f"return {body}")
    assert seen[0.75] != seen[0.25] != seen[1.8], "the body's vertex colours follow the stage"
    assert drv.execute_script("return window.kinodynViewer.errors") == []
