"""Offscreen OpenGL drawing with MuJoCo's renderer: a context, a scene of primitives, pixels back.

The MuJoCo half of :mod:`kinodyn.viz.render` (which decides what to draw): :func:`gl_context` opens an
offscreen OpenGL context, :class:`OffscreenScene` holds a model compiled from MJCF text (floor, lights,
sky), adds capsules, spheres, discs, lines and arrows as decoration geoms each frame, renders them with a
free camera, writes an overlay text and reads the pixels back.

Backends (``MUJOCO_GL``): ``egl`` (GPU or Mesa's EGL, no display needed), ``osmesa`` (CPU, Debian:
``apt-get install libosmesa6``) and ``glfw`` (needs a display). Images are ``(H, W, 3)`` uint8 RGB, top
row first. Conventions: Z up, metres; the camera's azimuth and elevation in degrees (MuJoCo's).
"""

from __future__ import annotations

import os

import mujoco
import numpy as np

from kinodyn.errors import KinodynError

__all__ = ["OffscreenScene", "RendererUnavailableError", "available", "gl_backend", "gl_context"]


class RendererUnavailableError(KinodynError, RuntimeError):
    """No offscreen OpenGL context could be created (OSMesa/EGL missing) or MuJoCo is not installed."""


def gl_backend() -> str:
    """The offscreen OpenGL backend to use: ``MUJOCO_GL`` if set, else ``osmesa`` without a display."""
    b = os.environ.get("MUJOCO_GL", "").strip().lower()
    if b in ("osmesa", "egl", "glfw"):
        return b
    return "glfw" if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") else "osmesa"


def gl_context(width: int, height: int):
    """An offscreen OpenGL context of ``width`` x ``height`` pixels, made current.

    Raises:
        RendererUnavailableError: the backend cannot create one.
    """
    backend = gl_backend()
    try:
        if backend == "osmesa":
            from mujoco.osmesa import GLContext
        elif backend == "egl":
            from mujoco.egl import GLContext
        else:
            from mujoco.glfw import GLContext
        ctx = GLContext(width, height)
    except Exception as e:  # noqa: BLE001 - ImportError, RuntimeError, PyOpenGL's errors, ctypes errors
        hint = " (Debian: apt-get install libosmesa6)" if backend == "osmesa" else ""
        raise RendererUnavailableError(f"cannot create an offscreen OpenGL context with {backend}: {e}{hint}") \
            from None
    ctx.make_current()
    return ctx


def available() -> str | None:
    """``None`` when images can be rendered here, else the reason why not."""
    try:
        ctx = gl_context(32, 32)
    except RendererUnavailableError as e:
        return str(e)
    ctx.free()
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
