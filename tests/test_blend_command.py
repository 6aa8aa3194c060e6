"""``kinodyn blend``'s outputs for seeing a blend: the viewer page with support phases on its timeline,
the comparison in lanes, and the feet figure among the plots."""

from __future__ import annotations

import json
import re
import time

import pytest

from kinodyn.cli import main
from kinodyn.viz import browser, html

_SCRIPT = "fps: 30\nactions:\n  - {clip: walk, start: 0, stop: 1.5, priority: 1}\n  - {clip: run, start: 1.2, stop: 2.5, priority: 1}\n"


@pytest.mark.skipif(not html.bundle_available(), reason="viewer bundle not built (run make)")
def test_blend_page_has_support_phases_on_and_the_comparison_in_lanes(tmp_path, capsys):
    script = tmp_path / "s.yaml"
    script.write_text(_SCRIPT)
    page = tmp_path / "s.html"
    plots = tmp_path / "plots"
    assert main(["blend", str(script), "-o", str(tmp_path / "s.bvh"), "--compare", "--html", str(page),
                 "--plots", str(plots)]) == 0
    data = json.loads(re.search(r'id="kinodyn-data">(.*?)</script>', page.read_text(), re.DOTALL).group(1))
    (scene,) = data["scenes"]
    assert data["options"]["phases"] is True and data["options"]["contacts"] is True
    # one support bar a character: the rows of the page's timeline
    assert [p["label"] for p in scene["phases"]] == ["synchronized support", "not synchronized support"]
    assert {lab for p in scene["phases"] for _, _, lab in p["spans"]} <= {"LS", "RS", "DS", "FLIGHT"}
    assert scene["view"] is not None  # lanes: side by side, filmed from the front
    assert (plots / "s_feet.png").stat().st_size > 10_000
    assert "s_feet.png" in capsys.readouterr().out


@pytest.mark.skipif((browser.unavailable_reason() or (None if html.bundle_available() else "no bundle")) is not None,
                    reason="headless browser unavailable")
def test_blend_page_shows_the_timeline(tmp_path):
    script = tmp_path / "s.yaml"
    script.write_text(_SCRIPT)
    page = tmp_path / "s.html"
    assert main(["blend", str(script), "-o", str(tmp_path / "s.bvh"), "--html", str(page)]) == 0
    with browser.chromium(960, 600) as drv:
        drv.get(page.resolve().as_uri())
        t0 = time.perf_counter()
        while not drv.execute_script("const v = window.kinodynViewer; return v && (v.ready || v.errors.length)"):
            assert time.perf_counter() - t0 < 60, "page did not finish loading"
            time.sleep(0.05)
        assert drv.execute_script("return window.kinodynViewer.errors") == []
        tl = drv.find_element("id", "kd-timeline")
        assert tl.is_displayed() and tl.size["height"] >= 16
