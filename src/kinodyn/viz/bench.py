"""Visualisation benchmark: viewer page size and write time, video render speed, page frame rate.

``kinodyn bench viz [--quick] --json FILE`` reports, for a 10,000-frame, 3-character scene made of
built-in clips strung together (:func:`long_scene`; 60 fps, 26 points per character):

* ``html_bytes_10k_3chars``: size of the page :func:`kinodyn.viz.html.write` writes (goal: < 15 MB);
* ``html_write_s``: seconds to build and write it (forward kinematics, contacts, encoding included);
* ``html_bytes_per_frame_char``: bytes per character frame, and ``raw_ratio``: the page's motion data
  against the baseline of the same positions embedded as float32 base64 (what a naive page would do);
* ``render_fps``: frames per second of :func:`kinodyn.viz.render.render` to MP4 at 640x360 (the 3
  characters; OSMesa on the CPU), and ``render_fps_fast`` without shadows;
* ``page_fps``: frames per second the page renders in headless Chromium (SwiftShader, software WebGL)
  while playing the 10,000-frame scene at 1280x720, ``page_load_s``, and the baseline
  ``bare_webgl_fps``: the same browser clearing a WebGL canvas of the same size and nothing else.
  Measured only when Chromium, chromedriver and Selenium are installed.
"""

from __future__ import annotations

import base64
import tempfile
import time
from pathlib import Path

import numpy as np

from kinodyn.bench import BenchResult

__all__ = ["GOAL_HTML_BYTES", "long_scene", "run"]

GOAL_HTML_BYTES = 15e6
_SEQUENCES = (("walk", "turn_right"), ("run", "turn_left"), ("step_forward_large", "punch", "step_back_large",
                                                            "kick", "idle"))
_BARE_PAGE = """<!DOCTYPE html><html><body style="margin:0"><canvas id="c" style="width:100vw;height:100vh;
display:block"></canvas><script>const c=document.getElementById('c');const gl=c.getContext('webgl2',
{antialias:false});c.width=innerWidth;c.height=innerHeight;let n=0;function f(){gl.clearColor(n%2,.5,.5,1);
gl.clear(gl.COLOR_BUFFER_BIT);n++;requestAnimationFrame(f);}requestAnimationFrame(f);
window.kinodynViewer={ready:true,get renderedFrames(){return n},frame:0,play(){},totalFrames:1,errors:[]};
</script></body></html>"""


def long_scene(frames: int = 10_000, characters: int = 3) -> list:
    """``characters`` motions of exactly ``frames`` frames: built-in clips strung together (aligned on the
    floor), each character on its own loop a few metres from the others."""
    from kinodyn.data import library

    have = set(library.names())
    out = []
    for i in range(characters):
        seq = [n for n in _SEQUENCES[i % len(_SEQUENCES)] if n in have] or [library.names()[0]]
        clips = [library.load(n) for n in seq]
        m = clips[0]
        k = 1
        while m.num_frames < frames:
            m = m.concatenate(clips[k % len(clips)])
            k += 1
        m = m[:frames].transformed(np.array([0.0, 4.0 * i, 0.0])).replace(name=f"{'+'.join(seq)}")
        out.append(m)
    return out


def run(quick: bool = False, progress=None) -> BenchResult:
    from kinodyn.viz import browser, html
    from kinodyn.viz.world import body_points

    res = BenchResult("viz")
    motions = long_scene()
    tmp = Path(tempfile.mkdtemp(prefix="kinodyn-bench-viz-"))
    page = tmp / "10k_3chars.html"
    t0 = time.perf_counter()
    info = html.write(page, motions, ("contacts", "phases"))
    res.add("html_write_s", time.perf_counter() - t0, "s")
    res.add("html_bytes_10k_3chars", info.bytes, "bytes")
    points = sum(body_points(m)[0].shape[1] for m in motions) // len(motions)
    res.add("points_per_char", points, "points")
    res.add("html_bytes_per_frame_char", info.bytes / (10_000 * len(motions)), "bytes")
    naive = sum(len(base64.b64encode(body_points(m)[0].astype(np.float32).tobytes())) for m in motions)
    res.baseline["float32_base64_bytes"] = float(naive)
    res.add("raw_ratio", info.bytes / naive, "x")
    res.add("html_under_goal", float(info.bytes < GOAL_HTML_BYTES), "bool")

    reason = _render_reason()
    if reason is None:
        from kinodyn.viz.render import render

        n = 30 if quick else 120
        short = [m[:n * 2] for m in motions]  # 60 fps clips, rendered at 30 fps: n frames
        for key, kw in (("render_fps", {}), ("render_fps_fast", {"shadows": False})):
            r = render(tmp / f"{key}.mp4", short, ("contacts",), width=640, height=360, fps=30, **kw)
            res.add(key, r.frames / r.seconds, "frames/s")
    else:
        res.notes["render"] = f"not measured: {reason}"

    reason = browser.unavailable_reason()
    if reason is None:
        seconds = 3.0 if quick else 8.0
        check = browser.check_page(page, seconds=seconds)
        res.add("page_fps", check.fps, "frames/s")
        res.add("page_load_s", check.load_s, "s")
        res.add("page_console_errors", len(check.console_errors), "count")
        bare = tmp / "bare.html"
        bare.write_text(_BARE_PAGE)
        res.baseline["bare_webgl_fps"] = browser.check_page(bare, seconds=min(seconds, 4.0)).fps
        if res.baseline["bare_webgl_fps"] > 0:
            res.add("page_fps_vs_bare", check.fps / res.baseline["bare_webgl_fps"], "x")
    else:
        res.notes["page"] = f"not measured: {reason}"
    return res


def _render_reason() -> str | None:
    from kinodyn.viz.render import available

    return available()
