"""Tracker input of the paper's scenarios: built-in clips steered into the obstacles, and the hand.

Schmidl and Lin drove the avatar by mouse and keyboard and the hand by a CyberGlove and a ceiling
tracker. Here clips of :mod:`kinodyn.data.library` stand in for the user: ``push`` (two arms into a
wall), ``push_kick`` (the push with the legs of the front kick: two arms and a leg), ``cross_arms``
(the arms swing across the chest through each other: self-collision), ``punch`` (an arm into a
corner). The hand is 15 ellipsoids (palm, three phalanges per finger, two for the thumb) on a tracked
path: moving about, sliding over the table one way and back, then flicking a ball off it (figure 7's
phases: idle, sliding, ball).

Shapes: ``F`` frames; metres, seconds; rotations ``(w, x, y, z)``.
"""

from __future__ import annotations

import numpy as np

from kinodyn.contact.setting import SceneObject, ellipsoid
from kinodyn.errors import UnknownNameError
from kinodyn.math import quat
from kinodyn.motion import Motion

__all__ = [
    "HAND_PATHS",
    "HAND_PHASES",
    "SCENARIO_MOTIONS",
    "hand_object",
    "hand_path",
    "hand_pieces",
    "scenario_motion",
]

_DEG = np.pi / 180.0


def _push_kick() -> Motion:
    from kinodyn.data import library

    push, kick = library.load("push"), library.load("kick")
    kick = kick.resample(kick.fps * kick.num_frames / push.num_frames)[: push.num_frames]
    sk = push.skeleton
    legs = [j for j, n in enumerate(sk.names) if "Leg" in n or "Foot" in n or "Toe" in n]
    q = np.array(push.local_rot)
    q[:, legs] = kick.local_rot[: len(q), legs]
    return push.replace(local_rot=q, name="push_kick")


def _cross_arms() -> Motion:
    from kinodyn.data import library

    base = library.load("idle")[:240]
    sk = base.skeleton
    t = np.arange(base.num_frames) / base.fps
    s = 0.5 - 0.5 * np.cos(2.0 * np.pi * t / 2.0)  # two swings in 4 s
    q = np.array(base.local_rot)
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        arm, fore = sk.index(f"{side}Arm"), sk.index(f"{side}ForeArm")
        # forward (about -Y) and across the body (left arm about -X, right about +X)
        swing = quat.mul(quat.from_axis_angle([0.0, -1.0, 0.0], 75 * _DEG * s),
                         quat.from_axis_angle([-sign, 0.0, 0.0], 55 * _DEG * s))
        q[:, arm] = quat.mul(swing, q[:, arm])
        q[:, fore] = quat.mul(quat.from_axis_angle([0.0, -1.0, 0.0], 40 * _DEG * s), q[:, fore])
    return base.replace(local_rot=q, name="cross_arms")


def _clip(name):
    def load():
        from kinodyn.data import library

        return library.load(name)
    return load


#: Scenario motions beyond the library's clips (any library clip name works too).
SCENARIO_MOTIONS = {"push_kick": _push_kick, "cross_arms": _cross_arms}


def scenario_motion(name: str) -> Motion:
    """A scenario motion, a library clip, or a motion file (BVH, AMC, NPZ; an added T-pose frame 0, as
    in the cgspeed CMU files, is dropped: :func:`kinodyn.io.drop_added_tpose`)."""
    from pathlib import Path

    if name in SCENARIO_MOTIONS:
        return SCENARIO_MOTIONS[name]()
    if Path(name).suffix.lower() in (".bvh", ".amc", ".npz"):
        from kinodyn.io import drop_added_tpose, load

        return drop_added_tpose(load(name))[0]  # a converter's added T-pose frame is not capture
    from kinodyn.data import library

    return _clip(name)() if name in library.names() else _unknown(name)


def _unknown(name):
    raise UnknownNameError(f"no scenario motion or clip named {name!r}; scenario motions: "
                           f"{', '.join(SCENARIO_MOTIONS)}; or any clip of `kinodyn library list`")


# --------------------------------------------------------------------------- the hand

#: Finger roots on the palm (hand frame: fingers along +x, palm facing -z, thumb toward +y).
_ROOTS = np.array([[0.045, 0.03, 0.0], [0.05, 0.01, 0.0], [0.048, -0.01, 0.0], [0.042, -0.028, 0.0]])
_LENGTHS = (0.045, 0.028, 0.022)
_THUMB_ROOT = np.array([0.0, 0.045, -0.005])


def hand_pose(flex: float, index_flex: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centres ``(15, 3)``, rotations ``(15, 4)`` and radii ``(15, 3)`` of the hand's ellipsoids with the
    fingers flexed by ``flex`` (rad per joint; the index finger by ``index_flex`` when given), in the hand
    frame. A phalanx along ``(cos a, 0, -sin a)`` is the x axis turned by ``a`` about y."""
    pos, rot, rad = [np.zeros(3)], [np.array([1.0, 0, 0, 0])], [np.array([0.048, 0.045, 0.014])]
    for f, root in enumerate(_ROOTS):
        a = flex if (f != 0 or index_flex is None) else index_flex
        p, ang = root.copy(), 0.0
        for length in _LENGTHS:
            ang += a
            d = np.array([np.cos(ang), 0.0, -np.sin(ang)])
            pos.append(p + 0.5 * length * d)
            rot.append(np.array([np.cos(0.5 * ang), 0.0, np.sin(0.5 * ang), 0.0]))
            rad.append(np.array([0.5 * length + 0.004, 0.0085, 0.0085]))
            p = p + length * d
    pos += list(_THUMB[0])
    rot += list(_THUMB[1])
    rad += list(_THUMB[2])
    return np.array(pos), np.array(rot), np.array(rad)


def _thumb():
    d = np.array([0.6, 0.8, -0.2]) / np.linalg.norm([0.6, 0.8, -0.2])
    q = quat.between(np.array([1.0, 0.0, 0.0]), d)
    p, out = _THUMB_ROOT.copy(), ([], [], [])
    for length in (0.035, 0.028):
        out[0].append(p + 0.5 * length * d)
        out[1].append(q)
        out[2].append(np.array([0.5 * length + 0.004, 0.01, 0.01]))
        p = p + length * d
    return out


_THUMB = _thumb()


def hand_pieces(flex: float, index_flex: float | None = None) -> list:
    """The 15 ellipsoid pieces of :func:`hand_pose`."""
    pos, rot, rad = hand_pose(flex, index_flex)
    return [ellipsoid(r, p, q) for p, q, r in zip(pos, rot, rad)]


def hand_object(mass: float = 0.5, name: str = "hand") -> SceneObject:
    """The hand as one driven object (rigid for overlap removal, as in the paper)."""
    return SceneObject(name, "driven", "human", tuple(hand_pieces(0.15)), pos=(0.0, 0.0, 1.5), mass=mass)


#: Hand path keyframes: (time s, position, finger flex rad, index flex rad, phase). The table top is at
#: z = 0.75 around (2, 0); the ball waits at (2.25, 0.25).
_FLICK = [
    (0.0, (0.5, -1.0, 1.4), 0.3, 0.3, "idle"), (2.0, (1.2, 1.0, 1.2), 0.5, 0.5, "idle"),
    (4.0, (2.5, 1.5, 1.6), 0.2, 0.2, "idle"), (6.0, (1.6, -0.4, 0.85), 0.1, 0.1, "idle"),
    (6.6, (1.6, -0.4, 0.76), 0.1, 0.1, "sliding"), (9.0, (1.7, 0.35, 0.76), 0.1, 0.1, "sliding"),
    (11.4, (1.6, -0.4, 0.76), 0.1, 0.1, "sliding"), (12.0, (1.6, -0.4, 0.9), 0.3, 0.3, "idle"),
    (13.0, (2.05, 0.25, 0.80), 0.3, 1.2, "ball"), (13.6, (2.07, 0.25, 0.80), 0.3, 1.2, "ball"),
    (13.75, (2.12, 0.25, 0.80), 0.3, 0.0, "ball"), (15.0, (2.0, 0.2, 1.0), 0.3, 0.3, "ball"),
    (18.0, (1.0, -0.5, 1.3), 0.3, 0.3, "ball"),
]
HAND_PATHS = {"flick": _FLICK}
HAND_PHASES = ("idle", "sliding", "ball")


def hand_path(name: str, fps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Tracker samples of a hand path: positions ``(F, 3)``, finger flex ``(F,)``, index flex ``(F,)``
    and phase index ``(F,)`` into :data:`HAND_PHASES`."""
    if name not in HAND_PATHS:
        raise UnknownNameError(f"no hand path named {name!r}; paths: {', '.join(HAND_PATHS)}")
    keys = HAND_PATHS[name]
    kt = np.array([k[0] for k in keys])
    t = np.arange(int(kt[-1] * fps) + 1) / fps
    pos = np.stack([np.interp(t, kt, [k[1][i] for k in keys]) for i in range(3)], axis=1)
    flex = np.interp(t, kt, [k[2] for k in keys])
    index = np.interp(t, kt, [k[3] for k in keys])
    seg = np.clip(np.searchsorted(kt, t, side="right") - 1, 0, len(keys) - 1)
    phase = np.array([HAND_PHASES.index(keys[s][4]) for s in seg])
    return pos, flex, index, phase
