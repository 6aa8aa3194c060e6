"""Videos and still frames rendered offscreen with MuJoCo's renderer (EGL, else OSMesa on the CPU).

The same :class:`~kinodyn.viz.world.World` as the HTML viewer is drawn: capsules for bones, a chequered
floor (1 m squares), foot-contact discs, impact arrows, root trajectories, names above heads (placed
apart from each other and the frame counter, sized to the picture: :mod:`kinodyn.viz.labels`), and 2-D
support-phase bars with a playhead at the bottom. Frames go to MP4 (H.264 through the ``imageio-ffmpeg``
wheel, which ships its own ffmpeg), GIF (Pillow) or PNG (one frame).

This module decides what to draw; the MuJoCo drawing itself (the OpenGL context, the scene of
primitives, the pixels) is :mod:`kinodyn.physics.render`, which also picks the offscreen OpenGL backend
(``MUJOCO_GL``: ``osmesa``, ``egl``, ``glfw``). Conventions: Z up, metres, seconds. Images are
``(H, W, 3)`` uint8 RGB, top row first.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.io.atomic import atomic_path
from kinodyn.physics import render as gl
from kinodyn.physics.render import RendererUnavailableError, available, gl_backend
from kinodyn.plotting import style
from kinodyn.viz.labels import draw_text
from kinodyn.viz.world import World, build_world

__all__ = [
    "VIDEO_FORMATS",
    "RenderConfig",
    "RenderResult",
    "Renderer",
    "RendererUnavailableError",
    "available",
    "frames",
    "gl_backend",
    "render",
    "write_video",
]

VIDEO_FORMATS = (".mp4", ".gif", ".png")
_HOLD_IMPACT_S = 0.8  # how long an impact arrow stays visible (as in the page)
_BAR_H = 12  # pixel height of one phase bar
_VIEW_DIR = np.array([0.45, -1.0, 0.42])  # from the target towards the camera (same as the page)


@dataclass(frozen=True)
class RenderConfig:
    """How to film a world.

    Attributes:
        width, height: image size in pixels (made even for video).
        fps: output frames per second; ``None``: the scene's fps capped at 30.
        start, end: scene time range in seconds (``end=None``: to the last frame).
        camera: ``"follow"`` (tracks the characters' middle), ``"orbit"`` (follows and turns
            ``orbit_deg_s`` degrees per second) or ``"fixed"`` (frames the whole scene once).
        azimuth, elevation: camera direction in degrees (MuJoCo convention); ``None``: the page's
            default side view (characters walking along +X go left to right).
        distance: camera distance in metres; ``None``: fit the characters.
        shadows: cast shadows (about twice slower).
        samples: multisampling (antialiasing) samples; 0 (default) is 2 to 3 times faster with OSMesa.
        body: ``"capsules"`` or ``"bones"`` (thin capsules).
        hud: draw the frame counter, names legend and phase bars.
    """

    width: int = 640
    height: int = 360
    fps: float | None = None
    start: float = 0.0
    end: float | None = None
    camera: str = "follow"
    azimuth: float | None = None
    elevation: float | None = None
    distance: float | None = None
    orbit_deg_s: float = 20.0
    shadows: bool = True
    samples: int = 0
    body: str = "capsules"
    hud: bool = True

    def __post_init__(self):
        if not (16 <= int(self.width) <= 4096 and 16 <= int(self.height) <= 4096):
            raise ParameterError(f"width and height must be 16..4096 pixels, got {self.width}x{self.height}")
        if self.fps is not None and not (math.isfinite(self.fps) and 0 < self.fps <= 240):
            raise ParameterError(f"fps must be in (0, 240], got {self.fps}")
        if self.camera not in ("follow", "orbit", "fixed"):
            raise ParameterError(f"camera must be follow, orbit or fixed, got {self.camera!r}")
        if self.body not in ("capsules", "bones"):
            raise ParameterError(f"body must be capsules or bones, got {self.body!r}")
        if not math.isfinite(self.start) or self.start < 0:
            raise ParameterError(f"start must be a time >= 0 s, got {self.start}")
        if self.end is not None and not (math.isfinite(self.end) and self.end >= self.start):
            raise ParameterError(f"end must be a time >= start ({self.start} s), got {self.end}")


@dataclass(frozen=True)
class RenderResult:
    """What :func:`render` wrote: path, frame count, fps, image size and wall time spent."""

    path: Path
    frames: int
    fps: float
    width: int
    height: int
    seconds: float


# --------------------------------------------------------------------------- scene


def _hex_rgb(c: str) -> str:
    return " ".join(f"{v:.3f}" for v in style.rgb(c))


def _model_xml(world: World, cfg: RenderConfig) -> str:
    lo, hi = world.bounds()
    cx, cy = 0.5 * (lo[:2] + hi[:2])
    half = 0.5 * float(max(hi[0] - lo[0], hi[1] - lo[1])) + 12.0
    w, h = int(cfg.width), int(cfg.height)
    floor = world.floor
    return f"""<mujoco model="kinodyn-render">
  <visual>
    <global offwidth="{w}" offheight="{h}" fovy="40"/>
    <quality shadowsize="{2048 if cfg.shadows else 0}" offsamples="{cfg.samples}"/>
    <headlight ambient=".42 .42 .42" diffuse=".45 .45 .45" specular=".05 .05 .05"/>
    <map znear=".01" zfar="60" haze=".25" shadowclip="8"/>
    <rgba haze=".87 .9 .93 1"/>
  </visual>
  <asset>
    <texture type="skybox" builtin="gradient" rgb1=".87 .9 .93" rgb2=".72 .78 .84" width="64" height="256"/>
    <texture name="floor" type="2d" builtin="checker" rgb1="{_hex_rgb(style.GROUND_COLOR)}" rgb2="{_hex_rgb('#e2ded5')}"
             width="256" height="256" mark="edge" markrgb=".72 .74 .77"/>
    <material name="floor" texture="floor" texrepeat=".5 .5" texuniform="true" reflectance="0"/>
  </asset>
  <worldbody>
    <light pos="{cx + 4:.3f} {cy - 6:.3f} 12" dir="-.33 .5 -1" directional="true" castshadow="{'true' if cfg.shadows else 'false'}"
           diffuse=".55 .55 .55" specular=".1 .1 .1"/>
    <geom name="floor" type="plane" pos="{cx:.3f} {cy:.3f} {floor:.4f}" size="{half:.2f} {half:.2f} .1" material="floor"/>
  </worldbody>
</mujoco>"""


# --------------------------------------------------------------------------- drawing


def _interp(ch, t: float) -> np.ndarray:
    f = ch.local_frame(t)  # held at both ends, or looping
    i0 = math.floor(f)
    i1 = min(i0 + 1, ch.num_frames - 1)
    a = f - i0
    return (1 - a) * ch.positions[i0] + a * ch.positions[i1]


class Renderer:
    """Draws a :class:`World` frame by frame; holds an OpenGL context (call :meth:`close`, or use
    ``with``). Mutable: the camera follows the characters from one frame to the next."""

    def __init__(self, world: World, config: RenderConfig = RenderConfig()):
        self.world = world
        w, h = int(config.width) // 2 * 2, int(config.height) // 2 * 2
        self.config = cfg = replace(config, width=w, height=h)
        n_geoms = 64 + sum(2 * len(c.parents) + 8 + 120 for c in world.characters) + 3 * len(world.impacts)
        self._scene = gl.OffscreenScene(_model_xml(world, cfg), w, h, n_geoms)
        self._rgba = [style.rgba(c.color) for c in world.characters]
        self._target = None
        self._fit = None
        self._trails = [self._trail(c) for c in world.characters]
        self._bars = self._phase_bars()
        d = np.asarray(world.view if world.view is not None else _VIEW_DIR, dtype=np.float64)
        self._az = cfg.azimuth if cfg.azimuth is not None else math.degrees(math.atan2(-d[1], -d[0]))
        self._el = cfg.elevation if cfg.elevation is not None else -math.degrees(math.asin(d[2] / np.linalg.norm(d)))
        self._dist = cfg.distance
        self._view = None  # (lookat, distance, azimuth, elevation) of the last frame
        self.label_boxes = np.zeros((0, 4), dtype=np.int64)  # (N, 4) name boxes of the last frame (pixels)

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        if getattr(self, "_scene", None) is not None:
            self._scene.close()
            self._scene = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ------------------------------------------------------------------ helpers
    def _trail(self, ch) -> np.ndarray:
        step = max(1, ch.num_frames // 150)
        pts = ch.positions[::step, 0].copy()
        pts[:, 2] = self.world.floor + 0.01
        return pts

    def _phase_bars(self) -> list[tuple[str, np.ndarray]]:
        """One ``(W, 3)`` uint8 colour row per phase bar (time along x)."""
        w = self.config.width
        dur = max(self.world.duration, 1e-9)
        t = (np.arange(w) + 0.5) / w * dur
        bars = []
        for ph in self.world.phases:
            row = np.full((w, 3), 236, dtype=np.uint8)
            for a, b, lab in ph.spans:
                col = (ph.colors or {}).get(lab) or style.PHASE_COLORS.get(lab, "#888888")
                row[(t >= a) & (t < b)] = (style.rgb(col) * 255).astype(np.uint8)
            bars.append((ph.label, row))
        return bars

    def _fit_distance(self, pts: np.ndarray, target: np.ndarray) -> float:
        """Camera distance that keeps every point of ``pts (N, 3)`` in the picture (as the page does)."""
        az, el = math.radians(self._az), math.radians(self._el)
        fwd = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        tv = math.tan(math.radians(self._scene.fovy) / 2)
        th = tv * self.config.width / self.config.height
        d = pts - target
        need = np.maximum(np.abs(d @ right) / th, np.abs(d @ up) / tv) - d @ fwd
        return max(3.0, float(need.max()) * 1.15 + 0.5)

    def _camera(self, cur: list[np.ndarray], t: float) -> None:
        roots = np.array([c[0] for c in cur])
        centre = 0.5 * (roots.min(axis=0) + roots.max(axis=0))
        centre[2] = max(centre[2] * 0.85, self.world.floor + 0.5)
        cfg = self.config
        if cfg.camera == "fixed":
            if self._target is None:
                lo, hi = self.world.bounds()
                self._target = 0.5 * (lo + hi)
                self._target[2] = self.world.floor + 0.8
                corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
                self._fit = self._fit_distance(corners, self._target)
        else:  # follow: the distance grows at once when someone would leave the picture, shrinks slowly
            tops = np.array([c[np.argmax(c[:, 2])] + (0.0, 0.0, 0.35) for c in cur])  # heads and their names
            self._target = centre if self._target is None else self._target + 0.3 * (centre - self._target)
            need = self._fit_distance(np.concatenate([*cur, tops]), self._target)
            self._fit = need if self._fit is None or need > self._fit else self._fit + 0.05 * (need - self._fit)
        self._view = (self._target.copy(), self._dist or self._fit,
                      self._az + (cfg.orbit_deg_s * (t - cfg.start) if cfg.camera == "orbit" else 0.0), self._el)
        self._scene.begin(*self._view)

    def project(self, points) -> np.ndarray:
        """``(N, 2)`` pixel coordinates (x right, y down, from the top-left corner) of world points
        ``(N, 3)`` in the image of the last :meth:`frame`; NaN for points behind the camera."""
        if getattr(self, "_view", None) is None:
            raise ParameterError("draw a frame first: the camera is placed for each frame")
        lookat, dist, az, el = self._view
        az, el = math.radians(az), math.radians(el)
        fwd = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        rel = np.asarray(points, dtype=np.float64).reshape(-1, 3) - (lookat - dist * fwd)
        depth = rel @ fwd
        tv = math.tan(math.radians(self._scene.fovy) / 2)
        w, h = self.config.width, self.config.height
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (0.5 + 0.5 * (rel @ right) / (depth * tv * w / h)) * w
            y = (0.5 - 0.5 * (rel @ up) / (depth * tv)) * h
        out = np.stack([x, y], axis=-1)
        out[depth <= 0] = np.nan
        return out

    # ------------------------------------------------------------------ one frame
    def frame(self, t: float) -> np.ndarray:
        """The image at scene time ``t`` (s): ``(H, W, 3)`` uint8, top row first (a view of an internal
        buffer: copy it to keep it)."""
        scene = self._scene
        w = self.world
        cur = [_interp(c, t) for c in w.characters]
        self._camera(cur, t)
        thin = self.config.body == "bones"
        show = w.show
        contact_rgba = style.rgba(style.CONTACT_COLOR)
        shadow_rgba = np.array([0, 0, 0, 0.12], dtype=np.float32)
        for i, (ch, p) in enumerate(zip(w.characters, cur)):
            rgba = self._rgba[i]
            for par, child in ch.bones():
                r = 0.3 * ch.radii[child] if thin else ch.radii[child]
                scene.connector("capsule", max(r, 0.008), p[par], p[child], rgba)
            if thin:
                for k in range(len(p)):
                    scene.sphere(p[k], 0.018, rgba)
            scene.disc((p[0, 0], p[0, 1], w.floor + 0.002), 0.3, shadow_rgba)
            if "contacts" in show and ch.contacts is not None and ch.feet:
                f = ch.frame_at(t)
                for k, side in enumerate(("left", "right")):
                    idx = ch.feet.get(side)
                    if idx is not None and len(idx) and ch.contacts[f, k]:
                        c = p[idx].mean(axis=0)
                        scene.disc((c[0], c[1], w.floor + 0.004), 0.1, contact_rgba)
            if "trajectories" in show:
                tr = self._trails[i]
                for a, b in itertools.pairwise(tr):
                    scene.connector("line", 2.0, a, b, rgba)
        if "trajectories" in show:
            for tr in w.trajectories:
                pts = np.asarray(tr.points, dtype=np.float64)
                step = max(1, len(pts) // 300)
                pts = pts[::step]
                col = style.rgba(tr.color)
                for a, b in itertools.pairwise(pts):
                    scene.connector("line", 2.5, a, b, col)
        for im in w.impacts:
            dt = t - im.time
            if -0.02 <= dt <= _HOLD_IMPACT_S:
                alpha = 1.0 if dt <= 0.15 else max(0.0, 1 - (dt - 0.15) / (_HOLD_IMPACT_S - 0.15))
                col = style.rgba(im.color or style.IMPACT_COLOR, alpha)
                p = np.asarray(im.point, dtype=np.float64)
                j = np.asarray(im.impulse, dtype=np.float64)
                mag = float(np.linalg.norm(j))
                length = min(max(0.25, mag * 0.02), 1.2)
                d = j / mag if mag > 1e-9 else np.array([1.0, 0, 0])
                scene.connector("arrow", 0.03, p - d * length, p, col)
                scene.sphere(p, 0.045, col)
        img = scene.finish(None)
        if self.config.hud:
            img = self._draw_text(img, cur, t)
            if self._bars:
                img = self._draw_bars(np.ascontiguousarray(img), t)
        return img

    def _draw_text(self, img: np.ndarray, cur: list[np.ndarray], t: float) -> np.ndarray:
        """The frame counter and the names above the heads, never overlapping (:mod:`kinodyn.viz.labels`)."""
        w = self.world
        nf = w.num_frames
        f = min(math.floor(t * w.fps + 1e-6), nf - 1)
        tops = np.array([p[np.argmax(p[:, 2])] + (0.0, 0.0, 0.2) for p in cur]).reshape(-1, 3)
        anchors = self.project(tops)
        names = [c.name + (" (reference)" if c.ghost else "") for c in w.characters]
        img, self.label_boxes = draw_text(img, f"frame {f} / {nf - 1}  {t:.2f} s", names,
                                          [c.color for c in w.characters], anchors)
        return img

    def _draw_bars(self, img: np.ndarray, t: float) -> np.ndarray:
        h, w = img.shape[:2]
        n = len(self._bars)
        top = h - n * (_BAR_H + 2) - 2
        if top < h // 2:
            return img
        for k, (_, row) in enumerate(self._bars):
            y = top + k * (_BAR_H + 2)
            img[y:y + _BAR_H] = row[None]
        x = round(min(max(t / max(self.world.duration, 1e-9), 0), 1) * (w - 1))
        img[top - 2:h, max(x - 1, 0):x + 1] = 20
        return img


# --------------------------------------------------------------------------- files


def _times(world: World, cfg: RenderConfig) -> np.ndarray:
    fps = cfg.fps or min(world.fps, 30.0)
    end = world.duration if cfg.end is None else min(cfg.end, world.duration)
    n = math.floor((end - cfg.start) * fps + 1e-9) + 1
    return cfg.start + np.arange(max(n, 1)) / fps


def frames(world: World, config: RenderConfig = RenderConfig()) -> Iterator[np.ndarray]:
    """Images of ``world`` at the config's times (copies, safe to keep)."""
    with Renderer(world, config) as r:
        for t in _times(world, config):
            yield r.frame(float(t)).copy()


def write_video(path, images, fps: float, quality: int = 7) -> int:
    """Write ``(H, W, 3)`` uint8 images to ``.mp4``, ``.gif`` or ``.png`` (the first image), atomically.

    Returns the number of frames written.
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in VIDEO_FORMATS:
        raise ParameterError(f"video file must end in {', '.join(VIDEO_FORMATS)}, got {p.name!r}")
    n = 0
    with atomic_path(p, suffix=ext) as tmp:
        if ext == ".png":
            from PIL import Image

            for img in images:
                Image.fromarray(img).save(tmp, format="PNG")
                n = 1
                break
        elif ext == ".gif":
            from PIL import Image

            pics = []
            for img in images:
                pics.append(Image.fromarray(img).quantize(colors=128, method=Image.Quantize.MEDIANCUT,
                                                          dither=Image.Dither.NONE))
            n = len(pics)
            if n:
                pics[0].save(tmp, format="GIF", save_all=True, append_images=pics[1:],
                             duration=max(round(1000 / fps), 20), loop=0, optimize=False, disposal=1)
        else:
            try:
                import imageio_ffmpeg
            except ImportError:
                raise RendererUnavailableError("MP4 needs the imageio-ffmpeg package (pip install 'kinodyn[viz]')") \
                    from None
            writer = None
            try:
                for img in images:
                    if writer is None:
                        h, w = img.shape[:2]
                        writer = imageio_ffmpeg.write_frames(str(tmp), (w, h), fps=fps, codec="libx264",
                                                             pix_fmt_out="yuv420p", quality=quality,
                                                             macro_block_size=2, output_params=["-movflags",
                                                                                                "+faststart"])
                        writer.send(None)
                    writer.send(np.ascontiguousarray(img))
                    n += 1
            finally:
                if writer is not None:
                    writer.close()
        if n == 0:
            raise ParameterError("no frames to write")
    return n


def render(path, motions, overlays=("contacts",), *, names=None, colors=None, layout: str = "world",
           loop_clips: bool = False, config: RenderConfig | None = None, progress=None,
           **config_kw) -> RenderResult:
    """Render motions to a video (``.mp4``, ``.gif``) or a still (``.png`` at ``config.start``).

    Args:
        path: output file; the format follows the ending.
        motions, overlays, names, colors, layout, loop_clips: as :func:`kinodyn.viz.html.write` (clips
            loop or hold their last pose for the video's length; ``layout="lanes"`` films from the front).
        config: a :class:`RenderConfig`; keyword arguments override its fields (``width=320``...).
        progress: optional ``progress(iterable, total=..., desc=...)`` wrapper (e.g. kinodyn.progress).

    Returns:
        :class:`RenderResult`.
    """
    import time

    cfg = replace(config or RenderConfig(), **config_kw)
    world = motions if isinstance(motions, World) else build_world(motions, overlays, names=names, colors=colors,
                                                                   layout=layout, loop_clips=loop_clips)
    fps = cfg.fps or min(world.fps, 30.0)
    times = _times(world, cfg)
    if Path(path).suffix.lower() == ".png":
        times = times[:1]
    t0 = time.perf_counter()
    with Renderer(world, cfg) as r:
        seq = (r.frame(float(t)) for t in times)
        if progress is not None:
            seq = progress(seq, total=len(times), desc=f"render {Path(path).name}")
        n = write_video(path, seq, fps)
        w, h = r.config.width, r.config.height
    return RenderResult(Path(path), n, fps, w, h, time.perf_counter() - t0)
