"""Demo part "viewer": ``out/demo.html`` and ``out/demo.mp4``, the page and video of everything so far.

The page has one scene per group of built-in clips (side by side) and one per set of motion files an
earlier demo part wrote (``out/<part>/<group>_*.bvh`` share a world: ``out/physics/fight_attacker.bvh``
and ``fight_defender.bvh`` play together). A part may write ``out/<part>/impacts.json`` beside them,
``{group or file stem: [{"time", "point", "impulse", "character"?}, ...]}``: those impacts are drawn
as arrows (one of each equal-and-opposite pair). The video shows built-in clips in lanes across their
direction of travel, each looping for the video's length. Beside them, in
``out/viewer/``: support-phase bars of the clips (PNG, SVG) and a glTF export of the walk.
"""

from __future__ import annotations

import json
import math
from collections import OrderedDict
from pathlib import Path

import numpy as np

from kinodyn.errors import KinodynError

__all__ = ["clip_scenes", "demo", "part_scenes"]

_SCENE_SIZE = 8  # clips per side-by-side scene
_VIDEO_CLIPS = ("idle", "walk", "run", "jump", "punch", "kick")
_VIDEO = {"width": 960, "height": 400, "end": 4.0}  # demo.mp4: clips in lanes, filmed from the front
_MOTION_EXT = (".bvh", ".npz")


def clip_scenes():
    """Scenes of the built-in clips: grouped by their first tag, at most ``_SCENE_SIZE`` side by side."""
    from kinodyn.data import library
    from kinodyn.viz.html import Scene

    groups: OrderedDict[str, list[str]] = OrderedDict()
    for name in library.names():
        tags = library.info(name).tags
        groups.setdefault(tags[0] if tags else "other", []).append(name)
    scenes = []
    for tag, names in groups.items():
        parts = math.ceil(len(names) / _SCENE_SIZE)
        for k in range(parts):
            chunk = names[k * _SCENE_SIZE:(k + 1) * _SCENE_SIZE]
            label = f"clips: {tag}" + (f" ({k + 1}/{parts})" if parts > 1 else "")
            scenes.append(Scene({n: library.load(n) for n in chunk}, ("contacts", "phases"), label, layout="row"))
    return scenes


def _impacts(folder: Path, group: str, stems: list[str], skipped: list[str]) -> list:
    """Impacts of a group from ``folder/impacts.json`` (see the module docstring)."""
    from kinodyn.viz.world import Impact

    path = folder / "impacts.json"
    if not path.is_file():
        return []
    try:
        table = json.loads(path.read_text())
        events = [e for key in [group, *stems] for e in table.get(key, [])]
        out, seen = [], []
        for e in events:
            t, p, j = float(e["time"]), np.asarray(e["point"], float), np.asarray(e["impulse"], float)
            if any(abs(t - t2) < 1e-6 and np.allclose(p, p2) and np.allclose(j, -j2) for t2, p2, j2 in seen):
                continue  # the reaction of an impulse already drawn
            seen.append((t, p, j))
            who = str(e.get("character", ""))
            char = next((i for i, s in enumerate(stems) if who and who in s), None)
            out.append(Impact(t, p, j, char, str(e.get("body", ""))))
        return out
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        skipped.append(f"{path}: {e}")
        return []


def part_scenes(out: Path) -> tuple[list, list[str]]:
    """Scenes of the motion files earlier demo parts wrote under ``out/<part>/``, and the motion files
    that could not be read (other archives, such as object trajectories, are left out silently)."""
    from kinodyn.io import load
    from kinodyn.io.npz import holds_other_arrays
    from kinodyn.viz.html import Scene

    scenes, skipped = [], []
    for folder in sorted(p for p in Path(out).iterdir() if p.is_dir() and p.name not in ("clips", "viewer")):
        groups: OrderedDict[str, dict] = OrderedDict()
        for f in sorted(folder.iterdir()):
            if f.suffix.lower() not in _MOTION_EXT or (f.suffix.lower() == ".npz" and holds_other_arrays(f)):
                continue  # not a motion: an object trajectory or crowd recording is drawn by its own part
            try:
                m = load(f)
            except KinodynError as e:
                skipped.append(f"{f}: {e}")
                continue
            groups.setdefault(f.stem.split("_")[0], {})[f.stem] = m
        for group, motions in groups.items():
            impacts = _impacts(folder, group, list(motions), skipped)
            scenes.append(Scene(motions, ["contacts", "trajectories", *impacts], f"{folder.name}: {group}"))
    return scenes, skipped


def demo(out: Path) -> list[str]:
    from kinodyn import contacts
    from kinodyn.data import library
    from kinodyn import plotting as plots
    from kinodyn.viz import html
    from kinodyn.viz.gltf import write_gltf
    from kinodyn.viz.render import RenderConfig, render

    out = Path(out)
    lines = []
    scenes = clip_scenes()
    extra, skipped = part_scenes(out)
    page = html.write(out / "demo.html", scenes=scenes + extra, title="kinodyn demo")
    lines.append(f"demo.html: {len(scenes)} scenes of built-in clips + {len(extra)} from earlier parts "
                 f"({', '.join(s.name for s in extra) or 'none'}), {page.bytes / 1e6:.2f} MB")
    lines += [f"skipped {s}" for s in skipped]

    names = [n for n in _VIDEO_CLIPS if n in library.names()] or library.names()[:6]
    motions = {n: library.load(n) for n in names}
    res = render(out / "demo.mp4", motions, ("contacts",), layout="lanes", loop_clips=True,
                 config=RenderConfig(**_VIDEO))
    lines.append(f"demo.mp4: {', '.join(names)}; {res.frames} frames at {res.fps:g} fps, {res.width}x{res.height}, "
                 f"rendered in {res.seconds:.1f} s")

    folder = out / "viewer"
    folder.mkdir(parents=True, exist_ok=True)
    fig = plots.support_bars({n: contacts.detect(m).as_array() for n, m in motions.items()},
                             next(iter(motions.values())).fps, title="support phases of built-in clips")
    written = plots.save(fig, folder / "support_phases")
    lines.append(f"{', '.join(p.name for p in written)}: support-phase bars in viewer/")
    if "walk" in motions:
        size = write_gltf(folder / "walk.glb", motions["walk"])
        lines.append(f"viewer/walk.glb: glTF 2.0 skeleton animation of walk, {size / 1e3:.0f} kB")
    return lines
