"""What a viewer page or a video shows: characters in one world plus overlays, prepared once.

Both :mod:`kinodyn.viz.html` and :mod:`kinodyn.viz.render` draw a :class:`World`, so a page and a video
of the same call show the same thing. A character is drawn from *points*: its joints followed by its
end sites (bone tips), with ``parents[P]`` (``-1`` for the root) and a capsule radius per bone (the bone
from a point's parent to the point). World convention: Z up, metres, seconds.

Inputs accepted wherever ``motions`` is asked for: one :class:`~kinodyn.motion.Motion`, an
:class:`Actor` (a motion with a name, colour and start time), a sequence of them, or a mapping
``name -> Motion | Actor``.

Overlays: the strings ``"contacts"`` (foot contacts detected by :func:`kinodyn.contacts.detect`),
``"phases"`` (support-phase bars LS/RS/DS/FLIGHT derived from them), ``"trajectories"`` (root paths on
the floor), ``"com"`` (centre of mass and its ground projection), ``"support"`` (support polygon of the
feet in contact), or objects: :class:`Contacts`, :class:`Impact`, :class:`Phases`, :class:`Trajectory`
and, from :mod:`kinodyn.viz.objects`, :class:`~kinodyn.viz.objects.Prop`,
:class:`~kinodyn.viz.objects.Forces`, :class:`~kinodyn.viz.objects.Marker`,
:class:`~kinodyn.viz.objects.Stages`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from kinodyn.errors import KinodynError, ParameterError
from kinodyn.kinematics import end_site_positions, forward_kinematics
from kinodyn.motion import Motion
from kinodyn.phases import contact_spans
from kinodyn.plotting import style
from kinodyn.roles import BONE_ROLES, bone_role, foot_point_indices
from kinodyn.viz.objects import (
    Forces,
    Marker,
    Prop,
    Stages,
    check_prop,
    face_points,
    lane_offsets,
    lane_view,
    point_sides,
    travel_direction,
)

__all__ = [
    "LAYOUTS",
    "OVERLAY_NAMES",
    "RADIUS_RULES",
    "Actor",
    "Character",
    "Contacts",
    "Impact",
    "Phases",
    "Trajectory",
    "World",
    "body_points",
    "bone_radii",
    "build_world",
    "support_phases",
]

OVERLAY_NAMES = ("contacts", "phases", "trajectories", "com", "support")
LAYOUTS = ("world", "row", "grid", "lanes")

_MSG_MOTIONS = "motions must be a Motion, an Actor, a sequence of them or a mapping name -> Motion, got {}"


# --------------------------------------------------------------------------- inputs


@dataclass(frozen=True)
class Actor:
    """A motion to show, with how to show it.

    Attributes:
        motion: the clip.
        name: label in the legend and above the head (default: the motion's name or ``character i``).
        color: ``"#rrggbb"`` (default: the palette in order).
        start: scene time (s) at which the clip's first frame plays; before it the first pose is held.
        ghost: draw it translucent, as a reference the others are compared with.
        loop: after its last frame the clip starts again (``True``) or holds its last pose (``False``);
            ``None`` takes ``build_world``'s ``loop_clips``.
        highlight: ``(F, J)`` bool, or ``None``: in frame ``f`` the segment carried by joint ``j`` (the
            bones from ``j`` to its children and end sites) is drawn in
            :data:`kinodyn.plotting.style.HIGHLIGHT_COLOR` (segments inside an obstacle, say).
    """

    motion: Motion
    name: str | None = None
    color: str | None = None
    start: float = 0.0
    ghost: bool = False
    loop: bool | None = None
    highlight: np.ndarray | None = None


@dataclass(frozen=True)
class Impact:
    """An impact: a point hit with an impulse at a time.

    Attributes:
        time: scene time in seconds.
        point: ``(3,)`` world point of application (m).
        impulse: ``(3,)`` impulse vector (N s); the arrow points along it and ends at ``point``.
        character: index of the character hit, if any.
        label: text for legends.
        color: arrow colour (default :data:`kinodyn.plotting.style.IMPACT_COLOR`).
    """

    time: float
    point: Sequence[float]
    impulse: Sequence[float]
    character: int | None = None
    label: str = ""
    color: str | None = None


@dataclass(frozen=True)
class Contacts:
    """Foot contact labels of one character.

    Attributes:
        character: index of the character.
        labels: ``(F, 2)`` bool, columns left and right (``FootContacts.as_array()``), at the motion's fps.
    """

    character: int
    labels: np.ndarray


@dataclass(frozen=True)
class Phases:
    """One bar of labelled time spans (support phases, blend weights, actions...).

    Attributes:
        spans: ``(start_s, stop_s, label)`` triples in scene time.
        label: the bar's title.
        character: index of the character it belongs to (for colouring), if any.
        colors: label -> colour; labels not listed use :data:`kinodyn.plotting.style.PHASE_COLORS`, then grey.
        tint: draw the character's body in the colour of the span it is in (needs ``character``).
    """

    spans: Sequence[tuple[float, float, str]]
    label: str = "phases"
    character: int | None = None
    colors: Mapping[str, str] | None = None
    tint: bool = False


@dataclass(frozen=True)
class Trajectory:
    """A polyline in the world (a planned path, a centre-of-mass trace).

    Attributes:
        points: ``(N, 3)`` world points (m).
        color: line colour.
        label: text for legends.
    """

    points: np.ndarray
    color: str = "#333333"
    label: str = ""


# --------------------------------------------------------------------------- prepared world


@dataclass(frozen=True)
class Character:
    """A character ready to draw.

    Attributes:
        name, color: label and ``"#rrggbb"``.
        fps: frames per second of ``positions``.
        start: scene time (s) of frame 0.
        positions: ``(F, P, 3)`` world positions of the points (joints, then end sites).
        parents: ``(P,)`` parent point of each point, ``-1`` for the root.
        radii: ``(P,)`` capsule radius (m) of the bone ending at each point (0 for the root).
        joints: number of joints ``J`` (points ``J..P-1`` are end sites).
        feet: ``{"left": idx, "right": idx}`` point indices of each foot, or ``{}``.
        contacts: ``(F, 2)`` bool foot contacts, or ``None``.
        ghost: drawn translucent (a reference).
        sides: ``(P,)`` int8 side of each point (-1 left, 0 centre, 1 right), or ``None``.
        face: ``{"head": i, "left": j, "right": k}`` points that say where the head faces, or ``{}``.
        point_names: ``P`` names of the points (joints, then ``<joint>_end`` end sites).
        loop: the clip plays again after its last frame (else its last pose is held).
        highlight: ``(F, P)`` bool, the bone ending at each point drawn highlighted, or ``None``.
    """

    name: str
    color: str
    fps: float
    start: float
    positions: np.ndarray
    parents: np.ndarray
    radii: np.ndarray
    joints: int
    feet: dict = field(default_factory=dict)
    contacts: np.ndarray | None = None
    ghost: bool = False
    sides: np.ndarray | None = None
    face: dict = field(default_factory=dict)
    point_names: tuple[str, ...] = ()
    loop: bool = False
    highlight: np.ndarray | None = None

    @property
    def num_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def end_time(self) -> float:
        return self.start + (self.num_frames - 1) / self.fps

    def local_frame(self, t: float) -> float:
        """Fractional frame shown at scene time ``t``: the first pose is held before ``start``; after the
        last frame the clip starts again when it loops (a period of ``num_frames / fps``), else holds."""
        f = max((t - self.start) * self.fps, 0.0)
        if self.loop and self.num_frames > 1:
            f = f % self.num_frames
        return min(f, self.num_frames - 1.0)

    def frame_at(self, t: float) -> int:
        """Index of the frame shown at scene time ``t`` (see :meth:`local_frame`)."""
        return int(min(round(self.local_frame(t)), self.num_frames - 1))

    def bones(self) -> np.ndarray:
        """``(B, 2)`` parent and child point of every bone."""
        child = np.nonzero(self.parents >= 0)[0]
        return np.stack([self.parents[child], child], axis=1)


@dataclass(frozen=True)
class World:
    """Characters and overlays of one scene.

    Attributes:
        characters: the :class:`Character` list.
        impacts, phases, trajectories, props, forces, markers: overlays.
        view: ``(3,)`` unit vector from the characters towards where the camera starts, or ``None`` for
            the default three-quarter side view (``"lanes"`` start in front, to see every lane).
        show: names of overlays switched on at start (``contacts``, ``phases``, ``trajectories``...).
        fps: frame rate of the scene clock (the highest character fps).
        duration: seconds from 0 to the last frame of the longest character.
        name: scene name.
    """

    characters: tuple[Character, ...]
    impacts: tuple[Impact, ...] = ()
    phases: tuple[Phases, ...] = ()
    trajectories: tuple[Trajectory, ...] = ()
    show: frozenset = frozenset()
    fps: float = 60.0
    duration: float = 0.0
    name: str = ""
    floor: float = 0.0
    props: tuple[Prop, ...] = ()
    forces: tuple[Forces, ...] = ()
    markers: tuple[Marker, ...] = ()
    view: tuple[float, float, float] | None = None

    @property
    def num_frames(self) -> int:
        """Frames of the scene clock (``duration * fps + 1``)."""
        return round(self.duration * self.fps) + 1

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(3,)`` lower and upper corners of every point over the whole scene."""
        lo = np.min([c.positions.reshape(-1, 3).min(axis=0) for c in self.characters], axis=0)
        hi = np.max([c.positions.reshape(-1, 3).max(axis=0) for c in self.characters], axis=0)
        return lo, hi


# --------------------------------------------------------------------------- bodies

#: Capsule radius in metres for a 1.75 m body of each bone role (:data:`kinodyn.roles.BONE_ROLES`).
_BONE_RADII = {"head": 0.095, "hand": 0.026, "neck": 0.05, "neck_base": 0.075, "upper_arm": 0.045,
               "shoulder": 0.05, "clavicle": 0.05, "forearm": 0.037, "trunk": 0.1, "pelvis": 0.075,
               "toe": 0.03, "foot": 0.042, "shin": 0.05, "thigh": 0.065}
#: (regex on the lower-cased name of a bone's child point, capsule radius) in the order of
#: :data:`kinodyn.roles.BONE_ROLES`, first match wins: the page applies the same rules to a dropped BVH.
RADIUS_RULES = tuple((pat, _BONE_RADII[role]) for role, pat in BONE_ROLES)


def bone_radii(names: Sequence[str], parents: np.ndarray, height: float) -> np.ndarray:
    """``(P,)`` capsule radius of the bone ending at each point, from joint names and the body height.

    End sites are named ``<parent>_end``; a second neck segment (CMU ``Neck1``) is thin. The root has
    radius 0.
    """
    s = max(height, 0.3) / 1.75
    out = np.zeros(len(names))
    for p, name in enumerate(names):
        if parents[p] < 0:
            continue
        n = name.lower()
        r = _BONE_RADII.get(bone_role(name), 0.04)
        if r == 0.075 and "neck" in n and "neck" in names[parents[p]].lower():
            r = 0.05  # a second neck segment
        out[p] = r * s
    return out


def body_points(motion: Motion) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """World positions of joints and end sites.

    Returns:
        positions ``(F, P, 3)``, parents ``(P,)`` (end sites point at their joint) and point names
        (end sites are ``<joint>_end``), with ``P = J + E``.
    """
    sk = motion.skeleton
    gr, gp = forward_kinematics(motion)
    names = list(sk.names)
    parents = np.asarray(sk.parents, dtype=np.int64)
    if len(sk.end_parents):
        ends = end_site_positions(motion, gr, gp)
        gp = np.concatenate([gp, ends], axis=1)
        names += [f"{sk.names[p]}_end" for p in sk.end_parents]
        parents = np.concatenate([parents, sk.end_parents])
    return gp, parents, names


def support_phases(labels: np.ndarray, fps: float, start: float = 0.0) -> list[tuple[float, float, str]]:
    """Support-phase spans from foot contacts.

    Args:
        labels: ``(F, 2)`` bool contacts, columns left and right.
        fps: their frame rate.
        start: scene time of frame 0.

    Returns:
        ``(t0, t1, label)`` spans covering ``[start, start + F / fps]``, labels ``LS`` (left foot only),
        ``RS`` (right only), ``DS`` (both), ``FLIGHT`` (none); consecutive equal labels merged.
    """
    return contact_spans(labels, fps, start, style.PHASE_LABELS)


# --------------------------------------------------------------------------- building


def _actors(motions, names, colors) -> list[Actor]:
    if isinstance(motions, (Motion, Actor)):
        items = [motions]
    elif isinstance(motions, Mapping):
        items = [Actor(m, str(k)) if isinstance(m, Motion) else
                 replace(m, name=m.name or str(k)) if isinstance(m, Actor) else m for k, m in motions.items()]
    elif isinstance(motions, Sequence) and not isinstance(motions, (str, bytes)):
        items = list(motions)
    else:
        raise ParameterError(_MSG_MOTIONS.format(type(motions).__name__))
    if not items:
        raise ParameterError("motions is empty: nothing to show")
    acts = []
    for i, m in enumerate(items):
        if isinstance(m, Motion):
            m = Actor(m)
        if not isinstance(m, Actor) or not isinstance(m.motion, Motion):
            raise ParameterError(_MSG_MOTIONS.format(f"an item of type {type(m).__name__} at index {i}"))
        if m.motion.num_frames == 0:
            raise ParameterError(f"motion {i} ({m.motion.name or 'unnamed'}) has no frames")
        if not math.isfinite(m.start):
            raise ParameterError(f"start of character {i} must be finite, got {m.start}")
        acts.append(m)
    if names is not None:
        names = list(names)
        if len(names) != len(acts):
            raise ParameterError(f"names must have one entry per character ({len(acts)}), got {len(names)}")
    cols = style.character_colors(len(acts), colors if colors is not None else [a.color for a in acts])
    out = []
    for i, a in enumerate(acts):
        nm = (names[i] if names is not None else None) or a.name or a.motion.name or f"character {i + 1}"
        out.append(Actor(a.motion, str(nm), cols[i], float(a.start), bool(a.ghost), a.loop, a.highlight))
    return out


def _feet_points(motion: Motion) -> dict[str, np.ndarray]:
    from kinodyn.contacts import find_feet

    try:
        feet = find_feet(motion.skeleton)
    except KinodynError:
        return {}
    return foot_point_indices(motion.skeleton, feet)


def _layout_offsets(chars: list[np.ndarray], layout: str, gap: float = 0.8) -> list[np.ndarray]:
    """``(3,)`` floor offsets that place characters side by side (``row``, ``grid``) or not (``world``)."""
    n = len(chars)
    if layout == "world" or n == 0:
        return [np.zeros(3) for _ in chars]
    # Each character centred on its first-frame root (x, y); extents measured in that frame.
    base = [np.array([-p[0, 0, 0], -p[0, 0, 1], 0.0]) for p in chars]
    ext = []
    for p, b in zip(chars, base):
        xy = p[..., :2].reshape(-1, 2) + b[:2]
        ext.append((xy.min(axis=0), xy.max(axis=0)))
    if layout == "row":  # along +X (left to right on screen), each after the previous one's extent
        out, x = [], 0.0
        for (lo, hi), b in zip(ext, base):
            out.append(b + np.array([x - lo[0], 0.0, 0.0]))
            x += hi[0] - lo[0] + gap
        return [o - np.array([0.5 * (x - gap), 0.0, 0.0]) for o in out]
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    width = [0.0] * cols
    depth = [0.0] * rows
    for i, (lo, hi) in enumerate(ext):
        r, c = divmod(i, cols)
        width[c] = max(width[c], hi[0] - lo[0] + gap, 1.2)
        depth[r] = max(depth[r], hi[1] - lo[1] + gap, 1.6)
    xs = np.concatenate([[0.0], np.cumsum(width)])
    ys = np.concatenate([[0.0], np.cumsum(depth)])
    out = []
    for i, ((lo, hi), b) in enumerate(zip(ext, base)):
        r, c = divmod(i, cols)
        cx = xs[c] + 0.5 * width[c] - 0.5 * (lo[0] + hi[0]) - 0.5 * xs[-1]
        cy = ys[-1] - ys[r] - 0.5 * depth[r] - 0.5 * (lo[1] + hi[1]) - 0.5 * ys[-1]  # row 0 at the back
        out.append(b + np.array([cx, cy, 0.0]))
    return out


def _lanes(ghost: list[bool], chars: list[np.ndarray]) -> list[np.ndarray]:
    """Lanes for the characters drawn solid; references (ghosts) are overlaid on the first one's lane,
    their first root moved across the direction of travel onto its first root."""
    if all(ghost) or not any(ghost):
        return lane_offsets(chars)
    solid = [p for p, g in zip(chars, ghost) if not g]
    offs = lane_offsets(solid)
    lanes = iter(offs)
    d = travel_direction(solid)
    n = np.array([d[1], -d[0], 0.0])
    return [offs[0] + ((solid[0][0, 0] - p[0, 0]) @ n) * n if g else next(lanes) for p, g in zip(chars, ghost)]


def _point_highlight(a: Actor, i: int, parents: np.ndarray) -> np.ndarray | None:
    """``(F, P)`` highlight of the bone ending at each point, from an actor's ``(F, J)`` per joint."""
    if a.highlight is None:
        return None
    h = np.asarray(a.highlight)
    f, j = a.motion.num_frames, a.motion.num_joints
    if h.shape != (f, j) or h.dtype != bool:
        raise ParameterError(f"highlight of character {i} must be a bool array of shape ({f}, {j}), got "
                             f"{h.dtype} {h.shape}")
    out = np.zeros((f, len(parents)), dtype=bool)
    child = np.nonzero(parents >= 0)[0]
    out[:, child] = h[:, parents[child]]
    return out


def _classify(overlays) -> tuple[set, set, dict]:
    """Sort overlays by kind: (overlays switched on, overlays computed per character, objects by kind)."""
    overlays = () if overlays is None else ([overlays] if isinstance(overlays, (str, Impact, Contacts, Phases,
                                                                                 Trajectory, Prop, Forces,
                                                                                 Marker, Stages))
                                            else list(overlays))
    wanted = set()  # overlays switched on in the viewer
    auto = set()  # overlays computed here for every character
    got = {"impacts": [], "phases": [], "trajectories": [], "contacts": {}, "props": [], "forces": [],
           "markers": [], "stages": []}
    for ov in overlays:
        if isinstance(ov, str):
            if ov not in OVERLAY_NAMES:
                raise ParameterError(f"unknown overlay {ov!r}; overlays: {', '.join(OVERLAY_NAMES)} "
                                     "or Impact/Contacts/Phases/Trajectory/Prop/Forces/Marker/Stages objects")
            wanted.add(ov)
            auto.add(ov)
        elif isinstance(ov, Impact):
            p = np.asarray(ov.point, dtype=np.float64)
            j = np.asarray(ov.impulse, dtype=np.float64)
            if p.shape != (3,) or j.shape != (3,) or not (np.all(np.isfinite(p)) and np.all(np.isfinite(j))):
                raise ParameterError(f"Impact point and impulse must be finite (3,) vectors, got {p.shape} "
                                     f"and {j.shape}")
            got["impacts"].append(ov)
        elif isinstance(ov, Contacts):
            got["contacts"][ov.character] = ov.labels
            wanted.add("contacts")
        elif isinstance(ov, (Phases, Stages)):
            if isinstance(ov, Stages):
                spans, cols = ov.colored_spans()
                got["stages"].append(Phases(spans, ov.label, ov.character, cols, bool(ov.tint)))
            else:
                got["phases"].append(ov)
            wanted.add("phases")
        elif isinstance(ov, Trajectory):
            pts = np.asarray(ov.points, dtype=np.float64)
            if pts.ndim != 2 or pts.shape[1] != 3:
                raise ParameterError(f"Trajectory points must have shape (N, 3), got {pts.shape}")
            got["trajectories"].append(ov)
            wanted.add("trajectories")
        elif isinstance(ov, Prop):
            check_prop(ov, len(got["props"]))
            got["props"].append(ov)
            wanted.add("props")
        elif isinstance(ov, Forces):
            ov.arrays()
            got["forces"].append(ov)
            wanted.add("forces")
        elif isinstance(ov, Marker):
            if not np.isfinite(ov.time):
                raise ParameterError(f"Marker time must be finite, got {ov.time}")
            got["markers"].append(ov)
        else:
            raise ParameterError(f"overlays must be names or overlay objects, got {type(ov).__name__}")
    if got["impacts"]:
        wanted.add("impacts")
    return wanted, auto, got


def build_world(motions, overlays=("contacts",), *, names=None, colors=None, layout: str = "world",
                name: str = "", loop_clips: bool = False) -> World:
    """Prepare characters and overlays for drawing.

    Args:
        motions: see the module docstring.
        overlays: overlay names (:data:`OVERLAY_NAMES`) and overlay objects; ``None`` for none.
        names: one label per character (overrides motion and actor names).
        colors: one colour per character (``None`` entries take the palette).
        layout: ``"world"`` (positions as they are), ``"row"`` (side by side along X, each clip's first
            root position moved to its slot), ``"grid"`` (rows and columns), for clip galleries; or
            ``"lanes"`` (side by side across the direction of travel, for comparing movers:
            :func:`kinodyn.viz.objects.lane_offsets`; references, ``Actor(ghost=True)``, are overlaid on
            the first solid character's lane).
        name: scene name.
        loop_clips: clips shorter than the scene start again after their last frame (else they hold
            their last pose); an :class:`Actor`'s ``loop`` overrides it.

    Raises:
        ParameterError: unknown overlay or layout, wrong shapes, bad character indices.
    """
    if layout not in LAYOUTS:
        raise ParameterError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    actors = _actors(motions, names, colors)
    wanted, auto, got = _classify(overlays)
    impacts, phases, contacts = got["impacts"], got["phases"], got["contacts"]
    n = len(actors)
    forces = got["forces"]
    for idx in list(contacts) + [o.character for o in impacts + phases + forces if o.character is not None]:
        if not (isinstance(idx, (int, np.integer)) and 0 <= idx < n):
            raise ParameterError(f"overlay character index must be in 0..{n - 1}, got {idx!r}")

    pos_list, prepared = [], []
    for a in actors:
        pos, parents, pnames = body_points(a.motion)
        pos_list.append(pos)
        radii = bone_radii(pnames, parents, a.motion.skeleton.height())
        prepared.append((pos, parents, radii, pnames))
    offsets = (_lanes([a.ghost for a in actors], pos_list) if layout == "lanes"
               else _layout_offsets(pos_list, layout))
    chars = []
    for i, (a, (pos, parents, radii, pnames), off) in enumerate(zip(actors, prepared, offsets)):
        m = a.motion
        lab = contacts.get(i)
        if lab is None and ("contacts" in auto or "phases" in auto or "support" in auto):
            from kinodyn import contacts as _contacts

            try:
                lab = _contacts.detect(m).as_array()
            except KinodynError:
                lab = None
        if lab is not None:
            lab = np.asarray(lab, dtype=bool)
            if lab.shape != (m.num_frames, 2):
                raise ParameterError(f"contacts of character {i} must have shape ({m.num_frames}, 2), got "
                                     f"{lab.shape}")
        sides = point_sides(pnames)
        chars.append(Character(a.name, a.color, m.fps, a.start, pos + off, parents, radii, m.num_joints,
                               _feet_points(m), lab, a.ghost, sides, face_points(pnames, sides, pos), tuple(pnames),
                               bool(loop_clips if a.loop is None else a.loop), _point_highlight(a, i, parents)))
        if "phases" in auto and lab is not None and not any(p.character == i for p in phases):
            phases.append(Phases(support_phases(lab, m.fps, a.start), f"{a.name} support", i))
    fps = max(c.fps for c in chars)
    duration = max(c.end_time for c in chars)
    for p in got["props"]:
        duration = max(duration, p.start + (len(np.atleast_2d(p.positions)) - 1) / p.fps)
    view = lane_view(pos_list) if layout == "lanes" else None
    return World(tuple(chars), tuple(sorted(impacts, key=lambda x: x.time)), tuple(phases + got["stages"]),
                 tuple(got["trajectories"]), frozenset(wanted), fps, max(duration, 0.0), name,
                 props=tuple(got["props"]), forces=tuple(forces),
                 markers=tuple(sorted(got["markers"], key=lambda m: m.time)), view=view)
