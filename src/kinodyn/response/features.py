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
from kinodyn.math.kernels import qmul

__all__ = ["FEATURE_SETS", "FEET", "SPINE", "feature_names", "features"]

FEATURE_SETS = ("large", "small")
#: Segments along the spine (pelvis, abdomen, chest, head) and the feet, on the built-in skeleton;
#: other skeletons map through the same names where they have them.
SPINE = ("Hips", "Spine", "Spine1", "Head")
FEET = ("LeftFoot", "RightFoot")


@numba.njit(cache=True)
def _rotate(q, v):  # pragma: no cover - compiled
    """:func:`kinodyn.math.quat.mul_vec` of one ``q (4,)`` and vectors ``v (N, 3)``, the same arithmetic in
    the same order (bit for bit; without numpy's per-call overhead, which is most of a feature vector;
    compiled without fast-math, so no fused multiply-adds either)."""
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


@numba.njit(cache=True)
def _large_slice(q, origin, pos, rot, linvel, angvel, feet, spine, feet_idx, out):  # pragma: no cover
    """The 66 ``large`` values of one state into ``out``: the spine bodies' positions (from ``origin``),
    orientations (``quat.abs(quat.mul(q, .))``, the same arithmetic in the same order), linear and
    angular velocities, the feet's positions and velocities, all rotated by ``q``, then the contacts."""
    n_s, n_f = spine.shape[0], feet_idx.shape[0]
    vec = np.empty((3 * n_s + 2 * n_f, 3))
    for a in range(n_s):
        for k in range(3):
            vec[a, k] = pos[spine[a], k] - origin[k]
            vec[n_s + a, k] = linvel[spine[a], k]
            vec[2 * n_s + a, k] = angvel[spine[a], k]
    for a in range(n_f):
        for k in range(3):
            vec[3 * n_s + a, k] = pos[feet_idx[a], k] - origin[k]
            vec[3 * n_s + n_f + a, k] = linvel[feet_idx[a], k]
    r = _rotate(q, vec)
    o = 0
    for a in range(n_s):
        for k in range(3):
            out[o] = r[a, k]
            o += 1
    aw, ax, ay, az = q[0], q[1], q[2], q[3]
    for a in range(n_s):
        b = rot[spine[a]]
        m = qmul(aw, ax, ay, az, b[0], b[1], b[2], b[3])
        for k in range(4):
            out[o] = -m[k] if m[0] < 0.0 else m[k]
            o += 1
    for a in range(n_s, r.shape[0]):
        for k in range(3):
            out[o] = r[a, k]
            o += 1
    for a in range(feet.shape[0]):
        out[o] = 1.0 if feet[a] else 0.0
        o += 1


def _large(states, q, origin) -> np.ndarray:
    names = list(states[0].names)
    spine = np.array(_index(names, SPINE, "large"), dtype=np.int64)
    feet = np.array(_index(names, FEET, "large"), dtype=np.int64)
    width = 12 * len(SPINE) + 8 * len(FEET) + 2  # 66
    out = np.empty((len(states), width))
    for i, s in enumerate(states):  # three slices, one compiled call each
        _large_slice(q, origin, s.pos, s.quat, s.linvel, s.angvel, s.feet, spine, feet, out[i])
    return out.ravel()


@numba.njit(cache=True)
def _small_values(q, com, com_vel, chest_w, pelvis, feet, out):  # pragma: no cover - compiled
    """The 20 ``small`` values into ``out`` from the three slices' centre-of-mass positions and velocities
    ``com, com_vel (3, 3)``, the chest's angular velocity ``chest_w (2, 3)`` at 0.1 and 0.2 s, the pelvis'
    orientation ``pelvis (4,)`` and the foot contacts ``feet (2,)`` at 0.2 s: the vectors rotated by ``q``
    (the arithmetic of ``quat.mul_vec`` and ``quat.mul``, in the same order)."""
    vec = np.empty((6, 3))
    vec[:3] = com_vel
    vec[3:5] = chest_w
    m = qmul(q[0], q[1], q[2], q[3], pelvis[0], pelvis[1], pelvis[2], pelvis[3])
    up = _rotate(np.array([m[0], m[1], m[2], m[3]]), np.array([[0.0, 0.0, 1.0]]))
    r = _rotate(q, vec[:5])
    for t in range(3):
        out[4 * t] = com[t, 2]
        for k in range(3):
            out[4 * t + 1 + k] = r[t, k]
    out[12], out[13], out[14], out[15] = r[3, 0], r[3, 1], r[4, 0], r[4, 1]
    out[16], out[17] = up[0, 0], up[0, 1]
    out[18] = 1.0 if feet[0] else 0.0
    out[19] = 1.0 if feet[1] else 0.0


def _small(states, q, origin) -> np.ndarray:
    names = list(states[0].names)
    chest, pelvis = _index(names, ("Spine1", "Hips"), "small")
    out = np.empty(20)
    _small_values(q, np.array([s.com for s in states], dtype=np.float64),
                  np.array([s.com_vel for s in states], dtype=np.float64),
                  np.array([s.angvel[chest] for s in states[1:]], dtype=np.float64),
                  np.ascontiguousarray(states[-1].quat[pelvis], dtype=np.float64), states[-1].feet, out)
    return out


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
