"""The keyframe space Q, the periodic mapping of travelled distance and multidimensional keyframe sets.

Mitake et al., sections 5.1 to 5.3 and equations 6 to 10. The keyframe space is
``Q = {Theta_x, Theta_z, D_x, D_z, B}``: forward and sideways tilt (identical to the rigid body's
``theta_x``, ``theta_z``, :mod:`kinodyn.crowd.body`), the phases of the distance travelled sideways and
forward, and the behaviour. Travel is integrated in the heading frame (equations 6, 7) and mapped to a
phase with the periodic function ``p(x) = x - floor(x)`` (equation 8) after dividing by the stride
length (the distance of one walk cycle, a parameter of the set): ``(D_x, D_z) = (p(D_side / stride),
p(D_front / stride))`` (equation 9).

A keyframe set is made of one-dimensional keyframe animations (section 5.3). Each animation runs along
one axis of Q with the other coordinates fixed, and lies in one of two planes of its behaviour: the
*forward plane* ``(Theta_z = 0, D_x = 0)`` spanned by ``(Theta_x, D_z)`` or the *side plane*
``(Theta_x = 0, D_z = 0)`` spanned by ``(Theta_z, D_x)``, as in the paper's figure 8. A keyframe is a
pose of the set's skeleton in the body frame Sr: the root position relative to the centre of mass and
every joint's local rotation (the root's relative to Sr).

File format (JSON, or YAML with the same structure; ``.json``, ``.yaml`` or ``.yml``)::

    format: kinodyn-keyframe-set        # required, exactly this
    version: 1                          # required
    skeleton: humanoid                  # "humanoid" (the built-in one) or {names, parents, offsets}
    scale: 0.857                        # optional, multiplies the skeleton's offsets (default 1)
    stride: 1.21                        # metres travelled per cycle of D (> 0)
    behaviours: [walking_and_falling, standing_up]
    animations:
      - name: walk                      # unique
        behaviour: walking_and_falling  # one of behaviours
        axis: d_z                       # theta_x, theta_z, d_x or d_z
        at: {theta_x: 0.0}              # the fixed coordinates of its plane (missing ones are 0)
        keys:
          - t: 0.0                      # coordinate along the axis: tilts in radians, phases in [0, 1)
            root: [0.0, 0.0, 0.04]      # root position in Sr, metres
            rotations: {Hips: [1, 0, 0, 0], LeftUpLeg: [0.97, 0, 0.24, 0]}   # (w, x, y, z); missing: identity

Tilts must lie in the ranges of equation 10 (``Theta_x`` in ``[-pi, pi]``, ``Theta_z`` in
``[-pi/2, pi/2]``); two keyframes of one behaviour may not share a point of Q. A keyframe where the
two planes meet (all four coordinates 0) belongs to both. Errors are
:class:`~kinodyn.errors.FileFormatError` naming the file, the animation, the key and what was expected.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinodyn.errors import FileFormatError, ParameterError
from kinodyn.skeleton import Skeleton

__all__ = [
    "AXES",
    "BUILTIN_PATH",
    "FORMAT",
    "FORWARD_PLANE",
    "SIDE_PLANE",
    "KeyframeSet",
    "builtin_keyframes",
    "keyframes_to_dict",
    "load_keyframes",
    "parse_keyframes",
    "periodic",
    "phases",
    "travel",
]

FORMAT = "kinodyn-keyframe-set"
AXES = ("theta_x", "theta_z", "d_x", "d_z")
FORWARD_PLANE, SIDE_PLANE = 0, 1
#: for each plane: (tilt axis, phase axis); the other two coordinates are zero on the plane.
PLANE_AXES = (("theta_x", "d_z"), ("theta_z", "d_x"))
_RANGES = {"theta_x": (-np.pi, np.pi), "theta_z": (-np.pi / 2, np.pi / 2), "d_x": (0.0, 1.0),
           "d_z": (0.0, 1.0)}
BUILTIN_PATH = Path(__file__).with_name("keyframes.json")


def periodic(x):
    """Equation 8, ``p(x) = x - floor(x)``: values ``(...)`` mapped into ``[0, 1)``."""
    x = np.asarray(x, dtype=np.float64)
    p = x - np.floor(x)
    return np.where(p >= 1.0, 0.0, p)  # -1e-17 - floor(-1e-17) rounds to 1.0


def phases(d_side, d_front, stride: float) -> tuple[np.ndarray, np.ndarray]:
    """Equation 9: ``(D_x, D_z) = (p(D_side / stride), p(D_front / stride))``.

    Args:
        d_side, d_front: ``(...)`` metres travelled sideways and forward (equations 6, 7).
        stride: metres per cycle (> 0).
    """
    if not (np.isfinite(stride) and stride > 0):
        raise ParameterError(f"stride must be a positive number of metres, got {stride!r}")
    return periodic(np.asarray(d_side) / stride), periodic(np.asarray(d_front) / stride)


def travel(d_side, d_front, vel, forward, left, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """One step of equations 6 and 7: the distances ``(N,)`` plus ``e . v dt`` in the heading frame.

    Args:
        d_side, d_front: ``(N,)`` distances so far, metres.
        vel: ``(N, 3)`` centre-of-mass velocity (its horizontal part counts), m/s.
        forward, left: ``(N, 3)`` the heading frame's ``e_zc`` and ``e_xc``.
        dt: seconds.
    """
    v = np.asarray(vel, dtype=np.float64)
    vx, vy = v[:, 0], v[:, 1]
    return (d_side + dt * (vx * left[:, 0] + vy * left[:, 1]), d_front + dt * (vx * forward[:, 0] + vy * forward[:, 1]))


@dataclass(frozen=True, eq=False)
class KeyframeSet:
    """A multidimensional keyframe set, packed for batched interpolation (section 5.1).

    Keyframes of one behaviour and plane are grouped into *levels* of equal tilt, each sorted by
    phase; :mod:`kinodyn.crowd.interpolate` blends the levels around a point.

    Attributes:
        skeleton: the posed skeleton (scaled).
        behaviours: behaviour names, the values of B.
        stride: metres per phase cycle.
        names: ``(A,)`` animation names.
        key_root: ``(K, 3)`` root positions in Sr.
        key_rot: ``(K, J, 4)`` local rotations.
        key_phase: ``(K,)`` phase of each keyframe.
        key_point: ``(K, 5)`` each keyframe's point (theta_x, theta_z, d_x, d_z, behaviour index).
        key_anim: ``(K,)`` index of the animation each keyframe belongs to.
        key_shared: ``(K,)`` True for the side-plane copy of a keyframe where the planes meet.
        level_tilt, level_start, level_count: ``(L,)`` levels: tilt, first key, number of keys.
        plane_start, plane_count: ``(B, 2)`` first level and number of levels of each behaviour and plane.
    """

    skeleton: Skeleton
    behaviours: tuple[str, ...]
    stride: float
    names: tuple[str, ...]
    key_root: np.ndarray
    key_rot: np.ndarray
    key_phase: np.ndarray
    key_point: np.ndarray
    key_anim: np.ndarray
    key_shared: np.ndarray
    level_tilt: np.ndarray
    level_start: np.ndarray
    level_count: np.ndarray
    plane_start: np.ndarray
    plane_count: np.ndarray

    @property
    def num_keys(self) -> int:
        return int(np.count_nonzero(~self.key_shared))

    def behaviour_index(self, name: str) -> int:
        if name not in self.behaviours:
            raise ParameterError(f"behaviour must be one of {', '.join(self.behaviours)}, got {name!r}")
        return self.behaviours.index(name)

    def replace_stride(self, stride: float) -> KeyframeSet:
        if not (np.isfinite(stride) and stride > 0):
            raise ParameterError(f"stride must be a positive number of metres, got {stride!r}")
        return KeyframeSet(**{**self.__dict__, "stride": float(stride)})


def _fail(msg: str, path) -> FileFormatError:
    return FileFormatError(msg, path=path)


def _number(v, what: str, path) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise _fail(f"{what} must be a finite number, got {v!r}", path)
    return float(v)


def _vector(v, n: int, what: str, path) -> np.ndarray:
    if not isinstance(v, (list, tuple)) or len(v) != n:
        raise _fail(f"{what} must be a list of {n} numbers, got {v!r}", path)
    return np.array([_number(x, what, path) for x in v])


def _skeleton(spec, scale: float, path) -> Skeleton:
    if spec == "humanoid":
        from kinodyn.data.skeleton import humanoid

        sk = humanoid()
    elif isinstance(spec, dict):
        try:
            sk = Skeleton(names=tuple(spec["names"]), parents=np.asarray(spec["parents"], dtype=np.int64),
                          offsets=np.asarray(spec["offsets"], dtype=np.float64))
        except KeyError as e:
            raise _fail(f"skeleton needs names, parents and offsets; {e.args[0]!r} is missing", path) from None
        except (TypeError, ValueError) as e:
            raise _fail(f"skeleton is not valid: {e}", path) from None
    else:
        raise _fail(f"skeleton must be 'humanoid' or a mapping with names, parents, offsets, got {spec!r}", path)
    return sk if scale == 1.0 else sk.scaled(scale)


def _plane(anim: dict, where: str, path) -> tuple[int, dict[str, float]]:
    axis = anim.get("axis")
    if axis not in AXES:
        raise _fail(f"{where}: axis must be one of {', '.join(AXES)}, got {axis!r}", path)
    at = anim.get("at", {}) or {}
    if not isinstance(at, dict) or any(k not in AXES for k in at):
        raise _fail(f"{where}: at must map coordinates ({', '.join(AXES)}) to numbers, got {at!r}", path)
    if axis in at:
        raise _fail(f"{where}: at must not fix the animation's own axis {axis!r}", path)
    fixed = {k: _number(at.get(k, 0.0), f"{where}: at.{k}", path) for k in AXES if k != axis}
    plane = FORWARD_PLANE if axis in PLANE_AXES[0] else SIDE_PLANE
    for k in PLANE_AXES[1 - plane]:
        if fixed[k] != 0.0:
            raise _fail(f"{where}: an animation along {axis} lies in the plane where "
                        f"{' and '.join(PLANE_AXES[1 - plane])} are 0, got at.{k}={fixed[k]}", path)
    return plane, fixed


def _check_range(axis: str, v: float, what: str, path) -> float:
    lo, hi = _RANGES[axis]
    if axis.startswith("d_"):
        if not 0.0 <= v < 1.0:
            raise _fail(f"{what}: phase {axis} must lie in [0, 1), got {v}", path)
    elif not lo - 1e-9 <= v <= hi + 1e-9:
        raise _fail(f"{what}: tilt {axis} must lie in [{lo:.4f}, {hi:.4f}] (equation 10), got {v}", path)
    return v


def _pose(key: dict, sk: Skeleton, what: str, path) -> tuple[np.ndarray, np.ndarray]:
    root = _vector(key.get("root", [0.0, 0.0, 0.0]), 3, f"{what}: root", path)
    rots = key.get("rotations", {}) or {}
    if not isinstance(rots, dict):
        raise _fail(f"{what}: rotations must map joint names to [w, x, y, z], got {type(rots).__name__}", path)
    rot = np.zeros((sk.num_joints, 4))
    rot[:, 0] = 1.0
    for name, q in rots.items():
        if name not in sk.names:
            raise _fail(f"{what}: unknown joint {name!r}; the skeleton's joints are {', '.join(sk.names)}", path)
        v = _vector(q, 4, f"{what}: rotation of {name}", path)
        n = np.linalg.norm(v)
        if n < 1e-6:
            raise _fail(f"{what}: rotation of {name} is a zero quaternion", path)
        rot[sk.index(name)] = v / n
    return root, rot


def _header(data, path) -> tuple[Skeleton, tuple[str, ...], float, list]:
    if not isinstance(data, dict):
        raise _fail(f"a keyframe set must be a mapping, got {type(data).__name__}", path)
    if data.get("format") != FORMAT:
        raise _fail(f"format must be {FORMAT!r}, got {data.get('format')!r}", path)
    if data.get("version") != 1:
        raise _fail(f"version must be 1, got {data.get('version')!r}", path)
    scale = _number(data.get("scale", 1.0), "scale", path)
    stride = _number(data.get("stride"), "stride", path)
    if scale <= 0 or stride <= 0:
        raise _fail(f"scale and stride must be positive, got {scale} and {stride}", path)
    beh = data.get("behaviours")
    if not isinstance(beh, list) or not beh or not all(isinstance(b, str) for b in beh) or len(set(beh)) < len(beh):
        raise _fail(f"behaviours must be a non-empty list of distinct names, got {beh!r}", path)
    anims = data.get("animations")
    if not isinstance(anims, list) or not anims:
        raise _fail("animations must be a non-empty list", path)
    return _skeleton(data.get("skeleton"), scale, path), tuple(beh), stride, anims


def parse_keyframes(data, path=None) -> KeyframeSet:
    """A :class:`KeyframeSet` from the parsed file structure (module docstring), validated.

    Raises:
        FileFormatError: naming the animation, the key and what is wrong.
    """
    sk, beh, stride, anims = _header(data, path)
    roots, rots, points, anim_of, names, seen = [], [], [], [], [], {}
    for a, anim in enumerate(anims):
        if not isinstance(anim, dict):
            raise _fail(f"animation {a} must be a mapping, got {type(anim).__name__}", path)
        name = anim.get("name")
        where = f"animation {name!r}" if isinstance(name, str) else f"animation {a}"
        if not isinstance(name, str) or name in names:
            raise _fail(f"{where}: name must be a unique string, got {name!r}", path)
        if anim.get("behaviour") not in beh:
            raise _fail(f"{where}: behaviour must be one of {', '.join(beh)}, got {anim.get('behaviour')!r}", path)
        b = beh.index(anim["behaviour"])
        plane, fixed = _plane(anim, where, path)
        keys = anim.get("keys")
        if not isinstance(keys, list) or not keys:
            raise _fail(f"{where}: keys must be a non-empty list", path)
        for i, key in enumerate(keys):
            what = f"{where}, key {i}"
            if not isinstance(key, dict):
                raise _fail(f"{what}: must be a mapping with t, root, rotations", path)
            coord = dict(fixed)
            coord[anim["axis"]] = _number(key.get("t"), f"{what}: t", path)
            for k, v in coord.items():
                _check_range(k, v, what, path)
            pt = (coord["theta_x"], coord["theta_z"], coord["d_x"], coord["d_z"], b)
            if pt in seen:
                raise _fail(f"{what}: its point {pt[:4]} already holds {seen[pt]}", path)
            seen[pt] = what
            root, rot = _pose(key, sk, what, path)
            roots.append(root), rots.append(rot), points.append(pt + (plane,)), anim_of.append(a)
        names.append(name)
    return _pack(sk, beh, stride, tuple(names), np.array(roots), np.array(rots), np.array(points), anim_of)


def _pack(sk, beh, stride, names, roots, rots, points, anim_of) -> KeyframeSet:
    """Group keyframes into levels of (behaviour, plane, tilt), sorted by phase.

    A keyframe at the point where a behaviour's two planes meet (all four coordinates 0) belongs to
    both: a copy goes into the side plane (``key_shared`` marks it) when that plane has keyframes.
    """
    has_side = {int(p[4]) for p in points if p[5] == SIDE_PLANE}
    origin = np.flatnonzero(np.all(points[:, :4] == 0.0, axis=1) & np.isin(points[:, 4], list(has_side))
                            & (points[:, 5] == FORWARD_PLANE))
    shared = np.zeros(len(points) + len(origin), bool)
    shared[len(points):] = True
    copies = points[origin].copy()
    copies[:, 5] = SIDE_PLANE
    roots, rots = np.concatenate([roots, roots[origin]]), np.concatenate([rots, rots[origin]])
    points = np.concatenate([points, copies])
    anim_of = list(anim_of) + [anim_of[k] for k in origin]
    plane = points[:, 5].astype(int)
    b = points[:, 4].astype(int)
    tilt = np.where(plane == FORWARD_PLANE, points[:, 0], points[:, 1])
    phase = np.where(plane == FORWARD_PLANE, points[:, 3], points[:, 2])
    order = np.lexsort((phase, tilt, plane, b))
    lt, ls, lc = [], [], []
    ps = np.zeros((len(beh), 2), np.int64)
    pc = np.zeros((len(beh), 2), np.int64)
    prev = None
    for pos, k in enumerate(order):
        group = (b[k], plane[k], tilt[k])
        if group != prev:
            if prev is None or group[:2] != prev[:2]:
                ps[group[0], group[1]] = len(lt)
            pc[group[0], group[1]] += 1
            lt.append(tilt[k]), ls.append(pos), lc.append(0)
            prev = group
        lc[-1] += 1
    arr = np.asarray
    return KeyframeSet(skeleton=sk, behaviours=beh, stride=float(stride), names=names,
                       key_root=_ro(roots[order]), key_rot=_ro(rots[order]), key_phase=_ro(phase[order]),
                       key_point=_ro(points[order, :5]), key_anim=_ro(arr(anim_of)[order]),
                       key_shared=_ro(shared[order]),
                       level_tilt=_ro(arr(lt, float)), level_start=_ro(arr(ls, np.int64)),
                       level_count=_ro(arr(lc, np.int64)), plane_start=_ro(ps), plane_count=_ro(pc))


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def load_keyframes(path) -> KeyframeSet:
    """Read and validate a keyframe-set file (``.json``, ``.yaml``, ``.yml``)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such keyframe-set file")
    text = path.read_text(encoding="utf-8")
    if path.suffix.lower() in (".yaml", ".yml"):
        import yaml

        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as e:
            raise _fail(f"not valid YAML: {e}", path) from None
    elif path.suffix.lower() == ".json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise FileFormatError(f"not valid JSON: {e.msg}", path=path, line=e.lineno) from None
    else:
        raise _fail(f"a keyframe set must be .json, .yaml or .yml, got {path.suffix or 'no suffix'!r}", path)
    return parse_keyframes(data, path)


def keyframes_to_dict(ks: KeyframeSet, skeleton="humanoid", scale: float = 1.0) -> dict:
    """The file structure of a keyframe set (the inverse of :func:`parse_keyframes`).

    Args:
        ks: the set.
        skeleton: what to write as ``skeleton`` (the set's own skeleton must be it, scaled by ``scale``).
        scale: what to write as ``scale``.
    """
    anims = []
    for a, name in enumerate(ks.names):
        idx = np.flatnonzero((ks.key_anim == a) & ~ks.key_shared)
        pts = ks.key_point[idx]
        varying = [AXES[c] for c in range(4) if np.ptp(pts[:, c]) > 0]
        axis = varying[0] if varying else ("d_z" if pts[0, 1] == 0 and pts[0, 2] == 0 else "d_x")
        c = AXES.index(axis)
        plane = FORWARD_PLANE if axis in PLANE_AXES[0] else SIDE_PLANE
        at = {k: float(pts[0, AXES.index(k)]) for k in PLANE_AXES[plane] if k != axis}
        keys = [{"t": float(ks.key_point[k, c]), "root": [round(float(v), 6) for v in ks.key_root[k]],
                 "rotations": {j: [round(float(v), 6) for v in ks.key_rot[k, i]]
                               for i, j in enumerate(ks.skeleton.names)
                               if np.abs(ks.key_rot[k, i] - [1, 0, 0, 0]).max() > 1e-9}}
                for k in idx[np.argsort(ks.key_point[idx, c], kind="stable")]]
        anims.append({"name": name, "behaviour": ks.behaviours[int(pts[0, 4])], "axis": axis, "at": at,
                      "keys": keys})
    return {"format": FORMAT, "version": 1, "skeleton": skeleton, "scale": scale, "stride": ks.stride,
            "behaviours": list(ks.behaviours), "animations": anims}


def builtin_keyframes() -> KeyframeSet:
    """The built-in set of figure 8 for the built-in humanoid (``keyframes.json`` beside this module)."""
    return load_keyframes(BUILTIN_PATH)
