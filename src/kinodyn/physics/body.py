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

import weakref
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import mujoco
import numpy as np

from kinodyn import limits as _limits
from kinodyn._arrays import readonly
from kinodyn.errors import ParameterError, SkeletonError, UnknownNameError
from kinodyn.physics import geoms, layout
from kinodyn.physics.conversions import (
    body_rotations,
    check_skeleton,
    motion_to_qpos,
    pose_to_ctrl,
    qpos_to_local_rot,
)
from kinodyn.physics.geoms import HEEL_FRACTION  # noqa: F401 - part of this module's surface
from kinodyn.physics.layout import ERR_ZERO_BONE  # noqa: F401 - part of this module's surface
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
    "model_from_xml",
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

ERR_MASS = "mass must be a positive, finite number of kilograms, got {!r}"


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




# --------------------------------------------------------------------------- building




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
    kept, reason = layout.merge_plan(skeleton, lims, cfg)
    owner = np.arange(skeleton.num_joints)  # kept joint owning each joint
    for j in range(1, skeleton.num_joints):
        if not kept[j]:
            owner[j] = owner[skeleton.parents[j]]
    body_joint = np.nonzero(kept)[0]
    joint_body = np.searchsorted(body_joint, owner)
    cls = layout.segment_classes(skeleton, lims, body_joint, joint_body, pos)
    feet = {}
    for b, j in enumerate(body_joint):
        if cls[b] == "foot":
            s = layout.joint_side(skeleton, j, pos)
            if s and s not in feet:
                feet[s] = b
    spec = mujoco.MjSpec()
    spec.modelname = "kinodyn_character"
    spec.compiler.degree = False
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.timestep = 1.0 / 240.0
    plan = _Plan(skeleton, lims, cfg, pos, kept, reason, owner, body_joint, joint_body, cls, height)
    seg, chains = _add_segments(spec, plan)
    model, total = _set_masses(spec, seg, cfg)
    bmap = _body_map(skeleton, seg, chains, joint_body, body_joint, feet)
    _check_layout(model, bmap)
    kp, kv = tracking.default_gains(model, bmap, pd)
    _add_actuators(spec, bmap, pd, kp, kv)
    tracking.set_joint_passives(spec, model, bmap, pd, cfg.armature)
    return CharacterBody(spec=spec, map=bmap, config=cfg, kp=readonly(kp, np.float64), kv=readonly(kv, np.float64),
                         total_mass=total, pd=pd)


@dataclass(frozen=True)
class _Plan:
    """What :func:`build_body` decided before building: limits, rest positions ``(J, 3)``, kept joints,
    the kept joint owning each joint, the segment of each joint and the class of each segment."""

    skeleton: Skeleton
    lims: tuple
    cfg: BodyConfig
    pos: np.ndarray
    kept: np.ndarray
    reason: list
    owner: np.ndarray
    body_joint: np.ndarray
    joint_body: np.ndarray
    cls: list
    height: float


def _segment_row(plan: _Plan, b: int, j: int) -> Segment:
    """The :class:`Segment` of kept joint ``j`` (segment ``b``)."""
    skeleton, pos, cfg = plan.skeleton, plan.pos, plan.cfg
    name = skeleton.names[j]
    parent_b = -1 if j == 0 else int(plan.joint_body[skeleton.parents[j]])
    rel = pos[j] - (pos[plan.body_joint[parent_b]] if parent_b >= 0 else pos[j])
    c = plan.cls[b]
    radius = float(cfg.radius_overrides.get(name, cfg.radii[c] * plan.height))
    pts, _ = layout.points_of_cluster(skeleton, plan.owner, pos, j)
    length = float(np.linalg.norm(pts, axis=1).max()) if len(pts) else 0.0
    lim = plan.lims[j]
    if j == 0:
        kind = "free" if cfg.root == "free" else "fixed"
    else:
        kind = "hinge" if lim.kind == "hinge" else "ball"
    axis = tuple(float(x) for x in lim.axis) if kind == "hinge" else (0.0, 0.0, 0.0)
    rng = (float(lim.lower), float(lim.upper)) if kind == "hinge" else (0.0, float(lim.max_angle))
    mine = [m for m in range(skeleton.num_joints) if plan.owner[m] == j and m != j]
    return Segment(name, j, parent_b, c, layout.joint_side(skeleton, j, pos), kind,
                   tuple(skeleton.names[m] for m in mine), tuple(plan.reason[m] for m in mine), radius, length,
                   axis, rng, tuple(float(x) for x in rel))


def _add_segments(spec: mujoco.MjSpec, plan: _Plan) -> tuple[tuple[Segment, ...], tuple]:
    """One MuJoCo body per kept joint with its joint and geoms. Returns the segment rows and, per
    segment, the chain of skeleton joints whose rotations compose its joint rotation."""
    skeleton, pos, cfg = plan.skeleton, plan.pos, plan.cfg
    segments, bodies, chains = [], [], []
    sole = SOLE_FRACTION * plan.height
    spine_cls = {int(jj): cc for jj, cc in zip(plan.body_joint, plan.cls)}
    for b, j in enumerate(plan.body_joint):
        j = int(j)
        chain = [j]
        k = int(skeleton.parents[j])
        while k >= 0 and not plan.kept[k]:
            chain.insert(0, k)
            k = int(skeleton.parents[k])
        chains.append(tuple(chain))
        s = _segment_row(plan, b, j)
        segments.append(s)
        parent_body = spec.worldbody if s.parent < 0 else bodies[s.parent]
        body = parent_body.add_body(name=s.name, pos=s.pos if s.parent >= 0 else pos[j])
        if j == 0 and cfg.root == "fixed":
            body.mocap = True
        bodies.append(body)
        if s.kind == "free":
            body.add_freejoint(name="root")
        elif s.kind == "ball":
            jt = body.add_joint(name=s.name, type=mujoco.mjtJoint.mjJNT_BALL, range=[0.0, s.range[1]])
            jt.limited = mujoco.mjtLimited.mjLIMITED_TRUE if s.range[1] < np.pi - 1e-6 else \
                mujoco.mjtLimited.mjLIMITED_FALSE
        elif s.kind == "hinge":
            jt = body.add_joint(name=s.name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=list(s.axis), range=list(s.range))
            jt.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        pts, kinds = layout.points_of_cluster(skeleton, plan.owner, pos, j)
        geoms.add_geoms(body, s, pts, kinds, skeleton, pos, sole, spine_cls)
    return tuple(segments), tuple(chains)


def _set_masses(spec: mujoco.MjSpec, seg, cfg: BodyConfig) -> tuple[mujoco.MjModel, float]:
    """Friction and densities scaled so the character weighs ``cfg.mass``, and the rest-contact
    exclusions. Returns the compiled model and its total mass (kg)."""
    for geom in spec.geoms:
        geom.friction = [cfg.friction, 0.005, 0.0001]
        geom.density = cfg.density
        geom.condim = 3
    model = spec.compile()
    char_mass = float(model.body_mass[1:].sum())
    scale = cfg.mass / char_mass
    for geom in spec.geoms:
        geom.density = cfg.density * scale
    geoms.exclude_rest_contacts(spec, seg, cfg)
    model = spec.compile()
    return model, float(model.body_mass[1:].sum())


def _body_map(skeleton: Skeleton, seg, chains, joint_body, body_joint, feet) -> BodyMap:
    """The :class:`BodyMap` of the segments: ``qpos``/``qvel``/control widths and starts."""
    widths = {"free": (7, 6, 0), "fixed": (0, 0, 0), "ball": (4, 3, 4), "hinge": (1, 1, 1)}
    qw = np.array([widths[s.kind][0] for s in seg])
    vw = np.array([widths[s.kind][1] for s in seg])
    cw = np.array([widths[s.kind][2] for s in seg])

    def starts(widths):
        return readonly(np.concatenate([[0], np.cumsum(widths)[:-1]]), np.int64)

    return BodyMap(
        skeleton=skeleton, segments=seg, joint_body=readonly(joint_body, np.int64),
        body_joint=readonly(body_joint, np.int64), chains=tuple(chains),
        qpos_adr=starts(qw), qpos_width=readonly(qw, np.int64),
        dof_adr=starts(vw), dof_width=readonly(vw, np.int64),
        ctrl_adr=readonly(np.where(cw > 0, starts(cw), -1), np.int64), ctrl_width=readonly(cw, np.int64),
        actuated=readonly(np.nonzero(cw > 0)[0], np.int64), nq=int(qw.sum()), nv=int(vw.sum()), nu=int(cw.sum()),
        feet=MappingProxyType(dict(feet)))


def _add_actuators(spec: mujoco.MjSpec, bmap: BodyMap, pd, kp: np.ndarray, kv: np.ndarray) -> None:
    """An orientation servo on every ball joint and a position servo on every hinge, gains ``(A,)``."""
    from kinodyn.physics import tracking

    w2 = tracking.natural_frequency(pd) ** 2
    seg = bmap.segments
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


def model_from_xml(xml: str) -> mujoco.MjModel:
    """Compile MJCF text (such as :func:`body_xml` writes) as MuJoCo loads it from a file."""
    return mujoco.MjModel.from_xml_string(xml)


def body_xml(body: CharacterBody) -> str:
    """MJCF of the stand-alone character on a ground plane (``mujoco.MjModel.from_xml_string`` loads it)."""
    return _with_ground(body.spec, body.config.friction).to_xml()
