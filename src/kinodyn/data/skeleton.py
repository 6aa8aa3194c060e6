"""The built-in humanoid: 21 joints, Z up, metres, facing +X, left = +Y, about 1.75 m tall.

The rest pose (every local rotation the identity) is a person standing straight with the arms hanging
at the sides and the feet pointing forward: every limb bone points straight down (local ``-Z``), the
spine straight up. So in every joint's local frame +X is forward, +Y is left and +Z is up (for the
rest pose), and Euler angles read the same way on every joint: a rotation about +Y bends the spine
forward, swings a leg or an arm backward and flexes the knee; about -Y it flexes the elbow; about +X it
raises the left arm or leg sideways (the right one inward).

The skeleton is exactly left/right symmetric, so a mirrored clip keeps the same skeleton object
(:meth:`kinodyn.skeleton.Skeleton.mirrored` returns ``self``).

Foot geometry (used by the clip generators): the ankle (``LeftFoot``) is :data:`ANKLE_HEIGHT` above
the floor when the foot is flat; the ball (``LeftToeBase``) and the toe tip (end site) are
:data:`SOLE` above it, the sole's half thickness, so a flat foot's lowest points rest at ``SOLE``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from kinodyn.skeleton import Skeleton

__all__ = [
    "ANKLE_HEIGHT",
    "BALL",
    "FOREARM",
    "HEEL",
    "HIP_WIDTH",
    "JOINTS",
    "SEGMENT_RADIUS",
    "SHIN",
    "SOLE",
    "STAND_HEIGHT",
    "THIGH",
    "UPPER_ARM",
    "humanoid",
]

#: Thigh and shin lengths (m): the leg reaches THIGH + SHIN from hip to ankle.
THIGH = 0.43
SHIN = 0.43
UPPER_ARM = 0.29
FOREARM = 0.26
#: Height of the ball and toe tip above the floor when the foot is flat (sole half thickness).
SOLE = 0.025
#: Ball of the foot (LeftToeBase) and the (virtual) heel in the foot's frame, relative to the ankle.
BALL = np.array([0.13, 0.0, -0.06])
HEEL = np.array([-0.05, 0.0, -0.06])
#: Height of the ankle above the floor when the foot is flat.
ANKLE_HEIGHT = SOLE - BALL[2]
#: Lateral offset of each hip joint from the pelvis centre.
HIP_WIDTH = 0.09
_HIP_DROP = 0.06
#: Root height of the rest pose standing on flat feet (legs straight).
STAND_HEIGHT = ANKLE_HEIGHT + SHIN + THIGH + _HIP_DROP
#: Approximate radius (m) of the body segments around each joint, by joint name: how high a joint sits
#: above the floor when that part of a lying body rests on it.
SEGMENT_RADIUS = {
    "Hips": 0.11, "Spine": 0.11, "Spine1": 0.12, "Neck": 0.06, "Head": 0.09, "Shoulder": 0.06, "Arm": 0.05,
    "ForeArm": 0.045, "Hand": 0.03, "UpLeg": 0.08, "Leg": 0.06, "Foot": 0.05, "ToeBase": SOLE,
}

# (name, parent, offset) in depth-first order (BVH needs each subtree contiguous).
_LEFT_ARM = [
    ("LeftShoulder", "Spine1", (0.0, 0.02, 0.17)),
    ("LeftArm", "LeftShoulder", (0.0, 0.16, 0.0)),
    ("LeftForeArm", "LeftArm", (0.0, 0.0, -UPPER_ARM)),
    ("LeftHand", "LeftForeArm", (0.0, 0.0, -FOREARM)),
]
_LEFT_LEG = [
    ("LeftUpLeg", "Hips", (0.0, HIP_WIDTH, -_HIP_DROP)),
    ("LeftLeg", "LeftUpLeg", (0.0, 0.0, -THIGH)),
    ("LeftFoot", "LeftLeg", (0.0, 0.0, -SHIN)),
    ("LeftToeBase", "LeftFoot", tuple(BALL)),
]


def _right(rows):
    return [(n.replace("Left", "Right"), p.replace("Left", "Right"), (o[0], -o[1], o[2])) for n, p, o in rows]


_ROWS = ([("Hips", None, (0.0, 0.0, 0.0)), ("Spine", "Hips", (0.0, 0.0, 0.10)),
          ("Spine1", "Spine", (0.0, 0.0, 0.18)), ("Neck", "Spine1", (0.0, 0.0, 0.20)),
          ("Head", "Neck", (0.0, 0.0, 0.09))]
         + _LEFT_ARM + _right(_LEFT_ARM) + _LEFT_LEG + _right(_LEFT_LEG))

#: Joint names in skeleton order.
JOINTS: tuple[str, ...] = tuple(r[0] for r in _ROWS)

# End sites: head top, finger tips, toe tips.
_ENDS = [("Head", (0.0, 0.0, 0.17)), ("LeftHand", (0.0, 0.0, -0.18)), ("RightHand", (0.0, 0.0, -0.18)),
         ("LeftToeBase", (0.06, 0.0, 0.0)), ("RightToeBase", (0.06, 0.0, 0.0))]


@lru_cache(maxsize=1)
def humanoid() -> Skeleton:
    """The built-in humanoid skeleton (the same object on every call; it is immutable).

    21 joints: Hips (root), Spine, Spine1, Neck, Head, Left/Right Shoulder, Arm, ForeArm, Hand,
    Left/Right UpLeg, Leg, Foot, ToeBase; end sites on the head, both hands and both toes.
    """
    index = {n: i for i, n in enumerate(JOINTS)}
    parents = [-1 if p is None else index[p] for _, p, _ in _ROWS]
    offsets = [o for _, _, o in _ROWS]
    # The root offset is its rest height, kept for file round trips (motions carry root_pos).
    offsets[0] = (0.0, 0.0, STAND_HEIGHT)
    return Skeleton(names=JOINTS, parents=np.array(parents), offsets=np.array(offsets, dtype=np.float64),
                    end_parents=np.array([index[p] for p, _ in _ENDS]),
                    end_offsets=np.array([o for _, o in _ENDS], dtype=np.float64))
