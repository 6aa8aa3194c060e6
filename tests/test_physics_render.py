"""kinodyn.physics.render: which offscreen OpenGL backend is used, what "unavailable" means, who imports
MuJoCo.

The backend choice is tested with a stand-in for the probe (so it runs the same on any machine); one test
probes for real."""

from __future__ import annotations

import ast
import sys
import types
from pathlib import Path

import pytest

pytest.importorskip("mujoco")

from kinodyn.physics import render

SRC = Path(__file__).resolve().parents[1] / "src" / "kinodyn"


@pytest.fixture
def clean_env(monkeypatch):
    """No MUJOCO_GL, no PyOpenGL platform, no display; a fresh choice; the probe recorded."""
    for var in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setattr(render, "_chosen", {})
    tried = []

    def use(works):
        def probe(b):
            tried.append(b)
            return None if b in works else f"{b} is missing here"

        monkeypatch.setattr(render, "probe", probe)
        return tried

    return use


def test_egl_is_tried_first_when_mujoco_gl_is_unset(clean_env):
    tried = clean_env({"egl", "osmesa"})
    assert render.gl_backend() == "egl"
    assert tried == ["egl"]


def test_osmesa_when_egl_fails(clean_env):
    tried = clean_env({"osmesa"})
    assert render.gl_backend() == "osmesa"
    assert tried == ["egl", "osmesa"]
    render.gl_backend()
    assert tried == ["egl", "osmesa"], "the choice is made once per process"


def test_glfw_only_with_a_display(clean_env, monkeypatch):
    tried = clean_env({"glfw"})
    with pytest.raises(render.RendererUnavailableError):
        render.gl_backend()
    assert tried == ["egl", "osmesa"]
    monkeypatch.setenv("DISPLAY", ":0")
    tried.clear()
    assert render.gl_backend() == "glfw"
    assert tried == ["egl", "osmesa", "glfw"]


def test_none_works_names_every_backend_tried_and_what_it_needs(clean_env):
    clean_env(set())
    with pytest.raises(render.RendererUnavailableError) as e:
        render.gl_backend()
    msg = str(e.value)
    assert "egl (egl is missing here)" in msg and "osmesa (osmesa is missing here)" in msg
    assert "libosmesa6" in msg and "MUJOCO_GL" in msg
    assert render.available() == msg


def test_mujoco_gl_is_the_only_backend_tried_when_set(clean_env, monkeypatch):
    tried = clean_env({"egl", "osmesa"})
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    assert render.gl_backend() == "osmesa" and tried == ["osmesa"]
    monkeypatch.setenv("MUJOCO_GL", "egl")
    monkeypatch.setattr(render, "probe", lambda b: "no EGL display")
    with pytest.raises(render.RendererUnavailableError, match=r"tried egl \(no EGL display\)"):
        render.gl_backend()


def test_a_pyopengl_platform_already_chosen_is_kept(clean_env, monkeypatch):
    tried = clean_env({"egl", "osmesa"})
    monkeypatch.setenv("PYOPENGL_PLATFORM", "osmesa")
    assert render.gl_backend() == "osmesa" and tried == ["osmesa"]


def _fake_backend(monkeypatch, error: Exception):
    class GLContext:
        def __init__(self, w, h):
            raise error

    monkeypatch.setattr(render, "gl_backend", lambda: "egl")
    monkeypatch.setitem(sys.modules, "mujoco.egl", types.SimpleNamespace(GLContext=GLContext))


def test_a_context_that_cannot_be_made_is_unavailable(monkeypatch):
    _fake_backend(monkeypatch, RuntimeError("Failed to create EGL context"))
    with pytest.raises(render.RendererUnavailableError, match="Failed to create EGL context"):
        render.gl_context(32, 32)


def test_other_errors_pass_through_instead_of_reading_unavailable(monkeypatch):
    """Regression: every exception used to become "unavailable", which hid bugs and skipped the render
    tests."""
    _fake_backend(monkeypatch, TypeError("a bug in the caller"))
    with pytest.raises(TypeError, match="a bug in the caller"):
        render.gl_context(32, 32)


def test_the_probe_runs_in_a_fresh_process_and_reports_why():
    why = render.probe("nosuchbackend")
    assert why is not None and "nosuchbackend" in why


def _imports_mujoco(path: Path) -> bool:
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "mujoco" for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "mujoco" and not node.level:
            return True
    return False


def test_only_the_physics_package_imports_mujoco():
    """DESIGN.md: only physics and the capabilities built on it import mujoco; viz films through
    kinodyn.physics.render."""
    built_on_physics = {"physics", "response", "contact", "crowd", "scene"}
    outside = sorted(str(p.relative_to(SRC)) for p in SRC.rglob("*.py")
                     if _imports_mujoco(p) and p.relative_to(SRC).parts[0] not in built_on_physics)
    assert outside == []
