"""How the built-in keyframe set (figure 8 of the paper) is authored; writes ``keyframes.json``.

Mitake et al., sections 5.3 and 6.1, figure 8: a set of 12 one-dimensional keyframe animations for
the built-in humanoid (scaled to the paper's 1.5 m body), with the behaviours ``walking_and_falling``
and ``standing_up``. Every keyframe is authored as an animator would see it, in the world, standing on
the floor, and then expressed in the body frame Sr of the rigid body at the keyframe's tilt (section
5.3: "each keyframe has to be made in this coordinate system"): the pose is put on the floor (its
lowest point touching it), its centre of mass over the body's, and rotated by the inverse of the tilt.

The animations (``t`` is the coordinate along the animation's axis):

========================  ===========  ========  =================================================
animation                 axis         at        keys
========================  ===========  ========  =================================================
walk                      D_z          Θx = 0    8, one walk cycle sampled from the built-in walk
stumble_forward           D_z          Θx = .35  8, long hurried strides, trunk forward, arms out
stumble_backward          D_z          Θx = -.35 6, short steps, arms thrown forward
fall_forward              Θx           D_z = 0   3, stepping into the fall, hands reaching, face down
fall_backward             Θx           D_z = 0   3, trunk folding, sitting down, face up
sidestep                  D_x          Θz = 0    4, a side shuffle
stumble_left/right        D_x          Θz = ±.35 4 each, crossing steps, arms out
fall_left/right           Θz           D_x = 0   2 each, the arms flutter
stand_up_front            Θx (B = 1)   line      6, push up, hands and knees, kneel, rise, stand
stand_up_back             Θx (B = 1)   line      5, sit up, knees up, squat, rise
========================  ===========  ========  =================================================

Run ``python -m kinodyn.crowd.authoring`` to rewrite the data file; a test checks it is up to date.
"""

from __future__ import annotations

import json
from functools import lru_cache

import numpy as np

from kinodyn.crowd.body import BodyConfig, support_height, tilt_quat
from kinodyn.crowd.keyframes import BUILTIN_PATH, FORMAT
from kinodyn.math import quat

__all__ = ["build_dict", "write"]

WALKING, STANDING = "walking_and_falling", "standing_up"
_MASS = {"Hips": 0.14, "Spine": 0.1, "Spine1": 0.16, "Neck": 0.02, "Head": 0.08, "Shoulder": 0.02,
         "Arm": 0.028, "ForeArm": 0.016, "Hand": 0.006, "UpLeg": 0.1, "Leg": 0.045, "Foot": 0.013,
         "ToeBase": 0.002}


def _suffix(name: str) -> str:
    return name.replace("Left", "").replace("Right", "")


@lru_cache(maxsize=1)
def _setup():
    from kinodyn.data import library
    from kinodyn.data.skeleton import humanoid

    body = BodyConfig()
    scale = body.height / humanoid().height()
    return body, scale, humanoid().scaled(scale), library.load("walk"), library.load("idle")


def _euler(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    return quat.from_euler(np.radians([x, y, z]), "xyz")


def _pose(base: np.ndarray | None = None, root_pitch=0.0, root_roll=0.0, **joints) -> np.ndarray:
    """Local rotations ``(J, 4)``: ``base`` (identity) with joints set from Euler degrees.

    ``joints`` maps a joint name, or a name without Left/Right for both sides mirrored, to ``(x, y, z)``
    degrees (intrinsic xyz); a name prefixed with ``add_`` multiplies onto the base instead.
    ``root_pitch`` (+ forward) and ``root_roll`` (+ left) turn the root in the world.
    """
    sk = _setup()[2]
    rot = quat.identity((sk.num_joints,)) if base is None else np.array(base)
    for key, (x, y, z) in joints.items():
        add = key.startswith("add_")
        name = key[4:] if add else key
        targets = [(name, 1.0)] if name in sk.names else [("Left" + name, 1.0), ("Right" + name, -1.0)]
        for jn, m in targets:
            q = _euler(m * x, y, m * z)
            j = sk.index(jn)
            rot[j] = quat.mul(rot[j], q) if add else q
    rot[0] = quat.mul(quat.mul(_euler(x=-root_roll), _euler(y=root_pitch)), rot[0])
    return rot


def _points(rot: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World points of a pose with its root at the origin: (points, radii, masses)."""
    from kinodyn.data.skeleton import HEEL, SEGMENT_RADIUS, SOLE

    _, s, sk, _, _ = _setup()
    lp = np.array(sk.offsets)
    lp[0] = 0.0
    gr, gp = quat.fk(rot, lp, sk.parents)
    ends = gp[sk.end_parents] + quat.mul_vec(gr[sk.end_parents], sk.end_offsets)
    feet = [sk.index(n) for n in ("LeftFoot", "RightFoot")]
    heels = gp[feet] + quat.mul_vec(gr[feet], HEEL * s)
    radii = [SEGMENT_RADIUS[_suffix(n)] * s for n in sk.names]
    end_r = [SEGMENT_RADIUS["Head"] * s * 0.9 if sk.names[p] == "Head" else
             (0.03 * s if "Hand" in sk.names[p] else SOLE * s) for p in sk.end_parents]
    pts = np.concatenate([gp, ends, heels])
    rad = np.concatenate([radii, end_r, [SOLE * s, SOLE * s]])
    mass = np.array([_MASS[_suffix(n)] for n in sk.names])
    return pts, rad, np.concatenate([mass, np.zeros(len(ends) + 2)])


def _key(rot: np.ndarray, tilt_x=0.0, tilt_z=0.0, shift=(0.0, 0.0)) -> dict:
    """A keyframe in Sr from a world-look pose: on the floor, its centre of mass over the body's."""
    body = _setup()[0]
    pts, rad, mass = _points(rot)
    com = mass @ pts / mass.sum()
    root = np.array([shift[0] - com[0], shift[1] - com[1], -np.min(pts[:, 2] - rad)])
    h = float(support_height(body, tilt_x, tilt_z))
    t = tilt_quat(tilt_x, tilt_z)
    root_sr = quat.inv_mul_vec(t, root - np.array([0.0, 0.0, h]))
    rot = np.array(rot)
    rot[0] = quat.inv_mul(t, rot[0])
    names = _setup()[2].names
    return {"root": [round(float(v), 6) for v in root_sr],
            "rotations": {n: [round(float(v), 6) for v in quat.abs(rot[j])] for j, n in enumerate(names)
                          if quat.angle(rot[j]) > 1e-6}}


def _walk_frame(phase: float) -> np.ndarray:
    walk = _setup()[3]
    f = phase * walk.fps  # one cycle (1.4 m) takes one second of the built-in walk
    i = int(np.floor(f))
    u = f - i
    return quat.slerp(walk.local_rot[i], walk.local_rot[i + 1], u)


def _scaled_swing(rot, joints, k: float) -> np.ndarray:
    sk = _setup()[2]
    rot = np.array(rot)
    for n in joints:
        for side in ("Left", "Right"):
            j = sk.index(side + n)
            rot[j] = quat.from_rotvec(k * quat.to_rotvec(rot[j]))
    return rot


def _mirror(rot: np.ndarray) -> np.ndarray:
    sk = _setup()[2]
    m = np.array(rot)[sk.mirror_map()]
    return m * np.array([1.0, -1.0, 1.0, -1.0])


def _walking_tracks() -> list[dict]:
    keys = {"walk": [], "stumble_forward": [], "stumble_backward": []}
    for p in np.arange(8) / 8:
        keys["walk"].append({"t": p, **_key(_walk_frame(p))})
        r = _scaled_swing(_walk_frame(p), ("UpLeg", "Leg"), 1.3)
        r = _pose(r, root_pitch=14, add_Spine=(0, 8, 0), add_Spine1=(0, 6, 0), add_Neck=(0, -14, 0),
                  Arm=(25, -55, 0), ForeArm=(0, -45, 0), add_Leg=(0, 8, 0))
        keys["stumble_forward"].append({"t": p, **_key(r, tilt_x=0.35, shift=(0.08, 0.0))})
    for p in np.arange(6) / 6:
        r = _scaled_swing(_walk_frame(p), ("UpLeg",), 0.75)
        r = _pose(r, root_pitch=-4, add_Spine=(0, 10, 0), add_Neck=(0, 8, 0), Arm=(30, -70, 0),
                  ForeArm=(0, -50, 0), add_Leg=(0, 12, 0), add_UpLeg=(0, -6, 0))
        keys["stumble_backward"].append({"t": p, **_key(r, tilt_x=-0.35, shift=(-0.05, 0.0))})
    return [{"name": "walk", "behaviour": WALKING, "axis": "d_z", "at": {"theta_x": 0.0}, "keys": keys["walk"]},
            {"name": "stumble_forward", "behaviour": WALKING, "axis": "d_z", "at": {"theta_x": 0.35},
             "keys": keys["stumble_forward"]},
            {"name": "stumble_backward", "behaviour": WALKING, "axis": "d_z", "at": {"theta_x": -0.35},
             "keys": keys["stumble_backward"]}]


def _lying_down() -> np.ndarray:
    return _pose(root_pitch=90, Neck=(0, -25, 0), Head=(0, 0, 35), Arm=(60, -70, 0), ForeArm=(0, -100, 0),
                 UpLeg=(4, 0, 0), Foot=(0, 45, 0))


def _lying_up() -> np.ndarray:
    return _pose(root_pitch=-90, Neck=(0, 12, 0), Arm=(22, 0, 0), ForeArm=(0, -25, 0), UpLeg=(6, -12, 0),
                 Leg=(0, 18, 0), Foot=(0, 20, 0))


def _falling_tracks() -> list[dict]:
    fwd = [(0.75, _pose(root_pitch=38, Spine=(0, 10, 0), Neck=(0, -28, 0), LeftUpLeg=(0, -72, 0),
                        LeftLeg=(0, 55, 0), LeftFoot=(0, -12, 0), RightUpLeg=(0, 5, 0), RightLeg=(0, 30, 0),
                        RightFoot=(0, 25, 0), Arm=(15, -85, 0), ForeArm=(0, -20, 0))),
           (1.15, _pose(root_pitch=68, Spine=(0, 6, 0), Neck=(0, -38, 0), LeftUpLeg=(0, -30, 0),
                        LeftLeg=(0, 45, 0), RightUpLeg=(0, -8, 0), RightLeg=(0, 30, 0), Foot=(0, 30, 0),
                        Arm=(18, -118, 0), ForeArm=(0, -18, 0))),
           (1.5708, _lying_down())]
    back = [(-0.7, _pose(root_pitch=-22, Spine=(0, 22, 0), Spine1=(0, 8, 0), Neck=(0, 18, 0),
                         UpLeg=(0, -55, 0), Leg=(0, 85, 0), Foot=(0, -20, 0), Arm=(28, -85, 0),
                         ForeArm=(0, -35, 0))),
            (-1.15, _pose(root_pitch=-32, Spine=(0, 26, 0), Neck=(0, 14, 0), UpLeg=(0, -78, 0),
                          Leg=(0, 55, 0), Arm=(22, 38, 0), ForeArm=(0, -12, 0))),
            (-1.5708, _lying_up())]
    side = [(0.7, _pose(root_roll=30, Spine=(5, 0, 0), Neck=(-12, 0, 0), LeftArm=(65, -10, 0),
                        LeftForeArm=(0, -20, 0), RightArm=(-130, -10, 0), RightForeArm=(0, -35, 0),
                        LeftUpLeg=(26, -10, 0), LeftLeg=(0, 22, 0), RightUpLeg=(12, 0, 0),
                        RightLeg=(0, 15, 0))),
            (1.1, _pose(root_roll=55, Spine=(8, 0, 0), Neck=(-20, 0, 0), LeftArm=(85, -20, 0),
                        LeftForeArm=(0, -10, 0), RightArm=(-155, 0, 0), RightForeArm=(0, -40, 0),
                        LeftUpLeg=(30, -20, 0), LeftLeg=(0, 30, 0), RightUpLeg=(22, -5, 0),
                        RightLeg=(0, 25, 0)))]

    def track(name, axis, at, pairs, tilt):
        return {"name": name, "behaviour": WALKING, "axis": axis, "at": at,
                "keys": [{"t": t, **_key(r, **{tilt: t})} for t, r in pairs]}

    return [track("fall_forward", "theta_x", {"d_z": 0.0}, fwd, "tilt_x"),
            track("fall_backward", "theta_x", {"d_z": 0.0}, back, "tilt_x"),
            track("fall_left", "theta_z", {"d_x": 0.0}, side, "tilt_z"),
            track("fall_right", "theta_z", {"d_x": 0.0}, [(-t, _mirror(r)) for t, r in side], "tilt_z")]


def _side_tracks() -> list[dict]:
    step = [_pose(Leg=(0, 6, 0), UpLeg=(0, -3, 0), ForeArm=(0, -10, 0)),
            _pose(LeftUpLeg=(20, -14, 0), LeftLeg=(0, 26, 0), RightUpLeg=(-4, 0, 0), Leg=(0, 5, 0),
                  LeftArm=(10, 0, 0), ForeArm=(0, -12, 0), root_roll=-3),
            _pose(LeftUpLeg=(12, 0, 0), RightUpLeg=(-12, 0, 0), Leg=(0, 6, 0), Arm=(6, 0, 0),
                  ForeArm=(0, -10, 0)),
            _pose(RightUpLeg=(4, -14, 0), RightLeg=(0, 26, 0), LeftUpLeg=(4, 0, 0), Leg=(0, 5, 0),
                  ForeArm=(0, -12, 0), root_roll=3)]
    left = [_pose(root_roll=16, Neck=(-8, 0, 0), Arm=(55, -10, 0), ForeArm=(0, -25, 0), LeftUpLeg=(8, -5, 0),
                  RightUpLeg=(-2, 0, 0), Leg=(0, 8, 0)),
            _pose(root_roll=16, Neck=(-8, 0, 0), Arm=(60, -15, 0), ForeArm=(0, -25, 0), LeftUpLeg=(30, -22, 0),
                  LeftLeg=(0, 35, 0), RightUpLeg=(-6, 0, 0), RightLeg=(0, 6, 0)),
            _pose(root_roll=16, Neck=(-8, 0, 0), Arm=(50, -10, 0), ForeArm=(0, -25, 0), LeftUpLeg=(22, 0, 0),
                  RightUpLeg=(12, 0, 0), Leg=(0, 10, 0)),
            _pose(root_roll=16, Neck=(-8, 0, 0), Arm=(60, -5, 0), ForeArm=(0, -30, 0), LeftUpLeg=(10, 0, 0),
                  RightUpLeg=(18, -25, 0), RightLeg=(0, 40, 0), LeftLeg=(0, 8, 0))]
    phases = [0.0, 0.25, 0.5, 0.75]
    return [{"name": "sidestep", "behaviour": WALKING, "axis": "d_x", "at": {"theta_z": 0.0},
             "keys": [{"t": p + 0.125, **_key(r)} for p, r in zip(phases, step)]},
            {"name": "stumble_left", "behaviour": WALKING, "axis": "d_x", "at": {"theta_z": 0.35},
             "keys": [{"t": p, **_key(r, tilt_z=0.35)} for p, r in zip(phases, left)]},
            {"name": "stumble_right", "behaviour": WALKING, "axis": "d_x", "at": {"theta_z": -0.35},
             "keys": [{"t": (1.0 - p) % 1.0, **_key(_mirror(r), tilt_z=-0.35)} for p, r in zip(phases, left)]}]


def _standing_tracks() -> list[dict]:
    stand = np.array(_setup()[4].local_rot[0])
    front = [(0.0, stand),
             (0.3, _pose(root_pitch=32, Spine=(0, 10, 0), Neck=(0, -18, 0), LeftUpLeg=(0, -78, 0),
                         RightUpLeg=(0, -62, 0), LeftLeg=(0, 80, 0), RightLeg=(0, 75, 0), Foot=(0, -8, 0),
                         Arm=(10, -45, 0), ForeArm=(0, -35, 0))),
             (0.65, _pose(root_pitch=22, Spine=(0, 14, 0), Neck=(0, -18, 0), LeftUpLeg=(0, -95, 0),
                          LeftLeg=(0, 92, 0), RightUpLeg=(0, -8, 0), RightLeg=(0, 95, 0),
                          RightFoot=(0, 40, 0), LeftArm=(8, -55, 0), LeftForeArm=(0, -40, 0),
                          RightArm=(6, -25, 0), RightForeArm=(0, -20, 0))),
             (0.95, _pose(root_pitch=84, Neck=(0, -38, 0), UpLeg=(3, -84, 0), Leg=(0, 90, 0), Foot=(0, 35, 0),
                          Arm=(4, -88, 0), ForeArm=(0, -5, 0))),
             (1.25, _pose(root_pitch=84, Spine=(0, -16, 0), Spine1=(0, -10, 0), Neck=(0, -30, 0),
                          Arm=(12, -52, 0), ForeArm=(0, -8, 0), Foot=(0, 50, 0), UpLeg=(3, 0, 0))),
             (1.5708, _lying_down())]
    back = [(-0.15, _pose(root_pitch=18, Spine=(0, 6, 0), UpLeg=(0, -40, 0), Leg=(0, 45, 0), Foot=(0, -6, 0),
                          Arm=(8, -25, 0), ForeArm=(0, -25, 0))),
            (-0.45, _pose(root_pitch=28, Spine=(0, 16, 0), Neck=(0, -16, 0), UpLeg=(4, -105, 0),
                          Leg=(0, 115, 0), Foot=(0, -12, 0), Arm=(12, -70, 0), ForeArm=(0, -20, 0))),
            (-0.8, _pose(root_pitch=-18, Spine=(0, 28, 0), Spine1=(0, 10, 0), UpLeg=(6, -105, 0),
                         Leg=(0, 120, 0), Foot=(0, -10, 0), Arm=(10, -62, 0), ForeArm=(0, -25, 0))),
            (-1.2, _pose(root_pitch=-58, Spine=(0, 16, 0), Neck=(0, 20, 0), UpLeg=(4, -62, 0), Leg=(0, 62, 0),
                         Arm=(12, 28, 0), ForeArm=(0, -85, 0))),
            (-1.5708, _lying_up())]

    def track(name, pairs):
        return {"name": name, "behaviour": STANDING, "axis": "theta_x", "at": {"d_z": 0.0},
                "keys": [{"t": t, **_key(r, tilt_x=t)} for t, r in pairs]}

    return [track("stand_up_front", front), track("stand_up_back", back)]


def build_dict() -> dict:
    """The built-in keyframe set as the file structure of :mod:`kinodyn.crowd.keyframes`."""
    _, scale, _, walk, _ = _setup()
    stride = float(walk.root_pos[60, 0] - walk.root_pos[0, 0]) * scale
    anims = _walking_tracks() + _falling_tracks() + _side_tracks() + _standing_tracks()
    for a in anims:
        for k in a["keys"]:
            k["t"] = round(float(k["t"]), 6)
    return {"format": FORMAT, "version": 1, "skeleton": "humanoid", "scale": round(scale, 9),
            "stride": round(stride, 6), "behaviours": [WALKING, STANDING], "animations": anims}


def write(path=BUILTIN_PATH) -> None:
    """Write the built-in set (atomically)."""
    from kinodyn.io.atomic import atomic_write_bytes

    atomic_write_bytes(path, (json.dumps(build_dict(), indent=1) + "\n").encode())


if __name__ == "__main__":  # pragma: no cover
    write()
