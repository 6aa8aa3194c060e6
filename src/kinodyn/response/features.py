"""Feature vectors of the reaction classifier (dynamic response, section 4.2).

From the simulated character's state at tenth-of-a-second slices after the contact (0.0, 0.1 and 0.2 s;
the paper found nothing gained after 0.2 s and much lost without 0.0 s):

* ``large``: the 6-DOF state and its derivative (position, orientation, linear and angular velocity) of
  the bodies along the spine (pelvis, abdomen, chest, head), plus the feet's position, velocity and
  contact: 66 values a slice, 198 in all. No centre-of-mass terms, as in the paper's best set.
* ``small``: 20 hand-picked terms with the balance terms: centre-of-mass height and velocity at each
  slice (12), the chest's angular velocity about the two horizontal axes at 0.1 and 0.2 s (4), the
  pelvis' lean (horizontal part of its up axis) at 0.2 s (2) and the foot contacts at 0.2 s (2).

Everything is expressed in the character's facing frame at the contact (origin under the centre of
mass, +X the pelvis' heading), so features do not depend on where the character stands or faces.
States are :class:`kinodyn.physics.CharacterState` (uses that public type only).
"""

from __future__ import annotations

import numba
import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.math import quat

__all__ = ["FEATURE_SETS", "SPINE", "FEET", "features", "feature_names"]

FEATURE_SETS = ("large", "small")
#: Segments along the spine (pelvis, abdomen, chest, head) and the feet, on the built-in skeleton;
#: other skeletons map through the same names where they have them.
SPINE = ("Hips", "Spine", "Spine1", "Head")
FEET = ("LeftFoot", "RightFoot")


@numba.njit(cache=True)
def _rotate(q, v):  # pragma: no cover - compiled
    """:func:`kinodyn.math.quat.mul_vec` of one ``q (4,)`` and vectors ``v (N, 3)``, the same arithmetic in
    the same order (bit for bit; without numpy's per-call overhead, which is most of a feature vector)."""
    w, ux, uy, uz = q[0], q[1], q[2], q[3]
    out = np.empty_like(v)
    for n in range(v.shape[0]):
        vx, vy, vz = v[n, 0], v[n, 1], v[n, 2]
        tx, ty, tz = 2.0 * (uy * vz - uz * vy), 2.0 * (uz * vx - ux * vz), 2.0 * (ux * vy - uy * vx)
        out[n, 0] = vx + w * tx + (uy * tz - uz * ty)
        out[n, 1] = vy + w * ty + (uz * tx - ux * tz)
        out[n, 2] = vz + w * tz + (ux * ty - uy * tx)
    return out


def _frame(state0):
    """Facing frame at the contact: origin under the com, rotation removing the pelvis' heading."""
    f = _rotate(np.asarray(state0.quat[0], dtype=np.float64), np.array([[1.0, 0.0, 0.0]]))[0]
    h = float(np.arctan2(f[1], f[0]))  # quat.heading(q, +X), in (-pi, pi]
    q = quat.from_heading(-(h + 2.0 * np.pi if h <= -np.pi else h))
    origin = np.array([state0.com[0], state0.com[1], 0.0])
    return q, origin


def _index(names, wanted, fallback: str) -> list[int]:
    out = []
    for w in wanted:
        if w not in names:
            raise ParameterError(f"the character has no segment {w!r} needed by the {fallback} features; "
                                 f"segments: {', '.join(names)}")
        out.append(names.index(w))
    return out


def _large(states, q, origin) -> np.ndarray:
    names = list(states[0].names)
    spine, feet = _index(names, SPINE, "large"), _index(names, FEET, "large")
    pos = np.stack([s.pos for s in states])  # (3, B, 3); every slice rotated in one call below
    vel = np.stack([s.linvel for s in states])
    vec = np.concatenate([pos[:, spine] - origin, vel[:, spine], np.stack([s.angvel[spine] for s in states]),
                          pos[:, feet] - origin, vel[:, feet]], axis=1)  # (3, 18, 3)
    r = _rotate(q, vec.reshape(-1, 3)).reshape(len(states), -1)
    rot = quat.abs(quat.mul(q, np.stack([s.quat[spine] for s in states]))).reshape(len(states), -1)
    feet_on = np.stack([s.feet for s in states]).astype(np.float64)
    return np.concatenate([r[:, :12], rot, r[:, 12:], feet_on], axis=1).ravel()


def _small(states, q, origin) -> np.ndarray:
    names = list(states[0].names)
    chest, pelvis = _index(names, ("Spine1",), "small")[0], _index(names, ("Hips",), "small")[0]
    vec = np.stack([s.com_vel for s in states] + [s.angvel[chest] for s in states[1:]])  # (5, 3)
    r = _rotate(q, vec)
    up = quat.mul_vec(quat.mul(q, states[-1].quat[pelvis]), [0.0, 0.0, 1.0])
    com = np.concatenate([np.array([[s.com[2]] for s in states]), r[:3]], axis=1).ravel()
    return np.concatenate([com, r[3:, :2].ravel(), up[:2], states[-1].feet.astype(np.float64)])


def features(states, kind: str = "large") -> np.ndarray:
    """The ``kind`` feature vector ``(n,)`` of states sampled at 0.0, 0.1 and 0.2 s after contact.

    Args:
        states: three :class:`kinodyn.physics.CharacterState`, in time order.
        kind: ``"large"`` (198 values) or ``"small"`` (20).
    """
    if kind not in FEATURE_SETS:
        raise ParameterError(f"feature set must be one of {', '.join(FEATURE_SETS)}, got {kind!r}")
    if len(states) != 3:
        raise ParameterError(f"features need the states at 0.0, 0.1 and 0.2 s after contact, got {len(states)}")
    q, origin = _frame(states[0])
    return _large(states, q, origin) if kind == "large" else _small(states, q, origin)


def feature_names(kind: str = "large") -> list[str]:
    """Names of the entries of :func:`features` (for plots and the model's JSON)."""
    if kind == "small":
        out = [f"{w}@{t}" for t in ("0.0", "0.1", "0.2") for w in ("com_z", "com_vx", "com_vy", "com_vz")]
        out += [f"chest_w{a}@{t}" for t in ("0.1", "0.2") for a in "xy"]
        return out + ["pelvis_lean_x@0.2", "pelvis_lean_y@0.2", "left_contact@0.2", "right_contact@0.2"]
    if kind != "large":
        raise ParameterError(f"feature set must be one of {', '.join(FEATURE_SETS)}, got {kind!r}")
    out = []
    for t in ("0.0", "0.1", "0.2"):
        for part, width in (("pos", 3), ("quat", 4), ("linvel", 3), ("angvel", 3)):
            out += [f"{b}.{part}{i}@{t}" for b in SPINE for i in range(width)]
        out += [f"{b}.{part}{i}@{t}" for part in ("pos", "linvel") for b in FEET for i in range(3)]
        out += [f"left_contact@{t}", f"right_contact@{t}"]
    return out
