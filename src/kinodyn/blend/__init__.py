"""Support-phase synchronized blending (Ménardais, Multon, Kulpa, Arnaldi).

A real-time motion mixer whose actions start and stop at any time, with priorities; the support
phases of the actions (right, left, double support, flight) are synchronized before blending, so feet
do not slide when a motion with the left foot down meets one with the right foot down.

Modules: :mod:`~kinodyn.phases` (sequences, the algebra, extension: sections 4.1-4.3),
:mod:`~kinodyn.blend.sync` (chronological organization, section 5.1) with :mod:`~kinodyn.blend.holds`
(the hold rule, appendix A),
:mod:`~kinodyn.blend.timewarp` (durations and time warp, 5.2-5.3), :mod:`~kinodyn.blend.mixer`
(the mixer) with :mod:`~kinodyn.blend.weights` (ramps, priorities), :mod:`~kinodyn.blend.pose` (pose
blending), :mod:`~kinodyn.blend.actions`, :mod:`~kinodyn.blend.character` (per-character state) and
:mod:`~kinodyn.blend.footlock` (support constraints after blending), :mod:`~kinodyn.blend.library`
(clips with their support, in a :class:`kinodyn.clips.ClipStore`), :mod:`~kinodyn.blend.parametric` (cycles blended by weights, a parametric model that adapts
its sequence with its motion), :mod:`~kinodyn.blend.script` (YAML scripts),
:mod:`~kinodyn.blend.plots` (figures 9 and 10).
"""

from kinodyn.blend.library import add_blend, add_clip
from kinodyn.blend.mixer import BlendConfig, Mixer, Pose
from kinodyn.blend.parametric import blend_cycles
from kinodyn.phases import (
    DS,
    ERR,
    FLIGHT,
    LS,
    RS,
    Phase,
    PhaseConfig,
    PhaseSequence,
    combine,
    compatible,
)
from kinodyn.blend.holds import resolve
from kinodyn.blend.script import BlendResult, Script, load_script, parse_script, run_script
from kinodyn.blend.sync import SyncConfig, Synchronizer
from kinodyn.blend.timewarp import WarpConfig, WarpPlanner
from kinodyn.clips import ClipStore

__all__ = [
    "DS",
    "ERR",
    "FLIGHT",
    "LS",
    "RS",
    "BlendConfig",
    "BlendResult",
    "ClipStore",
    "Mixer",
    "Phase",
    "PhaseConfig",
    "PhaseSequence",
    "Pose",
    "Script",
    "SyncConfig",
    "Synchronizer",
    "WarpConfig",
    "WarpPlanner",
    "add_blend",
    "add_clip",
    "blend_cycles",
    "combine",
    "compatible",
    "load_script",
    "parse_script",
    "resolve",
    "run_script",
]
