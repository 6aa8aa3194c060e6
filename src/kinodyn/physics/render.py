"""Offscreen OpenGL drawing with MuJoCo's renderer: a context, a scene of primitives, pixels back.

The MuJoCo half of :mod:`kinodyn.viz.render` (which decides what to draw): :func:`gl_context` opens an
offscreen OpenGL context, :class:`OffscreenScene` holds a model compiled from MJCF text (floor, lights,
sky), adds capsules, spheres, discs, lines and arrows as decoration geoms each frame, renders them with a
free camera, writes an overlay text and reads the pixels back.

Backends: ``egl`` (a GPU or Mesa's EGL, no display needed), ``osmesa`` (the CPU, Debian:
``apt-get install libosmesa6``) and ``glfw`` (needs a display). ``MUJOCO_GL`` chooses one; unset, the
first that makes a context is used, tried in that order (:func:`gl_backend`), and when none does the
error names each one tried and why it failed. Only a context that cannot be made means "unavailable";
any other error passes through. Images are ``(H, W, 3)`` uint8 RGB, top
row first. Conventions: Z up, metres; the camera's azimuth and elevation in degrees (MuJoCo's).
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import mujoco
import numpy as np

from kinodyn.errors import KinodynError

__all__ = [
    "BACKENDS",
    "OffscreenScene",
    "RendererUnavailableError",
    "available",
    "candidates",
    "gl_backend",
    "gl_context",
    "probe",
]


class RendererUnavailableError(KinodynError, RuntimeError):
    """No offscreen OpenGL context could be created (OSMesa/EGL missing) or MuJoCo is not installed."""


#: the offscreen backends, in the order they are tried when ``MUJOCO_GL`` is unset (``glfw`` only with a
#: display)
BACKENDS = ("egl", "osmesa", "glfw")
#: what each backend needs
HINTS = {
    "egl": "EGL: a GPU driver or Mesa's EGL (Debian: apt-get install libegl1 libgl1-mesa-dri)",
    "osmesa": "OSMesa, on the CPU (Debian: apt-get install libosmesa6)",
    "glfw": "GLFW: a display (DISPLAY or WAYLAND_DISPLAY) and the glfw package",
}
ERR_NONE_WORKS = ("no offscreen OpenGL backend works here; tried {tried}. Install one of: {hints}; or set "
                  "MUJOCO_GL to one that works")
ERR_BAD_GL = "MUJOCO_GL must be one of {options} for offscreen rendering, got {value!r}"

#: a fresh interpreter makes a context: PyOpenGL fixes its platform at its first import, so each backend
#: is tried in a process of its own
_PROBE = "from mujoco.{b} import GLContext\nc = GLContext(32, 32)\nc.make_current()\nc.free()\n"
_PROBE_TIMEOUT_S = 120.0
_chosen: dict[tuple, str] = {}
_lock = threading.Lock()


def candidates() -> tuple[str, ...]:
    """The backends to try, in order: ``MUJOCO_GL`` alone when it is set; the platform PyOpenGL is
    already fixed to (``PYOPENGL_PLATFORM``) alone; else EGL, then OSMesa, then GLFW when there is a
    display.

    Raises:
        RendererUnavailableError: ``MUJOCO_GL`` names no offscreen backend.
    """
    for var in ("MUJOCO_GL", "PYOPENGL_PLATFORM"):
        b = os.environ.get(var, "").strip().lower()
        if b:
            if b not in BACKENDS:
                raise RendererUnavailableError(ERR_BAD_GL.format(options=", ".join(BACKENDS), value=b)
                                               .replace("MUJOCO_GL", var))
            return (b,)
    display = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    return BACKENDS if display else BACKENDS[:2]


def probe(backend: str) -> str | None:
    """``None`` when a fresh Python process makes an offscreen context with ``backend``, else why not
    (the last line of its error)."""
    env = {k: v for k, v in os.environ.items() if k != "PYOPENGL_PLATFORM"}
    env["MUJOCO_GL"] = backend
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE.format(b=backend)], env=env, capture_output=True,
                           text=True, timeout=_PROBE_TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired:
        return f"no context within {_PROBE_TIMEOUT_S:g} s"
    if r.returncode == 0:
        return None
    lines = [ln.strip() for ln in r.stderr.splitlines() if ln.strip()]
    return lines[-1] if lines else f"exit status {r.returncode}"


def gl_backend() -> str:
    """The offscreen OpenGL backend to use here: the first of :func:`candidates` that makes a context
    (tried once per process and setting).

    Raises:
        RendererUnavailableError: none works; the message names each backend tried, why it failed and
            what it needs.
    """
    order = candidates()
    key = (order, os.environ.get("MUJOCO_GL"), os.environ.get("PYOPENGL_PLATFORM"))
    with _lock:
        if key in _chosen:
            return _chosen[key]
        tried = []
        for b in order:
            why = probe(b)
            if why is None:
                _chosen[key] = b
                return b
            tried.append(f"{b} ({why})")
    raise RendererUnavailableError(ERR_NONE_WORKS.format(tried="; ".join(tried),
                                                         hints="; ".join(HINTS[b] for b in order)))


def gl_context(width: int, height: int):
    """An offscreen OpenGL context of ``width`` x ``height`` pixels with the backend of
    :func:`gl_backend`, made current.

    Raises:
        RendererUnavailableError: no backend works here, or the context could not be created (a library
            missing, or the driver refused); other errors are bugs and pass through as they are.
    """
    import importlib

    backend = gl_backend()
    try:
        module = importlib.import_module(f"mujoco.{backend}")
        ctx = module.GLContext(width, height)
        ctx.make_current()
    except (ImportError, OSError, RuntimeError) as e:
        raise RendererUnavailableError(f"cannot create an offscreen OpenGL context with {backend}: {e} "
                                       f"(needs {HINTS[backend]})") from e
    except Exception as e:
        from OpenGL import error as gl_error

        if isinstance(e, gl_error.Error):
            raise RendererUnavailableError(f"cannot create an offscreen OpenGL context with {backend}: {e} "
                                           f"(needs {HINTS[backend]})") from e
        raise
    return ctx


def available() -> str | None:
    """``None`` when images can be rendered here, else the reason why not."""
    try:
        gl_backend()
    except RendererUnavailableError as e:
        return str(e)
    return None


#: decoration geom types by name
_GEOMS = {"capsule": mujoco.mjtGeom.mjGEOM_CAPSULE, "line": mujoco.mjtGeom.mjGEOM_LINE,
          "arrow": mujoco.mjtGeom.mjGEOM_ARROW, "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
          "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER}


class OffscreenScene:
    """A MuJoCo model (from MJCF text) drawn offscreen with decoration geoms added each frame (mutable;
    holds an OpenGL context: call :meth:`close`, or use ``with``).

    Each frame: :meth:`begin` (camera), then :meth:`connector`, :meth:`sphere`, :meth:`disc`, then
    :meth:`finish` for the pixels. At most ``max_geoms`` geoms are drawn per frame (more are dropped).
    """

    def __init__(self, xml: str, width: int, height: int, max_geoms: int):
        self._ctx = gl_context(width, height)
        try:
            self.model = mujoco.MjModel.from_xml_string(xml)
            self.data = mujoco.MjData(self.model)
            mujoco.mj_forward(self.model, self.data)
            self._con = mujoco.MjrContext(self.model, mujoco.mjtFontScale.mjFONTSCALE_100)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._con)
        except Exception:
            self._ctx.free()
            raise
        self._scn = mujoco.MjvScene(self.model, max_geoms)
        self._opt = mujoco.MjvOption()
        self._pert = mujoco.MjvPerturb()
        self._cam = mujoco.MjvCamera()
        self._cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self._rgb = np.empty((height, width, 3), dtype=np.uint8)

    @property
    def fovy(self) -> float:
        """Vertical field of view (degrees)."""
        return float(self.model.vis.global_.fovy)

    def close(self) -> None:
        if getattr(self, "_ctx", None) is not None:
            self._con.free()
            self._ctx.free()
            self._ctx = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def begin(self, lookat, distance: float, azimuth: float, elevation: float) -> None:
        """Start a frame: the model's own geoms seen from a free camera looking at ``lookat (3,)``."""
        cam = self._cam
        cam.lookat[:] = lookat
        cam.distance = distance
        cam.azimuth = azimuth
        cam.elevation = elevation
        mujoco.mjv_updateScene(self.model, self.data, self._opt, self._pert, cam, mujoco.mjtCatBit.mjCAT_ALL,
                               self._scn)

    def _geom(self, kind: str, rgba, label: str = ""):
        scn = self._scn
        if scn.ngeom >= scn.maxgeom:
            return None
        g = scn.geoms[scn.ngeom]
        mujoco.mjv_initGeom(g, _GEOMS[kind], np.zeros(3), np.zeros(3), np.eye(3).ravel(), rgba)
        if label:
            g.label = label
        scn.ngeom += 1
        return g

    def connector(self, kind: str, width: float, a, b, rgba) -> None:
        """A ``"capsule"``, ``"line"`` or ``"arrow"`` from ``a (3,)`` to ``b (3,)`` (nothing when they
        meet); ``width`` in metres (pixels for lines)."""
        if np.linalg.norm(np.asarray(b) - np.asarray(a)) < 1e-6:
            return
        g = self._geom(kind, rgba)
        if g is not None:
            mujoco.mjv_connector(g, _GEOMS[kind], width, np.asarray(a, dtype=np.float64),
                                 np.asarray(b, dtype=np.float64))

    def sphere(self, p, r: float, rgba, label: str = "") -> None:
        """A sphere of radius ``r`` at ``p (3,)``, with an optional text label."""
        g = self._geom("sphere", rgba, label)
        if g is not None:
            g.size[:] = r
            g.pos[:] = p

    def disc(self, p, r: float, rgba) -> None:
        """A flat disc of radius ``r`` centred at ``p (3,)``."""
        g = self._geom("cylinder", rgba)
        if g is not None:
            g.size[:] = (r, r, 0.003)
            g.pos[:] = p

    def finish(self, overlay: tuple[str, str] | None = None) -> np.ndarray:
        """Render the frame, with ``overlay`` (left and right column of text) at the top left; the image
        ``(H, W, 3)`` uint8, top row first (a view of an internal buffer: copy it to keep it)."""
        mujoco.mjr_render(self._rect, self._scn, self._con)
        if overlay is not None:
            mujoco.mjr_overlay(mujoco.mjtFont.mjFONT_NORMAL, mujoco.mjtGridPos.mjGRID_TOPLEFT, self._rect,
                               overlay[0], overlay[1], self._con)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._con)
        return self._rgb[::-1]
