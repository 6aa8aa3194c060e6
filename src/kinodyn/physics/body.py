"""A MuJoCo body for any skeleton: segments, geoms, masses, joints and the index map.

The character is built through :class:`mujoco.MjSpec`, one rigid body per bone segment, as in the
ragdolls of Zordan et al. (dynamic response, section 7: "ball and sockets for each joint", masses from
the geometric models). The rules:

* **Segments.** Every kept skeleton joint ``j`` owns one MuJoCo body whose frame is the joint's frame:
  its origin is the joint, its rest orientation the joint's rest orientation (the identity relative to
  the parent body, because skeletons store only offsets). The body's geometry spans from the joint to
  the points it carries: its kept children, the joints merged into it and their end sites.
* **Merging tiny bones.** A joint is merged into its parent (it becomes rigid, at its rest rotation, and
  its rotation is folded into the next kept joint below it) when :mod:`kinodyn.limits` calls it
  ``"fixed"`` (CMU's ``LHipJoint``/``RHipJoint``), when it is a finger (CMU's ``LeftFingerBase``,
  ``LFingers``, ``LThumb``), when it is a toe and ``merge_toes`` is set, when it duplicates the joint
  below it (it sits less than ``min_bone`` from its parent and its only child is a joint of the same
  kind: CMU's ``Neck`` above ``Neck1``, ``LowerBack`` above ``Spine``), or when it is a leaf with nothing
  to carry. A zero-length joint where the skeleton branches keeps its own segment (CMU's clavicles
  ``LeftShoulder``, which start at the chest); a zero-length bone in the middle of a chain (a knee at the
  hip) is an error: the skeleton is broken.
* **Geoms.** Capsules sized from bone lengths with a radius from :data:`SEGMENT_RADII` (a fraction of the
  standing height, by segment class); the pelvis and the chest get a lateral capsule between the hips or
  the shoulders; feet are boxes from the heel to the toe tip with the sole below the toe joints.
* **Masses.** From volume and density, scaled so the character weighs ``mass`` (default 70 kg).
* **Joints.** A free root (or a fixed, mocap-driven root), ball joints limited to the ``max_angle`` of
  :func:`kinodyn.limits.limits_for` and hinges (knees, elbows) with its axis and range.
* **Collisions.** Ground and other characters always; the character's own segments too unless
  ``self_collision`` is off, except parent/child pairs (MuJoCo's default filter) and pairs that touch in
  the rest pose (excluded explicitly).

The :class:`BodyMap` is the explicit index map between skeleton joints and MuJoCo ``qpos``, ``qvel`` and
actuator controls; :func:`motion_to_qpos` and :func:`qpos_to_local_rot` convert through it.

Shapes: ``J`` skeleton joints, ``B`` bodies (segments), ``F`` frames. Metres, kilograms, radians;
rotations are ``(w, x, y, z)``.
"""

from __future__ import annotations

import re
import weakref
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import mujoco
import numpy as np

from kinodyn import limits as _limits
from kinodyn._arrays import readonly
from kinodyn.errors import MotionError, ParameterError, SkeletonError, UnknownNameError
from kinodyn.math import quat
from kinodyn.skeleton import Skeleton

__all__ = [
    "SEGMENT_CLASSES",
    "SEGMENT_RADII",
    "BodyConfig",
    "BodyMap",
    "CharacterBody",
    "Segment",
    "body_rotations",
    "body_xml",
    "build_body",
    "check_skeleton",
    "motion_to_qpos",
    "pose_to_ctrl",
    "qpos_to_local_rot",
]

#: Capsule radius of each segment class as a fraction of the standing height (metres for a 1.75 m
#: person in the comments). Feet: half the width of the foot box. The pelvis and chest radii are their
#: half depth front to back.
SEGMENT_RADII: Mapping[str, float] = MappingProxyType({
    "pelvis": 0.052,    # 0.091 m
    "spine": 0.046,     # 0.080 m (abdomen)
    "chest": 0.051,     # 0.089 m
    "neck": 0.027,      # 0.047 m
    "head": 0.052,      # 0.091 m
    "clavicle": 0.022,  # 0.039 m
    "upperarm": 0.027,  # 0.047 m
    "forearm": 0.022,   # 0.039 m
    "hand": 0.019,      # 0.033 m
    "thigh": 0.042,     # 0.074 m
    "shin": 0.031,      # 0.054 m
    "foot": 0.026,      # 0.046 m half width
    "toe": 0.020,       # 0.035 m
    "other": 0.020,     # 0.035 m
})
SEGMENT_CLASSES = tuple(SEGMENT_RADII)

#: Sole thickness below the lowest toe point, as a fraction of the height (built-in humanoid: 2.5 cm).
SOLE_FRACTION = 0.0143
#: Heel length behind the ankle as a fraction of the ankle-to-toe-tip length, when no heel site exists.
HEEL_FRACTION = 0.27

_FINGER = re.compile(r"finger|thumb|index|middle|ring|pinky|hand.*\d|^[lr]hand$", re.IGNORECASE)
_END = re.compile(r"(_end|end|nub|site|tip)$", re.IGNORECASE)
_LIMIT_CLASS = {"thigh": "thigh", "knee": "shin", "ankle": "foot", "toe": "toe", "clavicle": "clavicle",
                "shoulder": "clavicle", "upper_arm": "upperarm", "forearm": "forearm", "wrist": "hand",
                "neck": "neck", "head": "head", "spine": "spine", "finger": "hand", "hip_joint": "pelvis"}

ERR_MASS = "mass must be a positive, finite number of kilograms, got {!r}"
ERR_ZERO_BONE = ("joint {name!r} has a zero-length bone ({mm:.2f} mm from its parent {parent!r}) in the middle "
                 "of a chain; a body segment cannot be built for it (fix the skeleton's offsets)")


@dataclass(frozen=True)
class BodyConfig:
    """How to build a character body.

    Attributes:
        mass: total mass in kilograms (segment masses keep the proportions of their volumes).
        density: kg/m^3 before scaling (only the distribution matters once ``mass`` is set).
        radii: segment class -> radius as a fraction of the standing height (:data:`SEGMENT_RADII`).
        radius_overrides: joint name -> radius in metres, for the segment that joint owns.
        height: standing height in metres used with ``radii``; ``None`` measures the skeleton.
        min_bone: bones shorter than this (m) count as zero-length.
        merge_toes: merge toes into the foot (one box per foot); by default each toe is a small box
            of its own, so the foot rolls over the ball at toe-off as the data does.
        self_collision: let the character's own non-adjacent segments collide.
        friction: sliding friction of the character's geoms.
        root: ``"free"`` (a free joint) or ``"fixed"`` (the root is a mocap body: placed, never pushed).
        armature: rotor inertia added to every joint dof, as a fraction of the joint's subtree inertia
            (a little extra inertia on the light twist axes of limbs keeps explicit stiffness stable).
        limits: one :class:`kinodyn.limits.JointLimit` per joint; ``None`` uses ``limits_for``.
    """

    mass: float = 70.0
    density: float = 1000.0
    radii: Mapping[str, float] = field(default_factory=lambda: SEGMENT_RADII)
    radius_overrides: Mapping[str, float] = field(default_factory=dict)
    height: float | None = None
    min_bone: float = 0.005
    merge_toes: bool = False
    self_collision: bool = True
    friction: float = 1.0
    root: str = "free"
    armature: float = 0.0
    limits: tuple | None = None

    def __post_init__(self):
        m = self.mass
        if isinstance(m, bool) or not isinstance(m, (int, float, np.floating, np.integer)) or not np.isfinite(m) \
                or m <= 0:
            raise ParameterError(ERR_MASS.format(m))
        if not (np.isfinite(self.density) and self.density > 0):
            raise ParameterError(f"density must be a positive number of kg/m^3, got {self.density!r}")
        missing = [c for c in SEGMENT_CLASSES if c not in self.radii]
        if missing:
            raise ParameterError(f"radii table is missing segment classes: {', '.join(missing)}")
        bad = {k: v for k, v in {**dict(self.radii), **dict(self.radius_overrides)}.items()
               if not (np.isfinite(v) and v > 0)}
        if bad:
            raise ParameterError(f"segment radii must be positive numbers, got {bad}")
        if self.height is not None and not (np.isfinite(self.height) and self.height > 0):
            raise ParameterError(f"height must be a positive number of metres or None, got {self.height!r}")
        if not (np.isfinite(self.min_bone) and self.min_bone >= 0):
            raise ParameterError(f"min_bone must be a non-negative number of metres, got {self.min_bone!r}")
        if not (np.isfinite(self.friction) and self.friction >= 0):
            raise ParameterError(f"friction must be a non-negative number, got {self.friction!r}")
        if self.root not in ("free", "fixed"):
            raise ParameterError(f"root must be 'free' or 'fixed', got {self.root!r}")
        if not (np.isfinite(self.armature) and self.armature >= 0):
            raise ParameterError(f"armature must be a non-negative number, got {self.armature!r}")


@dataclass(frozen=True)
class Segment:
    """One row of the segment table: a MuJoCo body.

    Attributes:
        name: body name (the name of the skeleton joint it stands for).
        joint: index of that skeleton joint.
        parent: index of the parent segment (-1 for the root).
        cls: segment class (a key of :data:`SEGMENT_RADII`).
        side: ``"left"``, ``"right"`` or ``""``.
        kind: ``"free"``, ``"fixed"`` (root only), ``"ball"`` or ``"hinge"``.
        merged: names of the skeleton joints merged into this segment (rigid at their rest rotation).
        merged_why: why each of them was merged (``"fixed joint"``, ``"finger"``, ...).
        radius: capsule radius (m).
        length: distance from the joint to the farthest point the segment carries (m).
        axis: hinge axis in the body frame (hinges only).
        range: ``(lower, upper)`` hinge range or ``(0, max_angle)`` for balls (rad).
        pos: body origin in the parent body's frame at rest (m).
    """

    name: str
    joint: int
    parent: int
    cls: str
    side: str
    kind: str
    merged: tuple[str, ...]
    merged_why: tuple[str, ...]
    radius: float
    length: float
    axis: tuple[float, float, float]
    range: tuple[float, float]
    pos: tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class BodyMap:
    """The explicit index map between a skeleton and its MuJoCo body (addresses relative to the character).

    Attributes:
        skeleton: the skeleton the body was built from.
        segments: ``B`` segment rows in MuJoCo body order (parents before children).
        joint_body: ``(J,)`` segment each skeleton joint belongs to (merged joints: their segment).
        body_joint: ``(B,)`` skeleton joint of each segment.
        chains: per segment, the skeleton joints whose rotations compose its joint rotation: the joints
            merged between the parent segment and this one, then its own joint
            (``q_body = q[chain[0]] * ... * q[chain[-1]]``).
        qpos_adr, qpos_width: ``(B,)`` start and width (7 free, 4 ball, 1 hinge, 0 fixed root) in the
            character's ``qpos`` block.
        dof_adr, dof_width: ``(B,)`` start and width (6, 3, 1, 0) in the character's ``qvel`` block.
        ctrl_adr, ctrl_width: ``(B,)`` start and width (4 quaternion for balls, 1 angle for hinges, 0 for
            the root) in the character's control block; actuator ``k`` of the character drives segment
            ``actuated[k]``.
        actuated: ``(A,)`` segments with an actuator, in actuator order.
        nq, nv, nu: sizes of the character's blocks.
        feet: ``{"left": b, "right": b}`` foot segments (absent when none was found).
    """

    skeleton: Skeleton
    segments: tuple[Segment, ...]
    joint_body: np.ndarray
    body_joint: np.ndarray
    chains: tuple[tuple[int, ...], ...]
    qpos_adr: np.ndarray
    qpos_width: np.ndarray
    dof_adr: np.ndarray
    dof_width: np.ndarray
    ctrl_adr: np.ndarray
    ctrl_width: np.ndarray
    actuated: np.ndarray
    nq: int
    nv: int
    nu: int
    feet: Mapping[str, int]

    @property
    def num_bodies(self) -> int:
        return len(self.segments)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.segments)

    def body(self, name: str) -> int:
        """Segment index of a body name, a skeleton joint name (merged joints give their segment) or a
        landmark (:meth:`landmark`)."""
        for b, s in enumerate(self.segments):
            if s.name == name:
                return b
        if name in self.skeleton.names:
            return int(self.joint_body[self.skeleton.index(name)])
        return self.landmark(name)

    def landmark(self, name: str) -> int:
        """Segment of a landmark name: a segment class (``pelvis``, ``chest``, ``head``, ``stomach`` =
        the lowest spine segment, ...) optionally prefixed by a side (``left_thigh``, ``right_hand``)."""
        key = name.lower()
        side = ""
        for s in ("left_", "right_"):
            if key.startswith(s):
                side, key = s[:-1], key[len(s):]
        if key == "stomach":
            spine = [b for b, s in enumerate(self.segments) if s.cls == "spine"]
            key_b = spine[0] if spine else next((b for b, s in enumerate(self.segments) if s.cls == "chest"), -1)
            if key_b >= 0:
                return key_b
        for b, s in enumerate(self.segments):
            if s.cls == key and (not side or s.side == side):
                return b
        landmarks = sorted({s.cls if not s.side else f"{s.side}_{s.cls}" for s in self.segments} | {"stomach"})
        raise UnknownNameError(f"no body or landmark named {name!r}; bodies: {', '.join(self.names)}; "
                               f"landmarks: {', '.join(landmarks)}")

    def spine_bodies(self) -> np.ndarray:
        """Segments along the spine from the pelvis to the head (the paper's pelvis, stomach, chest,
        head), in order."""
        b = next((i for i, s in enumerate(self.segments) if s.cls == "head"), self.num_bodies - 1)
        path = []
        while b >= 0:
            path.append(b)
            b = self.segments[b].parent
        return np.array(path[::-1], dtype=np.int64)


@dataclass(frozen=True, eq=False)
class CharacterBody:
    """A built character: the :class:`mujoco.MjSpec` (not yet attached anywhere), its map and config.

    ``kp``/``kv`` are the default PD gains of each actuator (see :mod:`kinodyn.physics.tracking`), set
    from ``pd`` (a :class:`~kinodyn.physics.tracking.PDConfig`).
    ``spec`` is mutable MuJoCo state: copy it (``spec.copy()``) before editing.
    """

    spec: mujoco.MjSpec
    map: BodyMap
    config: BodyConfig
    kp: np.ndarray
    kv: np.ndarray
    total_mass: float
    pd: object = None

    @property
    def skeleton(self) -> Skeleton:
        return self.map.skeleton

    def compile(self) -> mujoco.MjModel:
        """A new stand-alone model of this character (with a ground plane, as exported)."""
        return _with_ground(self.spec, self.config.friction).compile()

    def model(self) -> mujoco.MjModel:
        """The stand-alone model, compiled once and shared (treat it as read-only)."""
        m = _MODELS.get(self)
        if m is None:
            m = _MODELS[self] = self.compile()
        return m

    def to_xml(self) -> str:
        """MJCF text of the stand-alone character (ground plane included) that ``mujoco.MjModel`` loads."""
        return body_xml(self)


_MODELS: weakref.WeakKeyDictionary[CharacterBody, mujoco.MjModel] = weakref.WeakKeyDictionary()


# --------------------------------------------------------------------------- classification


def _side(skeleton: Skeleton, j: int, pos: np.ndarray) -> str:
    from kinodyn.contacts import name_side

    s = name_side(skeleton.names[j])
    if s:
        return s
    y = pos[j, 1]
    return "left" if y > 1e-3 else "right" if y < -1e-3 else ""


def _merge_plan(skeleton: Skeleton, lims, cfg: BodyConfig) -> tuple[np.ndarray, list[str]]:
    """``(J,)`` kept flags and a reason per merged joint."""
    j_n = skeleton.num_joints
    kept = np.ones(j_n, dtype=bool)
    reason = [""] * j_n
    nkids = np.bincount(skeleton.parents[1:], minlength=j_n) if j_n > 1 else np.zeros(1, dtype=int)
    nends = np.bincount(skeleton.end_parents, minlength=j_n) if len(skeleton.end_parents) else np.zeros(j_n, int)
    bone = skeleton.bone_lengths()
    from kinodyn.contacts import find_feet

    try:
        foot_sets = find_feet(skeleton)
    except UnknownNameError:  # feet are optional: a skeleton without named feet still builds
        foot_sets = {}
    toe_joints = set()  # every foot joint below the shallowest one of its side (toes, toe ends)
    for idx in foot_sets.values():
        idx = sorted(int(i) for i in idx)
        toe_joints.update(i for i in idx[1:] if _is_descendant(skeleton, i, idx[0]))
    for j in range(1, j_n):
        name = skeleton.names[j]
        p = skeleton.parents[j]
        if lims[j].kind == "fixed":
            kept[j], reason[j] = False, "fixed joint"
        elif _FINGER.search(name) and lims[j].name == "finger":
            kept[j], reason[j] = False, "finger"
        elif cfg.merge_toes and j in toe_joints:
            kept[j], reason[j] = False, "toe (the foot box covers it)"
        elif _END.search(name) and nkids[j] == 0:
            kept[j], reason[j] = False, "end joint"
        elif bone[j] < cfg.min_bone:
            kids = np.nonzero(skeleton.parents == j)[0]
            if len(kids) == 1 and lims[kids[0]].name == lims[j].name:
                # CMU's Neck/Neck1, LowerBack/Spine: two joints of one kind, the first at its parent
                kept[j], reason[j] = False, "zero-length duplicate of the joint below it"
            elif len(kids) == 0 and nends[j] == 0:
                kept[j], reason[j] = False, "end joint"
            elif nkids[p] < 2 and p != 0:
                raise SkeletonError(ERR_ZERO_BONE.format(name=name, mm=bone[j] * 1000,
                                                         parent=skeleton.names[p]))
            # else: a segment that starts where the skeleton branches (CMU's clavicles): kept
    # Merge the whole subtree below a merged finger/toe/end joint.
    for j in range(1, j_n):
        p = skeleton.parents[j]
        if not kept[p] and reason[p] in ("finger", "toe (the foot box covers it)", "end joint") and kept[j]:
            kept[j], reason[j] = False, reason[p]
    return kept, reason


# --------------------------------------------------------------------------- building


def _points_of_cluster(skeleton: Skeleton, owner: np.ndarray, pos: np.ndarray, b_joint: int):
    """Rest positions (relative to the segment's joint) of what the segment carries: merged joints,
    their end sites and the kept children's joints."""
    pts, kinds = [], []
    for j in range(skeleton.num_joints):
        if j == b_joint:
            continue
        if owner[j] == b_joint:
            pts.append(pos[j] - pos[b_joint])
            kinds.append(("merged", j))
        elif skeleton.parents[j] >= 0 and owner[skeleton.parents[j]] == b_joint and owner[j] == j:
            pts.append(pos[j] - pos[b_joint])
            kinds.append(("child", j))
    for e, p in enumerate(skeleton.end_parents):
        if owner[p] == b_joint:
            pts.append(pos[p] + skeleton.end_offsets[e] - pos[b_joint])
            kinds.append(("end", int(p)))
    return np.array(pts).reshape(-1, 3), kinds


def build_body(skeleton: Skeleton, config: BodyConfig | None = None, pd=None) -> CharacterBody:
    """Build the MuJoCo body of ``skeleton``.

    Args:
        skeleton: any :class:`~kinodyn.skeleton.Skeleton` in metres, Z up.
        config: a :class:`BodyConfig` (defaults: 70 kg, free root, toes merged into box feet).
        pd: a :class:`kinodyn.physics.tracking.PDConfig` for the actuator gains (default gains if None).

    Returns:
        A :class:`CharacterBody` whose ``spec`` compiles on its own (with a ground plane).

    Raises:
        ParameterError: bad configuration (negative mass, ...).
        SkeletonError: a zero-length bone in a chain, or a skeleton with no extent.
    """
    from kinodyn.physics import tracking

    cfg = BodyConfig() if config is None else config
    if not isinstance(skeleton, Skeleton):
        raise ParameterError(f"build_body needs a Skeleton, got {type(skeleton).__name__}")
    pd = tracking.PDConfig() if pd is None else pd
    lims = _limits.limits_for(skeleton) if cfg.limits is None else tuple(cfg.limits)
    if len(lims) != skeleton.num_joints:
        raise ParameterError(f"limits must have one entry per joint ({skeleton.num_joints}), got {len(lims)}")
    height = skeleton.height() if cfg.height is None else cfg.height
    if not np.isfinite(height) or height < 0.05:
        raise SkeletonError(f"the skeleton has no extent (height {height:.4f} m): all bones are zero-length; "
                            "is it in metres?")
    pos = skeleton.rest_positions()
    kept, reason = _merge_plan(skeleton, lims, cfg)
    owner = np.arange(skeleton.num_joints)  # kept joint owning each joint
    for j in range(1, skeleton.num_joints):
        if not kept[j]:
            owner[j] = owner[skeleton.parents[j]]
    body_joint = np.nonzero(kept)[0]
    joint_body = np.searchsorted(body_joint, owner)

    # classes --------------------------------------------------------------
    cls = []
    for j in body_joint:
        if j == 0:
            cls.append("pelvis")
            continue
        tname = lims[j].name
        c = _LIMIT_CLASS.get(tname, "other")
        cls.append(c)
    cls = _structural_classes(skeleton, body_joint, joint_body, cls, pos)
    feet = {}
    for b, j in enumerate(body_joint):
        if cls[b] == "foot":
            s = _side(skeleton, j, pos)
            if s and s not in feet:
                feet[s] = b

    # spec ------------------------------------------------------------------
    spec = mujoco.MjSpec()
    spec.modelname = "kinodyn_character"
    spec.compiler.degree = False
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.timestep = 1.0 / 240.0
    segments: list[Segment] = []
    bodies = []
    chains = []
    sole = SOLE_FRACTION * height
    for b, j in enumerate(body_joint):
        j = int(j)
        name = skeleton.names[j]
        parent_b = -1 if j == 0 else int(joint_body[skeleton.parents[j]])
        rel = pos[j] - (pos[body_joint[parent_b]] if parent_b >= 0 else pos[j])
        chain = [j]
        k = int(skeleton.parents[j])
        while k >= 0 and not kept[k]:
            chain.insert(0, k)
            k = int(skeleton.parents[k])
        chains.append(tuple(chain))
        side = _side(skeleton, j, pos)
        c = cls[b]
        radius = float(cfg.radius_overrides.get(name, cfg.radii[c] * height))
        pts, kinds = _points_of_cluster(skeleton, owner, pos, j)
        length = float(np.linalg.norm(pts, axis=1).max()) if len(pts) else 0.0
        lim = lims[j]
        if j == 0:
            kind = "free" if cfg.root == "free" else "fixed"
        else:
            kind = "hinge" if lim.kind == "hinge" else "ball"
        axis = tuple(float(x) for x in lim.axis) if kind == "hinge" else (0.0, 0.0, 0.0)
        rng = (float(lim.lower), float(lim.upper)) if kind == "hinge" else (0.0, float(lim.max_angle))
        mine = [m for m in range(skeleton.num_joints) if owner[m] == j and m != j]
        segments.append(Segment(name, j, parent_b, c, side, kind, tuple(skeleton.names[m] for m in mine),
                                tuple(reason[m] for m in mine), radius, length, axis, rng,
                                tuple(float(x) for x in rel)))
        parent_body = spec.worldbody if parent_b < 0 else bodies[parent_b]
        body = parent_body.add_body(name=name, pos=rel if parent_b >= 0 else pos[j])
        if j == 0 and cfg.root == "fixed":
            body.mocap = True
        bodies.append(body)
        if kind == "free":
            body.add_freejoint(name="root")
        elif kind == "ball":
            jt = body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_BALL, range=[0.0, rng[1]])
            jt.limited = mujoco.mjtLimited.mjLIMITED_TRUE if rng[1] < np.pi - 1e-6 else mujoco.mjtLimited.mjLIMITED_FALSE
        elif kind == "hinge":
            jt = body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=list(axis), range=list(rng))
            jt.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        _add_geoms(body, segments[b], pts, kinds, skeleton, pos, sole, {int(jj): cc for jj, cc in zip(body_joint, cls)})

    # contact exclusions and masses ---------------------------------------
    seg = tuple(segments)
    for geom in spec.geoms:
        geom.friction = [cfg.friction, 0.005, 0.0001]
        geom.density = cfg.density
        geom.condim = 3
    model = spec.compile()
    char_mass = float(model.body_mass[1:].sum())
    scale = cfg.mass / char_mass
    for geom in spec.geoms:
        geom.density = cfg.density * scale
    _exclude_rest_contacts(spec, seg, cfg)
    model = spec.compile()
    total = float(model.body_mass[1:].sum())

    # map -----------------------------------------------------------------
    widths = {"free": (7, 6, 0), "fixed": (0, 0, 0), "ball": (4, 3, 4), "hinge": (1, 1, 1)}
    qw = np.array([widths[s.kind][0] for s in seg])
    vw = np.array([widths[s.kind][1] for s in seg])
    cw = np.array([widths[s.kind][2] for s in seg])
    def starts(widths):
        return readonly(np.concatenate([[0], np.cumsum(widths)[:-1]]), np.int64)

    bmap = BodyMap(
        skeleton=skeleton, segments=seg, joint_body=readonly(joint_body, np.int64),
        body_joint=readonly(body_joint, np.int64), chains=tuple(chains),
        qpos_adr=starts(qw), qpos_width=readonly(qw, np.int64),
        dof_adr=starts(vw), dof_width=readonly(vw, np.int64),
        ctrl_adr=readonly(np.where(cw > 0, starts(cw), -1), np.int64), ctrl_width=readonly(cw, np.int64),
        actuated=readonly(np.nonzero(cw > 0)[0], np.int64), nq=int(qw.sum()), nv=int(vw.sum()), nu=int(cw.sum()),
        feet=MappingProxyType(dict(feet)))
    _check_layout(model, bmap)

    # actuators -----------------------------------------------------------
    kp, kv = tracking.default_gains(model, bmap, pd)
    w2 = tracking.natural_frequency(pd) ** 2
    for k, b in enumerate(bmap.actuated):
        s = seg[b]
        act = spec.add_actuator(name=s.name, target=s.name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        if s.kind == "ball":
            act.set_to_orientation(kp=float(kp[k]), kv=float(kv[k]), ctrlspec=mujoco.mjtCtrlChart.mjCHART_QUAT.value)
        else:
            act.set_to_position(kp=float(kp[k]), kv=float(kv[k]))
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        if pd.max_torque is not None:
            tmax = float(pd.max_torque * kp[k] / max(tracking.gain_multipliers(bmap, pd)[k], 1e-12)) if w2 else 0.0
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = [0.0, tmax] if s.kind == "ball" else [-tmax, tmax]
    tracking.set_joint_passives(spec, model, bmap, pd, cfg.armature)
    return CharacterBody(spec=spec, map=bmap, config=cfg, kp=readonly(kp, np.float64), kv=readonly(kv, np.float64),
                         total_mass=total, pd=pd)


def _structural_classes(skeleton, body_joint, joint_body, cls, pos):
    """Fix classes from the tree: the spine path from the root to the head, the chest where the arms
    attach, limb chains named from their ends when the names say nothing."""
    nb = len(body_joint)
    parent = np.array([-1] + [int(joint_body[skeleton.parents[j]]) for j in body_joint[1:]])
    children = [[c for c in range(nb) if parent[c] == b] for b in range(nb)]
    # head: a body named head, else the highest leaf.
    heads = [b for b in range(nb) if cls[b] == "head"]
    if heads:
        head = heads[0]
    else:
        leaves = [b for b in range(nb) if not children[b]]
        head = max(leaves, key=lambda b: pos[body_joint[b], 2]) if leaves else 0
        if head != 0:
            cls[head] = "head"
    path = []
    b = head
    while b >= 0:
        path.append(b)
        b = parent[b]
    path = path[::-1]
    on_path = set(path)
    # where do the arm chains attach? the path body (below the head) with the most side subtrees
    # that are not legs (legs hang off the root).
    attach = [b for b in path[1:-1] if any(c not in on_path for c in children[b])]
    chest = attach[-1] if attach else (path[-3] if len(path) >= 3 else path[0])
    for b in path[1:-1]:
        if b == chest:
            cls[b] = "chest"
        elif path.index(b) < path.index(chest):
            cls[b] = "spine"
        else:
            cls[b] = "neck" if cls[b] not in ("neck",) else cls[b]
    # limb chains: arms off the path (not the root), legs off the root.
    limb_names = {"arm": ["hand", "forearm", "upperarm", "clavicle"], "leg": ["foot", "shin", "thigh", "thigh"]}
    for start_parent in path:
        for c in children[start_parent]:
            if c in on_path:
                continue
            chain = [c]
            while children[chain[-1]]:
                chain.append(max(children[chain[-1]], key=lambda x: _subtree_size(children, x)))
            kind = "leg" if start_parent == path[0] else "arm"
            names = limb_names[kind]
            for k, b2 in enumerate(reversed(chain)):
                if cls[b2] == "other" or (kind == "leg" and cls[b2] in ("spine", "chest")):
                    cls[b2] = names[min(k, len(names) - 1)]
    return cls


def _subtree_size(children, b):
    return 1 + sum(_subtree_size(children, c) for c in children[b])


def _add_geoms(body, seg: Segment, pts, kinds, skeleton: Skeleton, pos, sole: float, spine_cls: dict) -> None:
    """Capsules (or a box for a foot or toe) for one segment, in the body frame (rest orientation).

    ``pts``/``kinds``: what the segment carries (:func:`_points_of_cluster`); ``spine_cls``: segment class of
    each kept joint, to find the child on the spine.
    """
    name, c, radius, j = seg.name, seg.cls, seg.radius, seg.joint
    capsule = mujoco.mjtGeom.mjGEOM_CAPSULE
    rgba = {"left": [0.55, 0.62, 0.75, 1.0], "right": [0.75, 0.58, 0.55, 1.0]}.get(seg.side, [0.6, 0.65, 0.6, 1.0])
    geoms = []
    if c == "foot":
        _foot_box(body, name, pts, radius, sole, rgba)
        return
    if c == "toe":
        _foot_box(body, name, pts, radius, sole, rgba, heel_fraction=0.0, top=0.6 * sole)
        return
    children = [(p, k) for p, k in zip(pts, kinds) if k[0] == "child"]
    far = [p for p, k in zip(pts, kinds) if k[0] in ("merged", "end")]
    if c in ("pelvis", "chest"):
        # lateral capsule between the left/right limb roots below this segment
        lat = _lateral_pair(skeleton, pos, seg)
        if lat is not None:
            a, e = lat
            geoms.append(("lat", a, e))
        # and a capsule up the spine, to the child on the path to the head
        ups = [p for p, k in children if spine_cls.get(k[1]) in ("spine", "chest", "neck", "head")]
        for p in ups:
            geoms.append(("cap", np.zeros(3), p))
        if not geoms:
            for p, _k in children:
                geoms.append(("cap", np.zeros(3), p))
    else:
        targets = [p for p, _ in children]
        if far and (not targets or c in ("hand", "head")):  # to the farthest fingertip or head top
            targets = [max(far, key=lambda v: np.linalg.norm(v))]
        if not targets:
            # a leaf with nothing below it: continue the bone that leads to it
            d = skeleton.offsets[j]
            n = np.linalg.norm(d)
            d = d / n if n > 1e-9 else np.array([0.0, 0.0, 1.0])
            targets = [d * 2.0 * radius]
        # branching segments other than pelvis/chest: one capsule to each child
        for p in targets:
            geoms.append(("cap", np.zeros(3), p))
    for k, (kind, a, e) in enumerate(geoms):
        gname = name if k == 0 else f"{name}_{k}"
        if np.linalg.norm(e - a) < 1e-6:
            body.add_geom(name=gname, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], pos=a, rgba=rgba)
        else:
            body.add_geom(name=gname, type=capsule, fromto=np.concatenate([a, e]), size=[radius, 0, 0], rgba=rgba)


def _lateral_pair(skeleton: Skeleton, pos, seg: Segment):
    """End points of the lateral capsule of the pelvis (between the hips) or chest (between the shoulders)."""
    j, c = seg.joint, seg.cls
    want = ("thigh",) if c == "pelvis" else ("upperarm",)
    # the shallowest left and right joints below j whose limit type makes them limb roots
    cand = {"left": [], "right": []}
    for k in range(skeleton.num_joints):
        if k == j or not _is_descendant(skeleton, k, j):
            continue
        tname = _limits.joint_kind(skeleton, k)[0]
        cl = _LIMIT_CLASS.get(tname, "other")
        if cl in want:
            side = _side(skeleton, k, pos)
            if side:
                cand[side].append(k)
    if not cand["left"] or not cand["right"]:
        return None
    lk = min(cand["left"], key=lambda k: _depth(skeleton, k))
    rk = min(cand["right"], key=lambda k: _depth(skeleton, k))
    a, e = pos[lk] - pos[j], pos[rk] - pos[j]
    r = seg.radius
    mid = 0.5 * (a + e)
    half = 0.5 * (a - e)
    n = np.linalg.norm(half)
    if n < 1e-9:
        return None
    # pull the ends inward by half a radius so the limb roots stay free; lower the chest capsule a bit
    shrink = max(n - 0.5 * r, 0.25 * n) / n
    drop = np.array([0.0, 0.0, -0.4 * r]) if c == "chest" else np.zeros(3)
    return mid + half * shrink + drop, mid - half * shrink + drop


def _is_descendant(skeleton, k, j):
    while k >= 0:
        if k == j:
            return True
        k = skeleton.parents[k]
    return False


def _depth(skeleton, k):
    d = 0
    while k > 0:
        k = skeleton.parents[k]
        d += 1
    return d


def _foot_box(body, name, pts, radius, sole, rgba, heel_fraction=HEEL_FRACTION, top=None):
    """A box from the heel to the farthest point (the ball or the toe tip), its sole ``sole`` below the
    lowest point; toes use the same shape without a heel."""
    if len(pts):
        horiz = pts.copy()
        horiz[:, 2] = 0.0
        far = horiz[np.argmax(np.linalg.norm(horiz, axis=1))]
        n = np.linalg.norm(far)
    else:
        n = 0.0
    if n < 1e-6:
        fwd = np.array([1.0, 0.0, 0.0])
        toe_len = 6.0 * radius
        low = -2.0 * radius
    else:
        fwd = far / n
        toe_len = float(np.max(pts @ fwd))
        low = float(min(pts[:, 2].min(), 0.0)) - sole
    heel = heel_fraction * toe_len
    lo = min(low, -radius) if top is None else low
    top = 0.25 * radius if top is None else top
    half = np.array([(toe_len + heel) / 2.0, radius, (top - lo) / 2.0])
    center = fwd * (toe_len - heel) / 2.0 + np.array([0.0, 0.0, (top + lo) / 2.0])
    yaw = np.arctan2(fwd[1], fwd[0])
    q = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
    body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=half, pos=center, quat=q, rgba=rgba)


def _exclude_rest_contacts(spec: mujoco.MjSpec, seg, cfg: BodyConfig) -> None:
    """Exclude segment pairs that touch in the rest pose (and all pairs without self-collision)."""
    if not cfg.self_collision:
        names = [s.name for s in seg]
        for a in range(len(names)):
            for b in range(a + 1, len(names)):
                if seg[b].parent != a and seg[a].parent != b:
                    spec.add_exclude(bodyname1=names[a], bodyname2=names[b])
        return
    model = spec.compile()
    data = mujoco.MjData(model)
    # measure overlap with a margin so near-touching pairs are excluded too
    model.geom_margin[:] = 0.01
    mujoco.mj_forward(model, data)
    pairs = set()
    for i in range(data.ncon):
        g1, g2 = data.contact.geom1[i], data.contact.geom2[i]
        b1, b2 = model.geom_bodyid[g1], model.geom_bodyid[g2]
        if b1 == 0 or b2 == 0 or b1 == b2:
            continue
        pairs.add((min(b1, b2), max(b1, b2)))
    for b1, b2 in sorted(pairs):
        spec.add_exclude(bodyname1=model.body(b1).name, bodyname2=model.body(b2).name)


def _check_layout(model: mujoco.MjModel, bmap: BodyMap) -> None:
    """The map's addresses must agree with the compiled model (stand-alone: world body is 0)."""
    for b, s in enumerate(bmap.segments):
        mb = b + 1
        if model.body(mb).name != s.name:
            raise SkeletonError(f"internal: body {mb} is {model.body(mb).name!r}, expected {s.name!r}")
        if s.kind in ("free", "ball", "hinge"):
            jid = model.body_jntadr[mb]
            if model.jnt_qposadr[jid] != bmap.qpos_adr[b] or model.jnt_dofadr[jid] != bmap.dof_adr[b]:
                raise SkeletonError(f"internal: qpos/dof address mismatch for {s.name!r}")


def _with_ground(spec: mujoco.MjSpec, friction: float) -> mujoco.MjSpec:
    out = spec.copy()
    g = out.worldbody.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                               friction=[friction, 0.005, 0.0001], rgba=[0.8, 0.8, 0.8, 1])
    # put the ground first so body and geom ids of the character do not move
    del g
    out.worldbody.add_light(pos=[0, 0, 4], dir=[0, 0, -1])
    return out


def body_xml(body: CharacterBody) -> str:
    """MJCF of the stand-alone character on a ground plane (``mujoco.MjModel.from_xml_string`` loads it)."""
    return _with_ground(body.spec, body.config.friction).to_xml()


# --------------------------------------------------------------------------- conversions


def check_skeleton(bmap: BodyMap, skeleton: Skeleton, what: str = "motion") -> None:
    """Raise :class:`MotionError` when ``skeleton`` is not the one the body was built for."""
    if skeleton is bmap.skeleton:
        return
    if not bmap.skeleton.same_topology(skeleton):
        raise MotionError(
            f"the {what} is for another skeleton ({skeleton.num_joints} joints, root {skeleton.names[0]!r}) "
            f"than the character's ({bmap.skeleton.num_joints} joints, root {bmap.skeleton.names[0]!r}); "
            "retarget it first")


def body_rotations(bmap: BodyMap, local_rot: np.ndarray) -> np.ndarray:
    """``(..., B, 4)`` joint rotation of each segment from skeleton local rotations ``(..., J, 4)``
    (merged joints folded into the next kept joint below them)."""
    lr = np.asarray(local_rot, dtype=np.float64)
    out = np.empty(lr.shape[:-2] + (bmap.num_bodies, 4))
    for b, chain in enumerate(bmap.chains):
        q = lr[..., chain[0], :]
        for k in chain[1:]:
            q = quat.mul(q, lr[..., k, :])
        out[..., b, :] = q
    return out


def _hinge_angle(q: np.ndarray, axis: np.ndarray) -> np.ndarray:
    q = quat.abs(q)
    _, twist = quat.swing_twist(q, axis)
    return 2.0 * np.arctan2(twist[..., 1:] @ axis, twist[..., 0])


def motion_to_qpos(bmap: BodyMap, root_pos: np.ndarray, local_rot: np.ndarray) -> np.ndarray:
    """The character's ``qpos`` block ``(..., nq)`` for root positions ``(..., 3)`` and skeleton local
    rotations ``(..., J, 4)``. Hinges keep the rotation about their axis (swing-twist)."""
    rp = np.asarray(root_pos, dtype=np.float64)
    brot = body_rotations(bmap, local_rot)
    out = np.zeros(rp.shape[:-1] + (bmap.nq,))
    for b, s in enumerate(bmap.segments):
        a = bmap.qpos_adr[b]
        if s.kind == "free":
            out[..., a:a + 3] = rp
            out[..., a + 3:a + 7] = quat.normalize(brot[..., b, :])
        elif s.kind == "ball":
            out[..., a:a + 4] = quat.normalize(brot[..., b, :])
        elif s.kind == "hinge":
            out[..., a] = _hinge_angle(brot[..., b, :], np.asarray(s.axis))
    return out


def pose_to_ctrl(bmap: BodyMap, local_rot: np.ndarray) -> np.ndarray:
    """PD targets ``(..., nu)``: a quaternion per ball joint and an angle per hinge, from skeleton local
    rotations ``(..., J, 4)``."""
    brot = body_rotations(bmap, local_rot)
    out = np.zeros(brot.shape[:-2] + (bmap.nu,))
    for b in bmap.actuated:
        s = bmap.segments[b]
        a = bmap.ctrl_adr[b]
        if s.kind == "ball":
            out[..., a:a + 4] = quat.normalize(brot[..., b, :])
        else:
            out[..., a] = _hinge_angle(brot[..., b, :], np.asarray(s.axis))
    return out


def qpos_to_local_rot(bmap: BodyMap, qpos: np.ndarray, root_quat: np.ndarray | None = None) -> np.ndarray:
    """Skeleton local rotations ``(..., J, 4)`` from the character's ``qpos`` block ``(..., nq)``; merged
    joints get the identity (they are rigid at rest). ``root_quat (..., 4)`` gives the root rotation
    of a fixed-root character."""
    q = np.asarray(qpos, dtype=np.float64)
    out = quat.identity(q.shape[:-1] + (bmap.skeleton.num_joints,))
    for b, s in enumerate(bmap.segments):
        a = bmap.qpos_adr[b]
        j = s.joint
        if s.kind == "free":
            out[..., j, :] = quat.normalize(q[..., a + 3:a + 7])
        elif s.kind == "fixed":
            if root_quat is not None:
                out[..., j, :] = root_quat
        elif s.kind == "ball":
            out[..., j, :] = quat.normalize(q[..., a:a + 4])
        else:
            out[..., j, :] = quat.from_axis_angle(np.asarray(s.axis), q[..., a])
    return out
