"""Things a viewer page draws besides characters: props, forces, markers, stages, and reading helpers.

* :class:`Prop`: a sphere, box, capsule or mesh with a trajectory (a ball, a crate, a simulated object),
  position ``(F, 3)`` and optionally orientation ``(F, 4)`` (w, x, y, z) at ``fps`` from ``start``.
* :class:`Forces`: contact points with force or impulse arrows over time (each shown from its time for
  ``hold`` seconds).
* :class:`Marker`: a labelled time on the timeline.
* :class:`Stages`: a character's timeline coloured by stage (motion data, simulation, transition,
  clip), the bar the dynamic response fills; its colours are :data:`kinodyn.plotting.style.STAGE_COLORS`.
* :func:`centre_of_mass`: the centre of mass of a drawn body, with uniform density over its capsules
  (the page computes the same per frame for its centre-of-mass overlay).
* :func:`point_sides`: which side (left, centre, right) each point of a body is on, from joint names.
* :func:`lane_offsets`, :func:`face_points`: side-by-side lanes across the direction of travel, and the
  points that tell where a head faces.

World convention: Z up, metres, seconds, quaternions (w, x, y, z).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.skeleton import mirror_name
from kinodyn.plotting import style

__all__ = [
    "PROP_SHAPES",
    "Forces",
    "Marker",
    "Prop",
    "Stages",
    "centre_of_mass",
    "check_prop",
    "face_points",
    "lane_offsets",
    "lane_view",
    "point_sides",
    "travel_direction",
]

PROP_SHAPES = ("sphere", "box", "capsule", "mesh")
_SIZE_LEN = {"sphere": 1, "box": 3, "capsule": 2, "mesh": 0}


@dataclass(frozen=True)
class Prop:
    """An object in the world with its trajectory.

    Attributes:
        shape: ``"sphere"`` (``size = (radius,)``), ``"box"`` (``size = (hx, hy, hz)`` half extents),
            ``"capsule"`` (``size = (radius, half_length)``, axis along the local Z) or ``"mesh"``
            (``vertices`` and ``faces``, ``size`` unused).
        positions: ``(F, 3)`` or ``(3,)`` centre in the world (m); one row is a still object.
        quats: ``(F, 4)`` or ``(4,)`` orientation (w, x, y, z), or ``None`` for the identity.
        fps: frame rate of ``positions`` (frames a second).
        start: scene time (s) of frame 0; before it and after the last frame the object is hidden when
            ``hide_outside`` is set, held otherwise.
        color: ``"#rrggbb"``; label: text for the legend.
        vertices: ``(V, 3)`` mesh vertices in the object frame (m); faces: ``(T, 3)`` int triangles.
        trail: draw the path of the centre.
        opacity: 1 for solid; less draws it translucent (the walls of a room, so the characters
            behind them show).
    """

    shape: str
    positions: np.ndarray
    size: Sequence[float] = (0.1,)
    quats: np.ndarray | None = None
    fps: float = 60.0
    start: float = 0.0
    color: str = "#8c6d4f"
    label: str = ""
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    trail: bool = True
    hide_outside: bool = False
    opacity: float = 1.0


def check_prop(p: Prop, i: int = 0) -> tuple[np.ndarray, np.ndarray | None]:
    """Validate a :class:`Prop`; returns its ``(F, 3)`` positions and ``(F, 4)`` quaternions or ``None``.

    Raises:
        ParameterError: an unknown shape, a size of the wrong length, bad shapes or non-finite values.
    """
    if p.shape not in PROP_SHAPES:
        raise ParameterError(f"prop {i}: shape must be one of {', '.join(PROP_SHAPES)}, got {p.shape!r}")
    pos = np.asarray(p.positions, dtype=np.float64)
    pos = pos[None] if pos.shape == (3,) else pos
    if pos.ndim != 2 or pos.shape[1] != 3 or len(pos) == 0 or not np.all(np.isfinite(pos)):
        raise ParameterError(f"prop {i}: positions must be finite, shape (F, 3) or (3,), got {np.shape(p.positions)}")
    size = np.asarray(p.size, dtype=np.float64).ravel()
    need = _SIZE_LEN[p.shape]
    if need and (size.shape != (need,) or not np.all(np.isfinite(size)) or np.any(size <= 0)):
        raise ParameterError(f"prop {i}: a {p.shape} needs {need} positive size value(s), got {list(size)}")
    if p.shape == "mesh":
        v = np.asarray(p.vertices if p.vertices is not None else np.zeros((0, 3)), dtype=np.float64)
        f = np.asarray(p.faces if p.faces is not None else np.zeros((0, 3)), dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise ParameterError(f"prop {i}: a mesh needs vertices (V, 3) and faces (T, 3), got {v.shape} and {f.shape}")
        if f.min() < 0 or f.max() >= len(v):
            raise ParameterError(f"prop {i}: face indices must be in 0..{len(v) - 1}, got {f.min()}..{f.max()}")
    if not (np.isfinite(p.fps) and p.fps > 0):
        raise ParameterError(f"prop {i}: fps must be positive, got {p.fps}")
    if not (np.isfinite(p.opacity) and 0 < p.opacity <= 1):
        raise ParameterError(f"prop {i}: opacity must be in (0, 1], got {p.opacity}")
    q = None
    if p.quats is not None:
        q = np.asarray(p.quats, dtype=np.float64)
        if q.shape == (4,):
            q = np.tile(q, (len(pos), 1))
        if q.shape != (len(pos), 4) or not np.all(np.isfinite(q)):
            raise ParameterError(f"prop {i}: quats must have shape ({len(pos)}, 4) or (4,), got {np.shape(p.quats)}")
        q = q / np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-12)
    return pos, q


@dataclass(frozen=True)
class Forces:
    """Contact points and force or impulse arrows over time.

    Attributes:
        times: ``(N,)`` scene times (s).
        points: ``(N, 3)`` world points of application (m).
        vectors: ``(N, 3)`` forces (N) or impulses (N s); each arrow points along its vector and ends at
            its point.
        kind: ``"force"`` or ``"impulse"`` (the unit of ``scale``).
        scale: arrow length in metres per unit of ``vectors`` (lengths clamped to 0.05 .. 1 m).
        hold: seconds each arrow stays drawn from its time.
        character: index of the character the forces act on, if any.
        color: arrow colour; label: text for legends.
    """

    times: np.ndarray
    points: np.ndarray
    vectors: np.ndarray
    kind: str = "force"
    scale: float = 0.0004
    hold: float = 1 / 30
    character: int | None = None
    color: str = "#9467bd"
    label: str = ""

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Validated ``(N,)`` times, ``(N, 3)`` points and ``(N, 3)`` vectors (sorted by time)."""
        t = np.asarray(self.times, dtype=np.float64).ravel()
        p = np.asarray(self.points, dtype=np.float64)
        v = np.asarray(self.vectors, dtype=np.float64)
        if p.shape != (len(t), 3) or v.shape != (len(t), 3):
            raise ParameterError(f"Forces points and vectors must have shape ({len(t)}, 3), got {p.shape} and {v.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p)) and np.all(np.isfinite(v))):
            raise ParameterError("Forces times, points and vectors must be finite")
        if self.kind not in ("force", "impulse"):
            raise ParameterError(f"Forces kind must be 'force' or 'impulse', got {self.kind!r}")
        if not (np.isfinite(self.scale) and self.scale > 0 and np.isfinite(self.hold) and self.hold > 0):
            raise ParameterError(f"Forces scale and hold must be positive, got {self.scale} and {self.hold}")
        order = np.argsort(t, kind="stable")
        return t[order], p[order], v[order]


@dataclass(frozen=True)
class Marker:
    """A labelled time on the timeline (``time`` s, ``label``, ``color``)."""

    time: float
    label: str = ""
    color: str = "#333333"


@dataclass(frozen=True)
class Stages:
    """Stages of one character's timeline: ``(start_s, stop_s, stage)`` spans in scene time.

    Stage names with a colour in :data:`kinodyn.plotting.style.STAGE_COLORS` (``motion data``,
    ``simulation``, ``transition``, ``clip``) take it; others take ``colors`` or grey. With ``tint``
    the character's body is also drawn in the colour of the stage it is in (its own colour outside
    every span).
    """

    spans: Sequence[tuple[float, float, str]]
    character: int | None = None
    label: str = "stages"
    colors: Mapping[str, str] | None = None
    tint: bool = False

    def colored_spans(self) -> tuple[list[tuple[float, float, str]], dict[str, str]]:
        """Checked spans and the colour of every stage (for a :class:`kinodyn.viz.world.Phases` bar)."""
        cols = dict(style.STAGE_COLORS)
        cols.update(self.colors or {})
        spans = []
        for a, b, lab in self.spans:
            if not (np.isfinite(a) and np.isfinite(b) and b >= a):
                raise ParameterError(f"stage spans must be finite (start, stop) with stop >= start, got ({a}, {b})")
            spans.append((float(a), float(b), str(lab)))
        return spans, cols


# --------------------------------------------------------------------------- reading a body

_LEFT = re.compile(r"^(left|l(?=[A-Z_])|l_)|Left|_[lL]$|^l(femur|tibia|foot|toes|clavicle|humerus|radius|wrist|"
                   r"hand|fingers|thumb|hipjoint)")


def point_sides(names: Sequence[str]) -> np.ndarray:
    """``(P,)`` int8 side of each point: ``-1`` left, ``1`` right, ``0`` centre, from its name.

    End sites (``<joint>_end``) take their joint's side; a name is sided when
    :func:`kinodyn.skeleton.mirror_name` maps it to another name.
    """
    out = np.zeros(len(names), dtype=np.int8)
    for i, n in enumerate(names):
        base = n.removesuffix("_end")
        if mirror_name(base) != base:
            out[i] = -1 if _LEFT.search(base) else 1
    return out


def centre_of_mass(positions: np.ndarray, parents: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Centre of mass of a capsule body of uniform density, per frame.

    Each bone (a point and its parent) is a capsule of its radius: mass proportional to
    ``pi r^2 L + 4/3 pi r^3`` at the bone's middle. The page draws the same.

    Args:
        positions: ``(F, P, 3)`` world positions of the points.
        parents: ``(P,)`` parent point of each point (``-1`` for the root).
        radii: ``(P,)`` radius of the bone ending at each point.

    Returns:
        ``(F, 3)`` centre of mass.
    """
    pos = np.asarray(positions, dtype=np.float64)
    par = np.asarray(parents)
    r = np.asarray(radii, dtype=np.float64)
    child = np.nonzero((par >= 0) & (r > 0))[0]
    if len(child) == 0:
        return pos[:, 0].copy()
    a, b = pos[:, par[child]], pos[:, child]
    length = np.linalg.norm(b - a, axis=-1)
    w = np.pi * r[child] ** 2 * length + 4.0 / 3.0 * np.pi * r[child] ** 3
    return np.einsum("fb,fbk->fk", w, 0.5 * (a + b)) / w.sum(axis=1, keepdims=True)


def face_points(names: Sequence[str], sides: np.ndarray, positions: np.ndarray) -> dict:
    """Points that tell which way a body faces: ``{"head", "left", "right"}`` indices, or ``{}``.

    ``head``: the joint named like a head (else the highest point of the first frame); ``left`` and
    ``right``: a mirrored pair of shoulders (else arms, else hips). Facing is ``up x (right - left)``.

    Args:
        names: ``P`` point names; sides: ``(P,)`` from :func:`point_sides`; positions: ``(F, P, 3)``.
    """
    heads = [i for i, n in enumerate(names) if re.search(r"(?i)head", n) and not n.endswith("_end")]
    head = heads[0] if heads else int(np.argmax(positions[0, :, 2]))
    index = {n: i for i, n in enumerate(names)}
    for word in ("shoulder|clavicle|collar", "arm|humerus", "upleg|thigh|femur|hip"):
        for i, n in enumerate(names):
            if sides[i] != -1 or n.endswith("_end") or not re.search(f"(?i)({word})", n):
                continue
            j = index.get(mirror_name(n))
            if j is not None and sides[j] == 1:
                return {"head": int(head), "left": int(i), "right": int(j)}
    return {}


def travel_direction(chars: Sequence[np.ndarray]) -> np.ndarray:
    """``(2,)`` unit mean direction of travel of characters (``(F, P, 3)`` positions each) on the floor;
    ``(0, 1)`` when they do not travel (lanes then run along Y: side by side along X)."""
    d = np.sum([p[-1, 0, :2] - p[0, 0, :2] for p in chars], axis=0)
    if np.linalg.norm(d) < 0.2 * len(chars):
        return np.array([0.0, 1.0])
    return d / np.linalg.norm(d)


def lane_view(chars: Sequence[np.ndarray]) -> tuple[float, float, float]:
    """Where a camera starts for lanes: in front of the characters, a little to their right and above,
    so that the lanes do not hide each other (unit vector from the characters to the camera)."""
    d = travel_direction(chars)
    v = np.array([0.85 * d[0] + 0.2 * d[1], 0.85 * d[1] - 0.2 * d[0], 0.5])
    return tuple(float(x) for x in v / np.linalg.norm(v))


def lane_offsets(chars: Sequence[np.ndarray], gap: float = 0.9) -> list[np.ndarray]:
    """``(3,)`` floor offsets that put characters in lanes side by side *across* their direction of travel.

    The direction of travel is the mean of every character's root displacement (first to last frame);
    each character keeps its position along it and is moved across it into its own lane, lanes as
    wide as the character's sweep across the direction plus ``gap``, centred on the first lane's line.
    Characters that do not travel are laid out across +X (lanes along +Y... i.e. as a row along X).

    Args:
        chars: per character, ``(F, P, 3)`` world positions.
    """
    d = travel_direction(chars)
    n = np.array([d[1], -d[0]])  # to the right of the direction of travel
    lo, hi, base = [], [], []
    for p in chars:
        across = p[..., :2].reshape(-1, 2) @ n
        c = float(p[0, 0, :2] @ n)
        base.append(c)
        lo.append(across.min() - c)
        hi.append(across.max() - c)
    out, x = [], 0.0
    for k in range(len(chars)):
        if k:
            x += hi[k - 1] - lo[k] + gap
        out.append(x)
    mid = 0.5 * (out[0] + out[-1]) if len(out) > 1 else 0.0
    return [np.array([*((o - mid + base[0] - b) * n), 0.0]) for o, b in zip(out, base)]
