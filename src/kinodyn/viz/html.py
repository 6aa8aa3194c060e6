"""A self-contained HTML viewer: one file that plays characters in a shared world, offline.

The page inlines everything: the viewer code bundled with three.js (``assets/viewer.js``, built from
``viz-js/`` by ``make``), the page template (``assets/viewer.html``) and the motion data. No CDN, no
server: open it from disk in any current browser, mail it, attach it to an issue.

Motion data: per character, the world positions of joints and end sites ``(F, P, 3)`` quantized to
int16 over the character's bounding box (about 1 mm steps for a 65 m box), delta-coded along frames,
byte planes split, zlib-compressed and base64-encoded: a 10,000-frame, 3-character scene of the built-in
skeleton (26 points each) makes a 3 MB page (``kinodyn bench viz``). Browsers decode it with
``DecompressionStream``.

Typical use::

    from kinodyn.viz import html
    html.write("out/walk.html", motion)                                  # one clip
    html.write("out/pair.html", {"A": a, "B": b}, overlays=["contacts", "phases",
               html.Impact(time=1.2, point=(0.3, 0, 1.4), impulse=(-30, 0, 0), character=1)])
    html.write("out/ranked.html", scenes=[html.Scene(ms, name=f"#{i} score {s:.2f}") ...])
"""

from __future__ import annotations

import base64
import json
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from html import escape
from importlib import resources
from pathlib import Path

import numpy as np

from kinodyn.errors import KinodynError, ParameterError
from kinodyn.io.atomic import atomic_write_bytes
from kinodyn.plotting import style
from kinodyn.version import __version__
from kinodyn.viz.objects import Forces, Marker, Prop, Stages, check_prop
from kinodyn.viz.world import RADIUS_RULES, Actor, Contacts, Impact, Phases, Trajectory, World, build_world

__all__ = [
    "CAMERAS",
    "FORMAT_VERSION",
    "STYLES",
    "Actor",
    "AssetMissingError",
    "Contacts",
    "Forces",
    "Impact",
    "Marker",
    "Phases",
    "Prop",
    "Scene",
    "Stages",
    "Trajectory",
    "ViewerPage",
    "bundle_available",
    "decode_positions",
    "encode_positions",
    "scene_data",
    "to_html",
    "write",
]

FORMAT_VERSION = 1
STYLES = ("capsules", "bones")
CAMERAS = ("follow", "orbit", "free")
_ASSETS = "assets"
_BUNDLE = "viewer.js"
_TEMPLATE = "viewer.html"

MSG_BUNDLE_MISSING = (
    "the viewer bundle kinodyn/viz/assets/viewer.js is missing: it is built from viz-js/ with npm "
    "(three.js). Run 'make' in the repository (or: cd viz-js && npm ci && npm run build); that needs node, "
    "npm and the npm registry")


class AssetMissingError(KinodynError, RuntimeError):
    """A file the viewer needs was not built or not installed with the package."""


@dataclass(frozen=True)
class Scene:
    """One scene of a page with several (a ranked set of scenes, variants to compare).

    Attributes mirror :func:`write`'s arguments; ``name`` labels the scene in the page's selector.
    """

    motions: object
    overlays: object = ("contacts",)
    name: str = ""
    names: Sequence[str] | None = None
    colors: Sequence[str] | None = None
    layout: str = "world"
    loop_clips: bool = False


@dataclass(frozen=True)
class ViewerPage:
    """What :func:`write` wrote: ``path``, size in ``bytes``, and per scene (name, characters, frames)."""

    path: Path
    bytes: int
    scenes: tuple[tuple[str, int, int], ...] = field(default_factory=tuple)


def _asset(name: str) -> str:
    res = resources.files("kinodyn.viz").joinpath(_ASSETS, name)
    try:
        return res.read_text(encoding="utf-8")
    except (FileNotFoundError, OSError):
        if name == _BUNDLE:
            raise AssetMissingError(MSG_BUNDLE_MISSING) from None
        raise AssetMissingError(f"kinodyn/viz/assets/{name} is missing from the installed package") from None


def bundle_available() -> bool:
    """Whether the three.js viewer bundle was built (``make`` builds it)."""
    return resources.files("kinodyn.viz").joinpath(_ASSETS, _BUNDLE).is_file()


# --------------------------------------------------------------------------- encoding


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def encode_positions(pos: np.ndarray, compress: bool = True) -> dict:
    """Encode ``(F, P, 3)`` positions for the page (see the module docstring); returns a JSON-able dict.

    The decoded value is ``origin + (q + 32768) * scale`` per axis; the error is at most ``scale / 2``.
    """
    pos = np.asarray(pos, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[2] != 3:
        raise ParameterError(f"positions must have shape (F, P, 3), got {pos.shape}")
    if not np.all(np.isfinite(pos)):
        raise ParameterError("positions must be finite, found NaN or inf")
    flat = pos.reshape(len(pos), -1, 3)
    lo = flat.reshape(-1, 3).min(axis=0)
    hi = flat.reshape(-1, 3).max(axis=0)
    scale = np.maximum(hi - lo, 1e-6) / 65535.0
    q = np.rint((flat - lo) / scale).astype(np.int32) - 32768
    q = q.reshape(len(pos), -1)
    d = q.copy()
    d[1:] -= q[:-1]
    u8 = d.astype("<i2").view(np.uint8).reshape(-1, 2)  # astype wraps into int16, as the page does
    planes = np.concatenate([u8[:, 0], u8[:, 1]]).tobytes()
    if compress:
        planes = zlib.compress(planes, 6)
    return {"enc": "i16dz" if compress else "i16d", "origin": [float(v) for v in lo],
            "scale": [float(v) for v in scale], "data": _b64(planes)}


def decode_positions(block: dict, frames: int, points: int) -> np.ndarray:
    """Inverse of :func:`encode_positions` (what the page computes), ``(F, P, 3)`` float64."""
    raw = base64.b64decode(block["data"])
    if block["enc"].endswith("z"):
        raw = zlib.decompress(raw)
    n = frames * points * 3
    u8 = np.frombuffer(raw, dtype=np.uint8)
    d = (u8[:n].astype(np.uint16) | (u8[n:].astype(np.uint16) << 8)).view(np.int16).reshape(frames, -1)
    q = np.cumsum(d.astype(np.int64), axis=0)
    q = ((q + 32768) % 65536).astype(np.float64)  # wrapped int16 + 32768
    return (np.asarray(block["origin"]) + q.reshape(frames, points, 3) * np.asarray(block["scale"]))


def _encode_bytes(a: np.ndarray, compress: bool) -> dict:
    data = np.ascontiguousarray(a, dtype=np.uint8).tobytes()
    return {"enc": "u8z", "data": _b64(zlib.compress(data, 6))} if compress else {"enc": "u8", "data": _b64(data)}


def _r(x, nd: int = 4):
    return [round(float(v), nd) for v in np.asarray(x).ravel()]


def scene_data(world: World, compress: bool = True, impulse_scale: float = 0.02) -> dict:
    """The JSON-able description of one scene (format :data:`FORMAT_VERSION`)."""
    chars = []
    for c in world.characters:
        entry = {"name": c.name, "color": c.color, "fps": c.fps, "frames": c.num_frames, "start": c.start,
                 "parents": [int(p) for p in c.parents], "joints": c.joints, "radius": _r(c.radii),
                 "pos": encode_positions(c.positions, compress),
                 "feet": {s: [int(i) for i in idx] for s, idx in c.feet.items()}, "contacts": None,
                 "ghost": bool(c.ghost), "face": {k: int(v) for k, v in c.face.items()},
                 "sides": [int(v) for v in c.sides] if c.sides is not None else None,
                 "pointNames": list(c.point_names), "loop": bool(c.loop)}
        entry["hot"] = None if c.highlight is None else _encode_bytes(c.highlight, compress)
        if c.contacts is not None:
            bits = c.contacts[:, 0].astype(np.uint8) | (c.contacts[:, 1].astype(np.uint8) << 1)
            entry["contacts"] = _encode_bytes(bits, compress)
        chars.append(entry)
    impacts = [{"t": float(i.time), "point": _r(i.point), "impulse": _r(i.impulse),
                "char": i.character, "label": i.label, "color": style.color(i.color or style.IMPACT_COLOR)}
               for i in world.impacts]
    phases = []
    for p in world.phases:
        spans = [[round(float(a), 4), round(float(b), 4), str(lab)] for a, b, lab in p.spans]
        cols = {str(k): style.color(v) for k, v in (p.colors or {}).items()}
        phases.append({"label": p.label, "char": p.character, "spans": spans, "colors": cols,
                       "tint": bool(p.tint) and p.character is not None})
    trajs = [{"points": _r(np.asarray(t.points, dtype=np.float64), 3), "color": style.color(t.color),
              "label": t.label} for t in world.trajectories]
    return {"name": world.name, "fps": world.fps, "duration": world.duration, "floor": world.floor,
            "characters": chars, "impacts": impacts, "phases": phases, "trajectories": trajs,
            "impulseScale": impulse_scale, "view": list(world.view) if world.view else None, "props": [_prop_data(p, i, compress) for i, p in enumerate(world.props)],
            "forces": [_forces_data(f) for f in world.forces],
            "markers": [{"t": float(m.time), "label": m.label, "color": style.color(m.color)} for m in world.markers]}


def _prop_data(p: Prop, i: int, compress: bool) -> dict:
    pos, q = check_prop(p, i)
    out = {"shape": p.shape, "size": _r(p.size), "fps": float(p.fps), "start": float(p.start), "frames": len(pos),
           "color": style.color(p.color), "label": p.label, "trail": bool(p.trail), "hide": bool(p.hide_outside),
           "opacity": float(p.opacity),
           "pos": encode_positions(pos[:, None, :], compress), "quat": None if q is None else _r(q, 4)}
    if p.shape == "mesh":
        out["vertices"] = _r(np.asarray(p.vertices, dtype=np.float64), 4)
        out["faces"] = [int(v) for v in np.asarray(p.faces).ravel()]
    return out


def _forces_data(f: Forces) -> dict:
    t, p, v = f.arrays()
    return {"t": _r(t, 6), "points": _r(p, 4), "vectors": _r(v, 4), "kind": f.kind, "scale": float(f.scale),
            "hold": float(f.hold), "char": f.character, "color": style.color(f.color), "label": f.label}


# --------------------------------------------------------------------------- page


def to_html(motions=None, overlays=("contacts",), **kwargs) -> str:
    """The page as a string; see :func:`write` for the arguments."""
    return _page(motions, overlays, **kwargs)[0]


def _page(motions=None, overlays=("contacts",), *, names=None, colors=None, title: str | None = None,
          layout: str = "world", scenes: Sequence[Scene] | None = None, body: str = "capsules",
          camera: str = "follow", autoplay: bool = True, loop: bool = True, compress: bool = True,
          impulse_scale: float = 0.02, curves: bool = False, loop_clips: bool = False) -> tuple[str, list[World]]:
    if body not in STYLES:
        raise ParameterError(f"body must be one of {', '.join(STYLES)}, got {body!r}")
    if camera not in CAMERAS:
        raise ParameterError(f"camera must be one of {', '.join(CAMERAS)}, got {camera!r}")
    if not (np.isfinite(impulse_scale) and impulse_scale > 0):
        raise ParameterError(f"impulse_scale must be a positive number of m per N s, got {impulse_scale}")
    if scenes is None:
        if motions is None:
            raise ParameterError("give motions or scenes")
        scenes = [Scene(motions, overlays, "", names, colors, layout, loop_clips)]
    elif motions is not None:
        raise ParameterError("give motions or scenes, not both")
    if not scenes:
        raise ParameterError("scenes is empty: nothing to show")
    script = _asset(_BUNDLE)
    template = _asset(_TEMPLATE)
    worlds = [build_world(s.motions, s.overlays, names=s.names, colors=s.colors, layout=s.layout,
                          name=s.name or f"scene {i + 1}", loop_clips=s.loop_clips) for i, s in enumerate(scenes)]
    show = set().union(*(w.show for w in worlds))
    title = title or (worlds[0].characters[0].name if len(worlds) == 1 and len(worlds[0].characters) == 1
                      else "kinodyn")
    data = {
        "version": FORMAT_VERSION, "title": title, "palette": list(style.PALETTE),
        "phaseColors": dict(style.PHASE_COLORS), "stageColors": dict(style.STAGE_COLORS),
        "radiusRules": [list(r) for r in RADIUS_RULES],
        "contactColor": style.CONTACT_COLOR, "highlightColor": style.HIGHLIGHT_COLOR,
        "options": {"style": body, "camera": camera, "autoplay": bool(autoplay), "loop": bool(loop),
                    "contacts": "contacts" in show, "phases": "phases" in show,
                    "trajectories": "trajectories" in show, "impacts": True, "labels": True,
                    "props": True, "forces": True, "com": "com" in show, "support": "support" in show,
                    "curves": bool(curves), "trails": False, "onion": False, "inPlace": False, "snap": False,
                    "ortho": False},
        "scenes": [scene_data(w, compress, impulse_scale) for w in worlds],
    }
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    script = script.replace("</script", "<\\/script")
    head, rest = template.split("{{DATA}}")
    rest_a, rest_b = rest.split("{{SCRIPT}}")
    head = head.replace("{{TITLE}}", escape(title)).replace("{{VERSION}}", __version__)
    return f"{head}{payload}{rest_a}{script}{rest_b}", worlds


def write(path, motions=None, overlays=("contacts",), **kwargs) -> ViewerPage:
    """Write a self-contained viewer page, atomically.

    Args:
        path: the ``.html`` file.
        motions: a Motion, an :class:`Actor`, a sequence or a mapping ``name -> Motion`` (all shown in
            one world, in their own coordinates unless ``layout`` says otherwise).
        overlays: overlay names (``"contacts"``, ``"phases"``, ``"trajectories"``, ``"com"``,
            ``"support"``) and objects (:class:`Impact`, :class:`Contacts`, :class:`Phases`,
            :class:`Trajectory`, :class:`Prop`, :class:`Forces`, :class:`Marker`, :class:`Stages`);
            ``None`` for none.

    Keyword Args:
        names, colors: one label / colour per character.
        title: page title (default: the clip name or "kinodyn").
        layout: ``"world"``, ``"row"`` or ``"grid"`` (side by side, for clip galleries), ``"lanes"``
            (side by side across the direction of travel, for comparisons).
        scenes: instead of ``motions``, a sequence of :class:`Scene` chosen from a selector in the page.
        body: ``"capsules"`` or ``"bones"``. camera: ``"follow"``, ``"orbit"`` or ``"free"``.
        autoplay, loop: playback at start.
        compress: zlib-compress the motion data (needs ``DecompressionStream``: every current browser).
        impulse_scale: impulse arrow length in metres per N s (clamped to 0.25 .. 1.2 m).
        curves: open the curves panel (joint speeds, root and foot heights) at start.
        loop_clips: clips shorter than the scene start again after their last frame (else they hold their
            last pose); an :class:`Actor`'s ``loop`` overrides it.

    Returns:
        :class:`ViewerPage` with the path and the file size.
    """
    text, worlds = _page(motions, overlays, **kwargs)
    data = text.encode("utf-8")
    atomic_write_bytes(path, data)
    return ViewerPage(Path(path), len(data), tuple((w.name, len(w.characters), w.num_frames) for w in worlds))
