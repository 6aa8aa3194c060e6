"""``kinodyn demo`` part: responses to hits from the front, the back and the side, a push and a punch.

Writes ``response/<case>.bvh``, one viewer page with every response, and for the first case the explain
plots (error surface, timeline). The shipped classifier picks the clips (exhaustive search when no model
is installed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _cases():
    from kinodyn.data import library as data
    from kinodyn.response.pipeline import Attacker, Ball, Push

    walk = data.load("walk")
    return {"ball_front": (walk, Ball(direction=np.pi)), "ball_back": (walk, Ball(direction=0.0)),
            "ball_side": (walk, Ball(direction=-np.pi / 2)),
            "push_side": (walk, Push((0.0, 110.0, 0.0), "chest", 1.0)),
            "punch": (data.load("idle"), Attacker(data.load("punch"), (1.0, 0.0, np.pi)))}


def _scene(name: str, r, impact):
    """The viewer scene of one response: the character, the opponent for a punch, the impact arrow and
    the stages (:func:`kinodyn.response.command.viewer_overlays`)."""
    from kinodyn.response.command import viewer_overlays
    from kinodyn.response.pipeline import Attacker
    from kinodyn.viz.html import Scene

    motions = {name: r.motion}
    if isinstance(impact, Attacker):  # it plays its clip kinematically where it stands
        motions["opponent"] = impact.motion.aligned_to(np.asarray(impact.at, dtype=np.float64), 0)
    return Scene(motions, ["contacts", *viewer_overlays(r)], name=f"{name}: {r.clip}")


def demo(out: Path) -> list[str]:
    from kinodyn.io import save
    from kinodyn.response.classifier import ReactionModel
    from kinodyn.response.command import DEFAULT_KIND, DEFAULT_MODEL
    from kinodyn.response.library import builtin
    from kinodyn.response.pipeline import respond
    from kinodyn.response.plots import timeline

    out = Path(out) / "response"
    out.mkdir(parents=True, exist_ok=True)
    lib = builtin()
    folder = DEFAULT_MODEL / DEFAULT_KIND
    model = ReactionModel.load(folder, lib) if folder.is_dir() else None
    lines, scenes = [], []
    for name, (base, impact) in _cases().items():
        r = respond(base, lib, impact, model)
        save(out / f"{name}.bvh", r.motion)
        scenes.append(_scene(name, r, impact))
        timeline(r.stages, r.motion.fps, out / f"{name}_timeline.png", r.motion.name, r.impact_time)
        lines.append(f"{name}.bvh: hit at {r.impact_time:.2f} s ({np.linalg.norm(r.impulse):.0f} N s) -> {r.clip} "
                     f"from frame {r.clip_frame} after {r.sim_frame} simulated frames (D = {r.error:.2f})")
    try:
        from kinodyn.viz.html import write

        write(out / "responses.html", scenes=scenes, title="dynamic responses")
        lines.append("responses.html: one scene per response (impact arrow, stages coloured on the timeline)")
    except ImportError:  # pragma: no cover - viz extra absent
        pass
    return lines
