"""The transitions of the paper's figures 12 and 13 on the built-in clips, and their foot sliding.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, section 6 (figures 12 and 13): a walk,
a run, a walk at another speed, then a fighting move (a kick), another walk and a jump, blended with and
without synchronization. :func:`kinodyn.blend.evaluate.evaluate` measures it; the demo part and the
benchmark both report it.
"""

from __future__ import annotations

__all__ = ["transition_script"]


def transition_script():
    """The figure 12/13 script (the same as ``examples/blend_fig12.yaml``)."""
    from kinodyn.blend.script import parse_script

    return parse_script({
        "name": "blend_fig12", "fps": 60, "synchronize": True, "nk": 5, "ramp_in": 0.5, "ramp_out": 0.5,
        "actions": [
            {"clip": "walk", "start": 0.0, "stop": 3.0, "priority": 1},
            {"clip": "run", "start": 2.8, "stop": 6.0, "priority": 1},
            {"clip": "walk", "start": 5.8, "stop": 8.5, "priority": 1, "speed": 1.25, "key": "fast_walk"},
            {"clip": "kick", "start": 8.2, "priority": 2},
            {"clip": "walk", "start": 9.6, "stop": 12.0, "priority": 1, "key": "walk_again"},
            {"clip": "jump", "start": 11.8, "priority": 2},
        ]})
