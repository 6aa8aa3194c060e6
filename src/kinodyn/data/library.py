"""The built-in motion library: clips written by this project, generated on first use.

Every clip is made by code in this package (:mod:`kinodyn.data.gaits` for the cyclic and jumping
clips, :mod:`kinodyn.data.keyed` for the clips keyframed in ``keyframes.json``) on the humanoid of
:mod:`kinodyn.data.skeleton`, at 60 frames per second. Clips are built lazily and kept in memory.
Mirrored variants (``<name>_mirror``, and ``turn_right``, ``stumble_side_right``, ``flinch_side_right``)
are the left/right mirror images of their source clip (:meth:`kinodyn.motion.Motion.mirrored`) and
share its skeleton object. Each fall that ends lying prone or supine has a get-up (:data:`GET_UP`) that
starts in the fall's last pose and ends standing in the neutral stance.

Quality, checked by ``tests/test_data_library.py`` on every clip: planted feet do not slide (mean foot
sliding under 2 cm/s by :func:`kinodyn.contacts.sliding`), no joint or end site goes under the floor,
joint angles stay inside :mod:`kinodyn.limits`, cyclic clips loop exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from kinodyn.data import gaits, keyed
from kinodyn.data.procedural import Assembled
from kinodyn.errors import UnknownNameError
from kinodyn.motion import Motion

__all__ = ["GET_UP", "MIRRORED", "ClipInfo", "describe", "ik_error", "info", "load", "names"]


@dataclass(frozen=True)
class ClipInfo:
    """What a library clip is.

    Attributes:
        name: the clip's name.
        cyclic: True when the clip loops (its last frame is its first up to root translation).
        tags: labels such as ``("locomotion",)``, ``("reaction", "front")``.
        description: one sentence.
        mirror_of: the clip this one mirrors, or None.
    """

    name: str
    cyclic: bool
    tags: tuple[str, ...]
    description: str
    mirror_of: str | None = None


_PROCEDURAL: dict[str, tuple[object, bool, tuple[str, ...], str]] = {
    "idle": (lambda: gaits.idle("idle"), True, ("idle", "standing"),
             "Standing still: breathing, a slow weight shift, relaxed arms; loops every 4 s."),
    "fighting_stance": (lambda: gaits.fighting_stance("fighting_stance"), True, ("idle", "stance", "fighting"),
                        "A boxer's guard in place, left foot forward, fists up, bouncing lightly; loops every 2 s."),
    "walk": (lambda: gaits.gait(gaits.WALK, "walk"), True, ("locomotion", "walk"),
             "Walk cycle at 1.4 m/s, two strides starting at left heel strike; loops."),
    "run": (lambda: gaits.gait(gaits.RUN, "run"), True, ("locomotion", "run"),
            "Run cycle at 3.2 m/s with flight phases, two strides; loops."),
    "jump": (lambda: gaits.jump("jump"), False, ("jump",),
             "Standing vertical jump: crouch, arm swing, take-off, flight, landing and recovery."),
}

#: Mirror-image clips: name -> source clip.
MIRRORED: dict[str, str] = {
    "turn_right": "turn_left",
    "stumble_side_right": "stumble_side_left",
    "flinch_side_right": "flinch_side_left",
}
_ASYMMETRIC = ("punch", "kick", "push", "step_forward_small", "step_forward_large", "step_back_small",
               "step_back_large", "steps_back", "steps_forward", "fall_forward", "fall_backward", "fall_side",
               "roll_forward", "roll_backward", "get_up_face_down", "get_up_face_up")
MIRRORED.update({f"{n}_mirror": n for n in _ASYMMETRIC})

#: The get-up that follows a fall: its first frame is the fall's last (placed where the fall ends).
GET_UP: dict[str, str] = {"fall_forward": "get_up_face_down", "fall_backward": "get_up_face_up"}
GET_UP.update({f"{k}_mirror": f"{v}_mirror" for k, v in list(GET_UP.items())})


def _mirror_description(text: str) -> str:
    swap = {"left": "right", "right": "left", "Left": "Right", "Right": "Left", "+Y": "-Y", "-Y": "+Y"}
    out = []
    for word in text.split(" "):
        core = word.strip(".,;:()")
        out.append(word.replace(core, swap[core]) if core in swap else word)
    return " ".join(out)


_ORDER = ("idle", "fighting_stance", "walk", "run", "turn_left", "turn_right", "jump", "punch", "kick", "push",
          "step_forward_small", "step_forward_large", "step_back_small", "step_back_large", "steps_back",
          "steps_forward", "stumble_side_left", "stumble_side_right", "fall_forward", "fall_backward", "fall_side",
          "roll_forward", "roll_backward", "get_up_face_down", "get_up_face_up", "flinch_front",
          "flinch_side_left", "flinch_side_right", "flinch_back")


def names() -> list[str]:
    """Every clip name: the base clips in a fixed order, then the ``_mirror`` variants."""
    known = set(_PROCEDURAL) | set(keyed.keyed_names()) | set(MIRRORED)
    out = [n for n in _ORDER if n in known]
    out += [n for n in keyed.keyed_names() if n not in out]
    out += [n for n in MIRRORED if n not in out]
    return out


def _check(name: str) -> None:
    if name not in _PROCEDURAL and name not in MIRRORED and name not in keyed.keyed_names():
        raise UnknownNameError(f"no library clip named {name!r}; clips: {', '.join(names())}")


@cache
def _generate(name: str) -> Assembled:
    _check(name)
    if name in MIRRORED:
        src = _generate(MIRRORED[name])
        return Assembled(src.motion.mirrored().replace(name=name), src.ik_error)
    if name in _PROCEDURAL:
        return _PROCEDURAL[name][0]()
    return keyed.build(name)


def load(name: str) -> Motion:
    """The clip ``name`` (60 fps, the humanoid skeleton); raises :class:`UnknownNameError` listing
    the clips when the name is unknown."""
    return _generate(name).motion


def ik_error(name: str) -> float:
    """Largest distance (m) between a solved ankle or wrist and its planned position in the clip:
    about 1e-15 when every planned foot position was reachable."""
    return _generate(name).ik_error


def info(name: str) -> ClipInfo:
    """What clip ``name`` is (:class:`ClipInfo`)."""
    _check(name)
    if name in MIRRORED:
        src = info(MIRRORED[name])
        return ClipInfo(name, src.cyclic, src.tags + ("mirrored",), _mirror_description(src.description),
                        src.name)
    if name in _PROCEDURAL:
        _, cyclic, tags, desc = _PROCEDURAL[name]
        return ClipInfo(name, cyclic, tags, desc, None)
    spec = keyed.clip_spec(name)
    return ClipInfo(name, bool(spec.get("cyclic", False)), tuple(spec.get("tags", ())),
                    spec.get("description", ""), None)


def describe(name: str) -> str:
    """One line: what the clip is, its length and whether it loops."""
    i = info(name)
    m = load(name)
    loop = ", loops" if i.cyclic else ""
    return f"{i.description} [{m.num_frames} frames, {m.duration:.2f} s{loop}]"
