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
* ``page_fps_500``: frames per second of a page with 500 characters (:func:`crowd_scene`: built-in clips
  of 2 s in a grid, contacts shown) at 1280x720, and ``page_fps_scene``: of a 20-object scene
  (:func:`object_scene`: 2 characters and 20 props, spheres, boxes, capsules and meshes on their
  trajectories, with contact force arrows), both in the same headless Chromium as ``page_fps``, and
  each against ``bare_webgl_fps`` (``*_vs_bare``): software WebGL on a shared machine is noisy.
"""

from __future__ import annotations

import base64
import tempfile
import time
from pathlib import Path

import numpy as np

from kinodyn.bench import BenchResult

__all__ = ["GOAL_HTML_BYTES", "crowd_scene", "long_scene", "object_scene", "run"]

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


def crowd_scene(characters: int = 500, frames: int = 120) -> list:
    """``characters`` built-in clips of ``frames`` frames (cycled through the library), for a grid page."""
    from kinodyn.data import library

    names = library.names()
    clips = {n: library.load(n) for n in names}
    out = []
    for i in range(characters):
        m = clips[names[i % len(names)]]
        while m.num_frames < frames:
            m = m.concatenate(clips[names[i % len(names)]])
        out.append(m[:frames].replace(name=f"{names[i % len(names)]} {i}"))
    return out


def object_scene(objects: int = 20, seconds: float = 4.0, fps: float = 60.0) -> tuple[list, list]:
    """Two walkers and ``objects`` props (spheres, boxes, capsules and tetrahedra in turn) flying on
    ballistic arcs and bouncing on the floor, spinning, with a force arrow at each bounce. Returns
    ``(motions, overlays)`` for :func:`kinodyn.viz.html.write`."""
    from kinodyn.data import library
    from kinodyn.viz.objects import Forces, Prop

    walk, run_ = library.load("walk"), library.load("run")
    motions = {"walk": walk, "run": run_.transformed(np.array([0.0, 2.0, 0.0]))}
    rng = np.random.default_rng(0)
    t = np.arange(round(seconds * fps)) / fps
    shapes = ("sphere", "box", "capsule", "mesh")
    tet = np.array([[0.1, 0.1, 0.1], [-0.1, -0.1, 0.1], [-0.1, 0.1, -0.1], [0.1, -0.1, -0.1]])
    overlays, hits_t, hits_p = [], [], []
    for k in range(objects):
        shape = shapes[k % 4]
        p0 = np.array([rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(0.5, 2.0)])
        v = np.array([rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5), rng.uniform(1.0, 4.0)])
        z = p0[2] + v[2] * t - 4.905 * t ** 2
        period = 2 * np.sqrt(2 * p0[2] / 9.81 + (v[2] / 9.81) ** 2) + 1e-9
        z = np.abs(np.where(z > 0.15, z, 0.15 + np.abs(np.sin(np.pi * t / period)) * (p0[2] - 0.15)))
        pos = np.stack([p0[0] + v[0] * t, p0[1] + v[1] * t, np.maximum(z, 0.15)], axis=1)
        ang = 2.0 * t * (k + 1) / objects
        quats = np.stack([np.cos(ang / 2), np.sin(ang / 2) * 0.6, np.sin(ang / 2) * 0.8, 0 * ang], axis=1)
        size = {"sphere": (0.15,), "box": (0.15, 0.1, 0.12), "capsule": (0.08, 0.12), "mesh": (0.1,)}[shape]
        overlays.append(Prop(shape, pos, size, quats=quats, fps=fps, label=f"{shape} {k}",
                             vertices=tet if shape == "mesh" else None,
                             faces=[[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]] if shape == "mesh" else None))
        low = np.nonzero(pos[:, 2] <= 0.151)[0]
        hits_t += list(t[low[::10]])
        hits_p += list(pos[low[::10]] - np.array([0.0, 0.0, 0.15]))
    if hits_t:
        overlays.append(Forces(hits_t, hits_p, np.tile([0.0, 0.0, 600.0], (len(hits_t), 1)), hold=0.15))
    return motions, overlays


def _page_fps(res: BenchResult, tmp: Path, seconds: float) -> None:
    from kinodyn.viz import browser, html

    crowd = tmp / "crowd_500.html"
    html.write(crowd, crowd_scene(500), ("contacts",), layout="grid")
    check = browser.check_page(crowd, seconds=seconds, timeout=120.0)
    res.add("page_fps_500", check.fps, "frames/s")
    res.add("page_load_s_500", check.load_s, "s")
    res.add("page_console_errors_500", len(check.console_errors), "count")
    motions, overlays = object_scene()
    scene = tmp / "scene_20_objects.html"
    html.write(scene, motions, ["contacts", *overlays])
    check = browser.check_page(scene, seconds=seconds)
    res.add("page_fps_scene", check.fps, "frames/s")
    res.add("page_console_errors_scene", len(check.console_errors), "count")


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
        _page_fps(res, tmp, seconds)
        if res.baseline["bare_webgl_fps"] > 0:
            for key in ("page_fps", "page_fps_500", "page_fps_scene"):
                res.add(f"{key}_vs_bare", res.metrics[key] / res.baseline["bare_webgl_fps"], "x")
    else:
        res.notes["page"] = f"not measured: {reason}"
    return res


def _render_reason() -> str | None:
    from kinodyn.viz.render import available

    return available()
