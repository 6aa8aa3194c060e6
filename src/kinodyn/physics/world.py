"""The simulated world: characters, projectiles and the ground in one MuJoCo model.

This is the one mutable simulator of kinodyn (it holds ``MjModel``/``MjData`` and says so). A character
is in one of two modes:

* **kinematic**: it plays a :class:`~kinodyn.motion.Motion`. Before and after every physics step its
  ``qpos``/``qvel`` are set from the clip (positions by slerp, velocities by central finite differences),
  so it moves exactly as the data but still collides: a ball bounces off a swinging arm with the arm's
  velocity, and the character's segment masses are what the ball feels. When something hits it (a
  projectile, a push, another character) it can switch to dynamic on that very step (``on_impact``).
* **dynamic**: MuJoCo integrates it; in-engine PD servos (:mod:`kinodyn.physics.tracking`) drive it toward
  the clip's pose at the current time (or a pose set with :meth:`Character.track`). Switching from
  kinematic starts from the clip's positions and velocities at that instant, so nothing jumps.

A character can also be given a fixed root (``BodyConfig(root="fixed")``): its pelvis hangs where it is
placed (a mocap body) and the limbs are simulated.

Time advances in output frames (``fps``, default 60) of ``substeps`` physics steps each (default 4, i.e.
dt = 1/240 s). After every frame the state is checked: a non-finite or exploding state raises
:class:`~kinodyn.errors.SimulationDivergedError` naming the step and the body, and the world refuses to
go on or to hand out its trajectory. Each frame's ``qpos`` is recorded; :meth:`World.trajectory` turns a
character's record into a Motion at any frame rate.

Shapes: ``nq``/``nv``/``nu`` are the world model's sizes; per-character blocks are described by
:class:`~kinodyn.physics.body.BodyMap`.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import ClassVar

import mujoco
import numpy as np

from kinodyn.errors import (
    MotionError,
    ParameterError,
    SimulationDivergedError,
    SimulationError,
    UnknownNameError,
)
from kinodyn.math import quat, xform
from kinodyn.motion import Motion
from kinodyn.physics import impacts as _impacts
from kinodyn.physics import tracking
from kinodyn.physics.body import (
    BodyConfig,
    CharacterBody,
    build_body,
    check_skeleton,
    motion_to_qpos,
    pose_to_ctrl,
    qpos_to_local_rot,
)
from kinodyn.skeleton import Skeleton

__all__ = ["Character", "Projectile", "World", "WorldConfig", "clip_qvel", "step_parallel"]

#: A state with a joint or body speed above this (rad/s or m/s) counts as exploded.
MAX_SPEED = 500.0


@dataclass(frozen=True)
class WorldConfig:
    """Settings of a world.

    Attributes:
        fps: output frames per second (the rate of :meth:`World.step`, of recording and of divergence
            checks).
        substeps: physics steps per frame (dt = 1 / (fps * substeps)).
        gravity: m/s^2 along -Z (0 for none).
        ground: add a ground plane at z = 0.
        friction: ground friction.
        contact_timeconst: contact stiffness as a time constant (s); 0 uses twice the timestep (MuJoCo's
            stiffest stable setting, which keeps a fast ball from sinking into a chest).
        impact_gap: contacts of one pair closer in time than this (s) form one impact.
        max_speed: speed (m/s, rad/s) above which the state counts as exploded.
    """

    fps: float = 60.0
    substeps: int = 4
    gravity: float = 9.81
    ground: bool = True
    friction: float = 1.0
    contact_timeconst: float = 0.0
    impact_gap: float = 0.05
    max_speed: float = MAX_SPEED

    def __post_init__(self):
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ParameterError(f"fps must be a positive number, got {self.fps!r}")
        if not (isinstance(self.substeps, (int, np.integer)) and self.substeps >= 1):
            raise ParameterError(f"substeps must be a positive integer, got {self.substeps!r}")
        if not np.isfinite(self.gravity):
            raise ParameterError(f"gravity must be a finite number, got {self.gravity!r}")
        if not (np.isfinite(self.friction) and self.friction >= 0):
            raise ParameterError(f"friction must be non-negative, got {self.friction!r}")
        if not (np.isfinite(self.contact_timeconst) and self.contact_timeconst >= 0):
            raise ParameterError(f"contact_timeconst must be non-negative, got {self.contact_timeconst!r}")
        if not (np.isfinite(self.max_speed) and self.max_speed > 0):
            raise ParameterError(f"max_speed must be positive, got {self.max_speed!r}")

    @property
    def timestep(self) -> float:
        return 1.0 / (self.fps * self.substeps)


# --------------------------------------------------------------------------- clip sampling


def clip_qvel(bmap, root_pos: np.ndarray, local_rot: np.ndarray, fps: float) -> np.ndarray:
    """``(F, nv)`` generalized velocities of a clip by central finite differences (one-sided at the
    ends), in MuJoCo's convention: free joints (world linear, local angular), ball joints (local angular),
    hinges (angle rate). Matches ``mj_differentiatePos`` on the neighbouring frames."""
    from kinodyn.physics.body import body_rotations

    f = len(root_pos)
    out = np.zeros((f, bmap.nv))
    if f < 2:
        return out
    brot = quat.unroll(body_rotations(bmap, local_rot))
    qp = motion_to_qpos(bmap, root_pos, local_rot)
    lo = np.maximum(np.arange(f) - 1, 0)
    hi = np.minimum(np.arange(f) + 1, f - 1)
    span = (hi - lo) / fps
    for b, s in enumerate(bmap.segments):
        v = bmap.dof_adr[b]
        if s.kind == "free":
            a = bmap.qpos_adr[b]
            out[:, v:v + 3] = (qp[hi, a:a + 3] - qp[lo, a:a + 3]) / span[:, None]
            out[:, v + 3:v + 6] = quat.to_rotvec(quat.inv_mul(brot[lo, b], brot[hi, b])) / span[:, None]
        elif s.kind == "ball":
            out[:, v:v + 3] = quat.to_rotvec(quat.inv_mul(brot[lo, b], brot[hi, b])) / span[:, None]
        elif s.kind == "hinge":
            a = bmap.qpos_adr[b]
            ang = np.unwrap(qp[:, a])
            out[:, v] = (ang[hi] - ang[lo]) / span
    return out


@dataclass
class _Clip:
    """A motion sampled at the physics rate for one character (private).

    A looped clip repeats with period ``n - 1`` samples (a cyclic clip's last frame is its first one,
    moved on the floor); every repetition is moved on by the ground transform ``cycle`` that takes the
    first sample's root to the last one's, so a looped walk keeps walking forward.
    """

    motion: Motion
    start_step: int
    qpos: np.ndarray    # (n, nq_char)
    qvel: np.ndarray    # (n, nv_char)
    ctrl: np.ndarray    # (n, nu_char)
    loop: bool = False
    free_root: bool = True
    cycle: np.ndarray | None = None  # (3,) ground transform from one repetition to the next

    def _period(self) -> int:
        return max(len(self.qpos) - 1, 1) if self.loop else len(self.qpos)

    def index(self, step: int) -> int:
        k = step - self.start_step
        if self.loop:
            return max(k, 0) % self._period()
        return min(max(k, 0), len(self.qpos) - 1)

    def indices(self, steps: np.ndarray) -> np.ndarray:
        k = steps - self.start_step
        if self.loop:
            return np.maximum(k, 0) % self._period()
        return np.clip(k, 0, len(self.qpos) - 1)

    def ended(self, step: int) -> bool:
        return not self.loop and step - self.start_step >= len(self.qpos) - 1

    def state(self, step: int) -> tuple[np.ndarray, np.ndarray]:
        """``(qpos, qvel)`` of the character's block at world step ``step``."""
        if not self.loop:
            i = self.index(step)
            return self.qpos[i], (np.zeros_like(self.qvel[i]) if self.ended(step) else self.qvel[i])
        rep, i = divmod(max(step - self.start_step, 0), self._period())
        q, v = self.qpos[i], self.qvel[i]
        if rep == 0 or not self.free_root or self.cycle is None:
            return q, v
        g = self.cycle
        for _ in range(rep - 1):
            g = xform.compose(self.cycle, g)
        q, v = q.copy(), v.copy()
        q[:2] = xform.apply(g, q[:2])
        q[3:7] = quat.mul(quat.from_heading(g[2]), q[3:7])
        c, s_ = np.cos(g[2]), np.sin(g[2])
        v[:2] = (c * v[0] - s_ * v[1], s_ * v[0] + c * v[1])  # world linear velocity turns with the heading
        return q, v


def _lead_steps(body: CharacterBody, dt: float) -> np.ndarray:
    """``(nu,)`` steps by which each control's target leads: ``kv/kp`` of its servo, or the configured
    lookahead."""
    bm = body.map
    out = np.zeros(bm.nu, dtype=np.int64)
    for k, b in enumerate(bm.actuated):
        if body.pd.lookahead is not None:
            lead = body.pd.lookahead
        else:
            lead = body.kv[k] / body.kp[k] if body.kp[k] > 0 else 0.0
        a, w = bm.ctrl_adr[b], bm.ctrl_width[b]
        out[a:a + w] = round(lead / dt)
    return out


# --------------------------------------------------------------------------- handles


class Projectile:
    """A ball in the world (a handle; its state lives in the world's MjData)."""

    def __init__(self, world: World, index: int, name: str, mass: float, radius: float):
        self.world = world
        self.index = index
        self.name = name
        self.mass = mass
        self.radius = radius
        self.active = False
        #: addresses of the ball in the world model (set when the model is compiled)
        self.qadr = self.vadr = self.body_id = self.geom_id = -1

    def _bind(self, model: mujoco.MjModel) -> None:
        self.body_id = model.body(self.name).id
        jid = model.body_jntadr[self.body_id]
        self.qadr = int(model.jnt_qposadr[jid])
        self.vadr = int(model.jnt_dofadr[jid])
        self.geom_id = int(model.body_geomadr[self.body_id])
        self._apply_active(model)

    def _apply_active(self, model: mujoco.MjModel) -> None:
        """A parked ball floats (gravity compensated) and collides with nothing."""
        model.geom_contype[self.geom_id] = 1 if self.active else 0
        model.geom_conaffinity[self.geom_id] = 1 if self.active else 0
        model.body_gravcomp[self.body_id] = 0.0 if self.active else 1.0

    def activate(self) -> None:
        self.active = True
        self._apply_active(self.world.model)

    @property
    def position(self) -> np.ndarray:
        return self.world.data.qpos[self.qadr:self.qadr + 3].copy()

    @property
    def velocity(self) -> np.ndarray:
        return self.world.data.qvel[self.vadr:self.vadr + 3].copy()

    @property
    def momentum(self) -> np.ndarray:
        return self.mass * self.velocity

    def set_state(self, pos, vel) -> None:
        """Put the ball at ``pos`` with velocity ``vel`` (and make it collide and fall)."""
        self.activate()
        d = self.world.data
        d.qpos[self.qadr:self.qadr + 3] = pos
        d.qpos[self.qadr + 3:self.qadr + 7] = (1.0, 0.0, 0.0, 0.0)
        d.qvel[self.vadr:self.vadr + 3] = vel
        d.qvel[self.vadr + 3:self.vadr + 6] = 0.0

    def __repr__(self) -> str:
        return f"Projectile({self.name!r}, {self.mass:g} kg, r={self.radius:g} m)"


class Character:
    """A character in a :class:`World` (a handle; its state lives in the world's MjData).

    Attributes:
        name: unique name in the world (prefix of its MuJoCo bodies: ``name/LeftArm``).
        body: the :class:`~kinodyn.physics.body.CharacterBody` it was built from.
        mode: ``"kinematic"`` or ``"dynamic"``.
        on_impact: ``"switch"`` (turn dynamic when hit while kinematic) or ``"ignore"``.
    """

    def __init__(self, world: World, index: int, name: str, body: CharacterBody):
        self.world = world
        self.index = index
        self.name = name
        self.body = body
        self.mode = "dynamic"
        self.on_impact = "switch"
        self.clip: _Clip | None = None
        #: fixed servo targets ``(nu,)`` when not following a clip (set by :meth:`track`), else None
        self.ctrl_target: np.ndarray | None = None
        self._stiffness = np.ones(len(body.map.actuated))
        self._damping = np.ones(len(body.map.actuated))
        self.switch_time: float | None = None
        self._mocap0 = None  # initial pose of a fixed root, applied at the first compile
        #: physics steps by which each control's clip target leads (kv/kp of its servo, see
        #: PDConfig.lookahead)
        self.lead_steps = _lead_steps(body, world.dt)
        self.ctrl_cols = np.arange(body.map.nu)
        #: servo targets of the rest pose (identity quaternions, zero hinge angles)
        self.rest_ctrl = pose_to_ctrl(body.map, quat.identity((body.map.skeleton.num_joints,)))
        # addresses in the world model (set by World._bind)
        self.qadr = self.vadr = self.cadr = 0
        self.body_ids = np.zeros(0, dtype=np.int64)
        self.actuator_ids = np.zeros(0, dtype=np.int64)
        self.geom_ids = np.zeros(0, dtype=np.int64)
        self.mocap_id = -1

    # ------------------------------------------------------------------ info
    @property
    def map(self):
        return self.body.map

    @property
    def skeleton(self) -> Skeleton:
        return self.body.map.skeleton

    @property
    def mass(self) -> float:
        return float(self.world.model.body_mass[self.body_ids].sum())

    def __repr__(self) -> str:
        return f"Character({self.name!r}, {self.map.num_bodies} bodies, {self.mode})"

    def body_id(self, name: str) -> int:
        """MuJoCo body id of a segment, skeleton joint or landmark name."""
        return int(self.body_ids[self.map.body(name)])

    # ------------------------------------------------------------------ state views
    @property
    def qpos(self) -> np.ndarray:
        return self.world.data.qpos[self.qadr:self.qadr + self.map.nq]

    @property
    def qvel(self) -> np.ndarray:
        return self.world.data.qvel[self.vadr:self.vadr + self.map.nv]

    def momentum(self) -> np.ndarray:
        """``(3,)`` linear momentum (kg m/s) of the character."""
        from kinodyn.physics import state

        return state.character_state(self.world, self).com_vel * self.mass

    # ------------------------------------------------------------------ control (delegates)
    def play(self, motion: Motion, **kw) -> Character:
        self.world.play(self, motion, **kw)
        return self

    def switch_to_dynamic(self, **kw) -> Character:
        self.world.switch_to_dynamic(self, **kw)
        return self

    def switch_to_kinematic(self, motion: Motion | None = None, **kw) -> Character:
        self.world.switch_to_kinematic(self, motion, **kw)
        return self

    def track(self, target) -> Character:
        self.world.track(self, target)
        return self

    def set_gains(self, stiffness=1.0, damping=None, joints=None) -> Character:
        self.world.set_gains(self, stiffness, damping, joints)
        return self

    def trajectory(self, fps: float | None = None, **kw) -> Motion:
        return self.world.trajectory(self, fps, **kw)

    def state(self):
        from kinodyn.physics import state

        return state.character_state(self.world, self)


# --------------------------------------------------------------------------- world


class World:
    """Characters, projectiles and a ground plane in one MuJoCo model (mutable).

    Example::

        world = World()
        a = world.add_character(humanoid())
        a.play(library.load("walk"))           # kinematic
        world.throw(a, "chest", mass=3, radius=0.1, speed=8, direction=np.pi / 2, height=1.4, at=1.0)
        world.run(2.0)                         # a switches to dynamic when the ball lands
        walk = a.trajectory(fps=30)
    """

    def __init__(self, config: WorldConfig | None = None, **kw):
        if config is None:
            config = WorldConfig(**kw)
        elif kw:
            raise ParameterError("pass either a WorldConfig or keyword settings, not both")
        self.config = config
        self.characters: list[Character] = []
        self.projectiles: list[Projectile] = []
        self._spec = mujoco.MjSpec()
        self._spec.modelname = "kinodyn_world"
        self._spec.option.timestep = config.timestep
        self._spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        self._spec.option.gravity = [0.0, 0.0, -config.gravity]
        self._spec.copy_during_attach = True
        if config.ground:
            tc = config.contact_timeconst or 2.0 * config.timestep
            self._spec.worldbody.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                                          friction=[config.friction, 0.005, 0.0001], rgba=[0.8, 0.8, 0.8, 1],
                                          priority=1, solref=[tc, 1.0])
        self._spec.worldbody.add_light(pos=[0, 0, 5], dir=[0, 0, -1])
        self._model: mujoco.MjModel | None = None
        self._data: mujoco.MjData | None = None
        self._dirty = True
        self._step = 0
        self._log = _impacts.ImpactLog(config.impact_gap)
        self._frames: list[np.ndarray] = []
        self._mocap: list[tuple[np.ndarray, np.ndarray]] = []
        self._frame_steps: list[int] = []
        self._diverged: SimulationDivergedError | None = None
        self._pending_throws: list[tuple] = []
        self._owner = np.zeros(0, dtype=np.int64)
        self._warn0 = np.zeros(len(mujoco.mjtWarning.__members__) - 1, dtype=np.int64)
        self.record = True

    # ------------------------------------------------------------------ building
    @property
    def dt(self) -> float:
        return self.config.timestep

    @property
    def time(self) -> float:
        return self._step * self.dt

    @property
    def step_count(self) -> int:
        return self._step

    def add_character(self, skeleton_or_body, name: str | None = None, config: BodyConfig | None = None,
                      pd: tracking.PDConfig | None = None, at=(0.0, 0.0, 0.0)) -> Character:
        """Add a character built from a Skeleton (or a prebuilt CharacterBody).

        Args:
            skeleton_or_body: a :class:`~kinodyn.skeleton.Skeleton` or a
                :class:`~kinodyn.physics.body.CharacterBody`.
            name: unique name (default ``c0``, ``c1``, ...).
            config, pd: body and servo settings when building from a skeleton.
            at: ``(x, y, heading)`` where the rest pose stands until a clip is played.
        """
        if isinstance(skeleton_or_body, CharacterBody):
            if config is not None or pd is not None:
                raise ParameterError("config/pd apply when building from a skeleton, not to a prebuilt body")
            body = skeleton_or_body
        elif isinstance(skeleton_or_body, Skeleton):
            body = build_body(skeleton_or_body, config, pd)
        else:
            raise ParameterError(f"add_character needs a Skeleton or CharacterBody, got {type(skeleton_or_body).__name__}")
        name = f"c{len(self.characters)}" if name is None else str(name)
        if not name or "/" in name or any(c.name == name for c in self.characters) \
                or any(p.name == name for p in self.projectiles):
            raise ParameterError(f"character name must be unique, non-empty and without '/', got {name!r}")
        at = np.asarray(at, dtype=np.float64)
        if at.shape != (3,) or not np.all(np.isfinite(at)):
            raise ParameterError(f"at must be (x, y, heading), got {at!r}")
        # stand the rest pose on the floor: lowest point of the body at z = 0
        lift = self._rest_lift(body)
        frame = self._spec.worldbody.add_frame(pos=[at[0], at[1], lift],
                                               quat=[math.cos(at[2] / 2), 0, 0, math.sin(at[2] / 2)])
        child = body.spec.copy()
        child.option.timestep = self._spec.option.timestep
        child.option.integrator = self._spec.option.integrator
        child.option.gravity = self._spec.option.gravity
        self._spec.attach(child, prefix=f"{name}/", frame=frame)
        char = Character(self, len(self.characters), name, body)
        if body.config.root == "fixed":
            char._mocap0 = ([at[0], at[1], lift], [math.cos(at[2] / 2), 0, 0, math.sin(at[2] / 2)])
        self.characters.append(char)
        self._dirty = True  # compiled when the model is next needed
        return char

    _lifts: ClassVar[weakref.WeakKeyDictionary] = weakref.WeakKeyDictionary()

    @classmethod
    def _rest_lift(cls, body: CharacterBody) -> float:
        """Height of the root above the floor when the rest pose stands on it (cached per body)."""
        if body not in cls._lifts:
            m = body.compile()
            d = mujoco.MjData(m)
            mujoco.mj_kinematics(m, d)
            cls._lifts[body] = float(-_lowest_point(m, d, np.arange(1, m.ngeom)))
        return cls._lifts[body]

    def add_projectile(self, mass: float, radius: float, name: str | None = None) -> Projectile:
        """Add a ball, parked below the floor (floating, colliding with nothing) until it is thrown.
        Changes the model (a recompile that keeps the state)."""
        if not (np.isfinite(mass) and mass > 0):
            raise ParameterError(f"projectile mass must be a positive number of kilograms, got {mass!r}")
        if not (np.isfinite(radius) and radius > 0):
            raise ParameterError(f"projectile radius must be a positive number of metres, got {radius!r}")
        name = f"ball{len(self.projectiles)}" if name is None else str(name)
        if any(p.name == name for p in self.projectiles) or any(c.name == name for c in self.characters):
            raise ParameterError(f"projectile name must be unique, got {name!r}")
        k = len(self.projectiles)
        b = self._spec.worldbody.add_body(name=name, pos=[0.0, 3.0 * k, -10.0 - 3.0 * k])
        b.add_freejoint(name=f"{name}/free")
        tc = self.config.contact_timeconst or 2.0 * self.dt
        b.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], mass=mass,
                   rgba=[0.9, 0.3, 0.2, 1.0], priority=1, solref=[tc, 1.0], friction=[0.5, 0.005, 0.0001])
        p = Projectile(self, k, name, float(mass), float(radius))
        self.projectiles.append(p)
        self._dirty = True
        return p

    def _ensure(self) -> None:
        if self._dirty:
            self._compile()

    @property
    def model(self) -> mujoco.MjModel:
        """The compiled model (compiled on first use after characters or balls were added)."""
        if self._dirty:
            self._compile()
        return self._model

    @property
    def data(self) -> mujoco.MjData:
        """The simulation state (see :attr:`model`)."""
        if self._dirty:
            self._compile()
        return self._data

    def _compile(self) -> None:
        """Compile the spec, keeping the state of what existed before (new things start at their qpos0)."""
        self._dirty = False
        if self._model is None:
            self._model = self._spec.compile()
            self._data = mujoco.MjData(self._model)
        else:
            self._model, self._data = self._spec.recompile(self._model, self._data)
        self._bind()

    def _bind(self) -> None:
        m, d = self._model, self._data
        owner = np.full(m.ngeom, -1, dtype=np.int64)
        for c in self.characters:
            bm = c.map
            ids = np.array([m.body(f"{c.name}/{s.name}").id for s in bm.segments], dtype=np.int64)
            c.body_ids = ids
            root = ids[0]
            if bm.segments[0].kind == "free":
                jid = m.body_jntadr[root]
                c.qadr, c.vadr = int(m.jnt_qposadr[jid]), int(m.jnt_dofadr[jid])
                c.mocap_id = -1
            else:
                c.mocap_id = int(m.body_mocapid[root])
                if len(bm.actuated):
                    jid = m.body_jntadr[ids[bm.actuated[0]]]
                    c.qadr, c.vadr = int(m.jnt_qposadr[jid]), int(m.jnt_dofadr[jid])
            acts = np.array([m.actuator(f"{c.name}/{bm.segments[b].name}").id for b in bm.actuated], dtype=np.int64)
            c.actuator_ids = acts
            c.cadr = int(m.actuator_ctrladr[acts[0]]) if len(acts) else 0
            geoms = np.nonzero(np.isin(m.geom_bodyid, ids))[0]
            c.geom_ids = geoms
            owner[geoms] = c.index
            # check the map against the compiled layout
            for b, s in enumerate(bm.segments):
                if s.kind in ("ball", "hinge", "free"):
                    jid = m.body_jntadr[ids[b]]
                    if m.jnt_qposadr[jid] != c.qadr + bm.qpos_adr[b] or m.jnt_dofadr[jid] != c.vadr + bm.dof_adr[b]:
                        raise SimulationError(f"internal: qpos layout of {c.name}/{s.name} does not match its map")
            for k, b in enumerate(bm.actuated):
                if m.actuator_ctrladr[acts[k]] != c.cadr + bm.ctrl_adr[b]:
                    raise SimulationError(f"internal: control layout of {c.name} does not match its map")
            tracking.apply_gains(m, acts, c.body.kp, c.body.kv, c._stiffness, c._damping)
        for p in self.projectiles:
            p._bind(m)
            owner[m.body_geomadr[p.body_id]] = -2 - p.index
        self._owner = owner
        # reach of each character: farthest geometry from its root in the rest pose
        self._reach = np.array([_reach(c.body) for c in self.characters])
        self._warn0 = np.array(d.warning.number, dtype=np.int64)
        for c in self.characters:
            if c._mocap0 is not None:
                d.mocap_pos[c.mocap_id], d.mocap_quat[c.mocap_id] = c._mocap0
                c._mocap0 = None
            if c.mode == "kinematic" and c.clip is not None:
                self._set_kinematic(c)
            self._set_ctrl(c)

    def character(self, name: str) -> Character:
        for c in self.characters:
            if c.name == name:
                return c
        raise UnknownNameError(f"no character named {name!r}; characters: {', '.join(c.name for c in self.characters)}")

    # ------------------------------------------------------------------ clips and modes
    def _sample_clip(self, char: Character, motion: Motion, start_step: int, loop: bool, align_floor) -> _Clip:
        check_skeleton(char.map, motion.skeleton)
        if motion.num_frames < 1:
            raise MotionError("cannot play an empty motion")
        bm = char.map
        rate = 1.0 / self.dt
        if motion.num_frames > 1:
            fine = motion.resample(rate)
            # velocities: central differences on the clip's own frames, interpolated to the physics rate
            v0 = clip_qvel(bm, motion.root_pos, motion.local_rot, motion.fps)
            t = np.arange(fine.num_frames) / rate
            src = np.arange(motion.num_frames) / motion.fps
            qvel = np.stack([np.interp(t, src, v0[:, i]) for i in range(bm.nv)], axis=1) if bm.nv else \
                np.zeros((fine.num_frames, 0))
        else:
            fine = motion
            qvel = np.zeros((1, bm.nv))
        root_pos = np.array(fine.root_pos)
        if align_floor is True or align_floor == "auto":
            root_pos[:, 2] += self._floor_offset(char, fine)
        elif align_floor not in (False, None):
            root_pos[:, 2] += float(align_floor)
        qpos = motion_to_qpos(bm, root_pos, fine.local_rot)
        root_quat = None if char.mocap_id < 0 else np.repeat(self.data.mocap_quat[char.mocap_id][None], len(qpos), 0)
        ctrl = tracking.feedforward_targets(char.body, qpos, pose_to_ctrl(bm, fine.local_rot), qvel, self.dt,
                                            root_quat, lead_steps=char.lead_steps)
        g = fine.ground()
        cycle = xform.compose(g[-1], xform.inverse(g[0])) if loop and fine.num_frames > 1 else None
        return _Clip(motion, start_step, qpos, qvel, ctrl, loop, bm.segments[0].kind == "free", cycle)

    def _floor_offset(self, char: Character, fine: Motion) -> float:
        """Vertical shift that puts the clip's lowest body point on the floor (median over time)."""
        bm = char.map
        m = char.body.model()
        d = mujoco.MjData(m)
        step = max(1, round(0.05 / self.dt))
        frames = range(0, fine.num_frames, step)
        lows = []
        q = motion_to_qpos(bm, fine.root_pos[list(frames)], fine.local_rot[list(frames)])
        for k in range(len(q)):
            if bm.segments[0].kind == "free":
                d.qpos[:] = q[k]
            else:
                d.qpos[:] = q[k]
                d.mocap_pos[0] = fine.root_pos[frames[k]]
                d.mocap_quat[0] = fine.local_rot[frames[k], 0]
            mujoco.mj_kinematics(m, d)
            lows.append(_lowest_point(m, d, np.arange(1, m.ngeom)))
        return float(-np.percentile(lows, 50))

    def play(self, char: Character, motion: Motion, start: float = 0.0, at=None, loop: bool = False,
             align_floor=True) -> None:
        """Play ``motion`` kinematically on ``char`` from clip time ``start`` (s), beginning now.

        Args:
            start: clip time (s) to begin at; with ``loop`` a phase in the cycle.
            at: ``(x, y, heading)`` ground transform for the clip's frame at ``start`` (default: as
                recorded).
            loop: repeat the clip (for cyclic clips: each repetition starts where the last one ended, moved
                on the floor); otherwise hold the last frame.
            align_floor: ``True`` shifts the clip vertically so the body's lowest point touches the floor
                (median over the clip); ``False`` plays it as is; a number shifts by that.
        """
        if not (np.isfinite(start) and 0.0 <= start <= motion.duration + 1e-9):
            raise ParameterError(f"start must be a clip time within [0, {motion.duration:g}] s, got {start!r}")
        if at is not None:
            motion = motion.aligned_to(np.asarray(at, dtype=np.float64), min(round(start * motion.fps),
                                                                             motion.num_frames - 1))
        # the clip is sampled whole; it started `start` seconds ago
        char.clip = self._sample_clip(char, motion, self._step - round(start / self.dt), loop, align_floor)
        char.mode = "kinematic"
        char.ctrl_target = None
        self._set_kinematic(char)
        self._set_ctrl(char)

    def switch_to_dynamic(self, char: Character, stiffness=None, damping=None) -> None:
        """Let MuJoCo integrate ``char`` from now on, starting from the clip's current positions and
        velocities; its servos keep tracking the clip (or its :meth:`track` target). Optionally set gains."""
        self._ensure()
        if char.mode == "kinematic" and char.clip is not None:
            self._set_kinematic(char)
        char.mode = "dynamic"
        char.switch_time = self.time
        if stiffness is not None or damping is not None:
            self.set_gains(char, 1.0 if stiffness is None else stiffness, damping)

    def switch_to_kinematic(self, char: Character, motion: Motion | None = None, start: float = 0.0,
                            **kw) -> None:
        """Play a clip kinematically again (``motion`` from ``start``, or the current clip from now)."""
        if motion is None:
            if char.clip is None:
                raise SimulationError(f"character {char.name!r} has no clip to return to; pass a motion")
            char.mode = "kinematic"
            self._set_kinematic(char)
            return
        self.play(char, motion, start=start, **kw)

    def track(self, char: Character, target) -> None:
        """Servo targets of a dynamic character: a :class:`Motion` (followed in time from now), a single
        pose as skeleton local rotations ``(J, 4)``, or ``None`` to follow the current clip again."""
        self._ensure()
        if target is None:
            char.ctrl_target = None
        elif isinstance(target, Motion):
            clip = self._sample_clip(char, target, self._step, False, False)
            if char.mode == "kinematic":
                raise SimulationError(f"character {char.name!r} is kinematic; switch it to dynamic before "
                                      "giving it a separate tracking target")
            char.clip = clip
            char.ctrl_target = None
        else:
            rot = np.asarray(target, dtype=np.float64)
            if rot.shape != (char.skeleton.num_joints, 4):
                raise MotionError(f"a target pose for character {char.name!r} must have shape "
                                  f"({char.skeleton.num_joints}, 4) (one rotation per joint of its skeleton), "
                                  f"got {rot.shape}")
            if not np.all(np.isfinite(rot)):
                raise MotionError("target pose has non-finite values")
            char.ctrl_target = pose_to_ctrl(char.map, quat.normalize(rot))
        self._set_ctrl(char)

    def set_gains(self, char: Character, stiffness=1.0, damping=None, joints=None) -> None:
        """Scale ``char``'s servo gains now (0 = limp, 1 = the defaults; see :func:`tracking.apply_gains`).

        Args:
            joints: segment/joint names or landmarks to change (default all).
        """
        self._ensure()
        a = len(char.map.actuated)
        sel = np.arange(a) if joints is None else self._actuator_index(char, joints)
        st = np.broadcast_to(np.asarray(stiffness, dtype=np.float64), (len(sel),))
        dm = np.sqrt(np.maximum(st, 0)) if damping is None else \
            np.broadcast_to(np.asarray(damping, dtype=np.float64), (len(sel),))
        if not np.all(np.isfinite(st)) or np.any(st < 0) or not np.all(np.isfinite(dm)) or np.any(dm < 0):
            raise ParameterError(f"gain multipliers must be non-negative numbers, got stiffness={stiffness!r}, "
                                 f"damping={damping!r}")
        char._stiffness[sel] = st
        char._damping[sel] = dm
        tracking.apply_gains(self.model, char.actuator_ids, char.body.kp, char.body.kv, char._stiffness,
                             char._damping)

    @staticmethod
    def _actuator_index(char: Character, joints) -> np.ndarray:
        if isinstance(joints, str):
            joints = [joints]
        pos = {int(b): k for k, b in enumerate(char.map.actuated)}
        out = []
        for j in joints:
            b = char.map.body(j)
            if b not in pos:
                raise ParameterError(f"{j!r} ({char.map.segments[b].name}) has no servo (the root is unactuated)")
            out.append(pos[b])
        return np.array(out, dtype=np.int64)

    def place_root(self, char: Character, pos, quat_=None) -> None:
        """Move a fixed-root character's root (a mocap body) to ``pos`` with rotation ``quat_``."""
        self._ensure()
        if char.mocap_id < 0:
            raise SimulationError(f"character {char.name!r} has a free root; place it by playing a clip")
        self.data.mocap_pos[char.mocap_id] = pos
        if quat_ is not None:
            self.data.mocap_quat[char.mocap_id] = quat.normalize(np.asarray(quat_, dtype=np.float64))

    def _set_kinematic(self, c: Character) -> None:
        d = self.data
        d.qpos[c.qadr:c.qadr + c.map.nq], d.qvel[c.vadr:c.vadr + c.map.nv] = c.clip.state(self._step)

    def _set_ctrl(self, c: Character) -> None:
        if c.ctrl_target is not None:
            self.data.ctrl[c.cadr:c.cadr + c.map.nu] = c.ctrl_target
        elif c.clip is not None:
            rows = c.clip.indices(self._step + c.lead_steps)
            self.data.ctrl[c.cadr:c.cadr + c.map.nu] = c.clip.ctrl[rows, c.ctrl_cols]
        else:
            self.data.ctrl[c.cadr:c.cadr + c.map.nu] = c.rest_ctrl

    # ------------------------------------------------------------------ impacts
    def throw(self, char: Character, landmark: str = "chest", mass: float = 2.0, radius: float = 0.1,
              speed: float = 8.0, direction=0.0, height: float = 1.5, distance: float = 2.0,
              at: float | None = None, projectile: Projectile | None = None) -> Projectile:
        """Throw a ball at a landmark of ``char``.

        Args:
            landmark: body, joint or landmark name (``chest``, ``head``, ``pelvis``, ``stomach``,
                ``left_thigh``...); the ball aims at the centre of that segment's geometry.
            mass, radius: of the ball (kg, m).
            speed: launch speed (m/s); direction: horizontal heading of travel (rad) or a vector;
            height: launch height (m); distance: horizontal distance from the target at launch (m).
            at: world time (s) at which the ball should arrive; ``None`` launches now. When the character
                plays a clip, the aim point is where the landmark will be at arrival.
            projectile: reuse a ball (default: a new one with this mass and radius, or an idle one).

        Returns:
            The :class:`Projectile`.
        """
        if projectile is None:
            projectile = next((p for p in self.projectiles if abs(p.mass - mass) < 1e-12
                               and abs(p.radius - radius) < 1e-12 and not p.active), None)
            if projectile is None:
                projectile = self.add_projectile(mass, radius)
        b = char.map.body(landmark)
        # aim: where the landmark is at arrival (kinematic clips are known ahead)
        t_now = self.time
        t_hit = t_now if at is None else float(at)
        for _ in range(3):
            target = self.landmark_point(char, b, t_hit)
            start, vel, flight = _impacts.launch(target, speed, direction, height, distance,
                                                 np.array([0.0, 0.0, -self.config.gravity]))
            if at is None:
                t_hit = t_now + flight
            else:
                break
        t_launch = t_hit - flight if at is not None else t_now
        if t_launch < t_now - 1e-9:
            raise ParameterError(f"cannot make the ball arrive at t={t_hit:.3f} s: its flight takes {flight:.3f} s "
                                 f"and the world is at t={t_now:.3f} s")
        launch_step = round(t_launch / self.dt)
        self._pending_throws.append((launch_step, projectile, start, vel))
        if launch_step <= self._step:
            self._launch_due()
        return projectile

    def _launch_due(self) -> None:
        keep = []
        for s, p, pos, vel in self._pending_throws:
            if s <= self._step:
                p.set_state(pos, vel)
            else:
                keep.append((s, p, pos, vel))
        self._pending_throws = keep

    def landmark_point(self, char: Character, b: int, t: float) -> np.ndarray:
        """World position of the centre of segment ``b``'s geometry at time ``t`` (clip-predicted for
        kinematic characters, current otherwise)."""
        m = self.model
        if char.mode == "kinematic" and char.clip is not None:
            step = round(t / self.dt)
            d = mujoco.MjData(m)
            d.qpos[:] = self.data.qpos
            d.mocap_pos[:] = self.data.mocap_pos
            d.mocap_quat[:] = self.data.mocap_quat
            d.qpos[char.qadr:char.qadr + char.map.nq] = char.clip.state(step)[0]
        else:
            d = self.data
        mujoco.mj_kinematics(m, d)
        bid = char.body_ids[b]
        gs = np.arange(m.body_geomadr[bid], m.body_geomadr[bid] + m.body_geomnum[bid])
        vol = np.array([_geom_volume(m, g) for g in gs])
        return (d.geom_xpos[gs] * vol[:, None]).sum(axis=0) / vol.sum()

    def push(self, char: Character, body: str, impulse, point=None) -> None:
        """An impulsive push, now: ``impulse (3,)`` N s at ``point`` (world, default the segment's centre
        of mass) on ``body``. The velocities jump by ``M^-1 J^T impulse`` at the current pose, so the
        character's momentum changes by exactly the impulse (contacts react from the next step on).
        Switches a kinematic character to dynamic when its ``on_impact`` says so. Recorded as an impact."""
        self._ensure()
        imp = np.asarray(impulse, dtype=np.float64)
        if imp.shape != (3,) or not np.all(np.isfinite(imp)):
            raise ParameterError(f"impulse must be a finite (3,) vector in N s, got {impulse!r}")
        b = char.map.body(body)
        bid = int(char.body_ids[b])
        m, d = self.model, self.data
        if char.mode == "kinematic":
            if char.on_impact != "switch":
                raise SimulationError(f"character {char.name!r} plays a clip and ignores impacts; switch it to "
                                      "dynamic (or set on_impact='switch') to push it")
            self.switch_to_dynamic(char)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_crb(m, d)
        mujoco.mj_factorM(m, d)
        if point is None:
            p = d.xipos[bid].copy()
        else:
            p = np.asarray(point, dtype=np.float64)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise ParameterError(f"point must be a finite (3,) world position, got {point!r}")
        jacp = np.zeros((3, m.nv))
        mujoco.mj_jac(m, d, jacp, None, p, bid)
        dv = np.zeros((1, m.nv))
        mujoco.mj_solveM(m, d, dv, (jacp.T @ imp)[None, :])
        d.qvel[:] += dv[0]
        self._log.add(("push", char.index, b, self._step), self.time, char.name, char.map.segments[b].name, p,
                      imp, "push", "push", 0.0, 0.0)
        self._log.close(("push", char.index, b, self._step))

    @property
    def impacts(self) -> list:
        """Every impact so far (:class:`~kinodyn.physics.impacts.Impact`), by time."""
        return self._log.all()

    # ------------------------------------------------------------------ stepping
    def step(self, frames: int = 1) -> None:
        """Advance ``frames`` output frames (``substeps`` physics steps each).

        Raises:
            SimulationDivergedError: the state became non-finite or exploded (checked every frame).
        """
        if self._diverged is not None:
            raise SimulationDivergedError(f"the simulation diverged earlier ({self._diverged}); build a new world",
                                          self._diverged.step, self._diverged.body)
        frames = int(frames)
        if frames < 0:
            raise ParameterError(f"frames must be non-negative, got {frames}")
        m, d = self.model, self.data
        if self.record and not self._frames:
            self._record()
        nsub = self.config.substeps
        for _ in range(frames):
            # who needs what this frame (modes change only between steps, on impacts)
            kin = [c for c in self.characters if c.mode == "kinematic" and c.clip is not None]
            watch = any(p.active for p in self.projectiles) or self._characters_close()
            ctrl = self._frame_controls(nsub)
            for _s in range(nsub):
                if self._pending_throws:
                    self._launch_due()
                    watch = True
                if ctrl is not None:
                    d.ctrl[:] = ctrl[_s]
                mujoco.mj_step(m, d)
                self._step += 1
                if watch:
                    n_kin = len(kin)
                    kin = self._watch_contacts(kin)
                    if len(kin) != n_kin:  # someone was hit and turned dynamic: follow its clip now
                        ctrl = self._frame_controls(nsub - _s - 1, ctrl_prev=ctrl, offset=_s + 1)
                for c in kin:
                    self._set_kinematic(c)
            self._check()
            if self.record:
                self._record()

    def _characters_close(self) -> bool:
        """Whether two characters may touch within the next frame (their roots closer than their reaches
        plus a margin); contacts between characters are watched only then."""
        n = len(self.characters)
        if n < 2:
            return False
        d = self.data
        pos = np.empty((n, 3))
        for i, c in enumerate(self.characters):
            pos[i] = d.mocap_pos[c.mocap_id] if c.mocap_id >= 0 else d.qpos[c.qadr:c.qadr + 3]
        reach = self._reach
        dist = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
        near = dist < reach[:, None] + reach[None, :] + 0.5
        np.fill_diagonal(near, False)
        return bool(near.any())

    def _frame_controls(self, nsub: int, ctrl_prev=None, offset: int = 0):
        """``(offset + nsub, nu)`` servo targets of the next ``nsub`` steps (rows from ``offset`` on are
        filled) for dynamic characters following a clip; ``None`` when nobody does."""
        follow = [c for c in self.characters if c.mode == "dynamic" and c.ctrl_target is None and c.clip is not None]
        if not follow:
            return ctrl_prev
        d = self.data
        out = np.empty((offset + nsub, self.model.nu)) if ctrl_prev is None else ctrl_prev
        out[offset:] = d.ctrl
        steps = self._step + np.arange(nsub)[:, None]
        for c in follow:
            rows = c.clip.indices(steps + c.lead_steps[None, :])
            out[offset:, c.cadr:c.cadr + c.map.nu] = c.clip.ctrl[rows, c.ctrl_cols[None, :]]
        return out

    def run(self, seconds: float) -> None:
        """Advance by ``seconds`` (rounded to whole frames)."""
        if not (np.isfinite(seconds) and seconds >= 0):
            raise ParameterError(f"seconds must be a non-negative number, got {seconds!r}")
        self.step(round(seconds * self.config.fps))

    def _watch_contacts(self, kin: list[Character]) -> list[Character]:
        hits = _impacts.contact_impulses(self.model, self.data, self._owner, self.dt)
        t = self.time
        switched = False
        for ga, gb, p, imp, fn in hits:
            ca = self.characters[self._owner[ga]]
            ob = self._owner[gb]
            if ob >= 0:
                other = self.characters[ob]
                if ca.mode == "kinematic" and ca.on_impact != "switch":
                    continue  # a clip that does not react (an attacker's fist): nothing happens to it
                src = f"{other.name}/{self.model.body(self.model.geom_bodyid[gb]).name.split('/', 1)[-1]}"
                kind = "character"
            else:
                src = self.projectiles[-2 - ob].name
                kind = "projectile"
            b = int(np.searchsorted(ca.body_ids, self.model.geom_bodyid[ga]))
            self._log.add((ca.index, b, src), t, ca.name, ca.map.segments[b].name, p, imp, src, kind, fn, self.dt)
            if ca.mode == "kinematic" and ca.on_impact == "switch":
                # keep the state this step produced (it holds the impact) and simulate from here on
                ca.mode = "dynamic"
                ca.switch_time = t
                switched = True
        self._log.close_stale(t)
        if switched:
            kin = [c for c in kin if c.mode == "kinematic"]
        return kin

    def _record(self) -> None:
        # whole-state rows; adding characters or balls later only appends to qpos and mocap, so the
        # addresses of what existed stay valid in older rows
        self._frames.append(self.data.qpos.copy())
        self._mocap.append((self.data.mocap_pos.copy(), self.data.mocap_quat.copy()))
        self._frame_steps.append(self._step)

    _BAD_WARNINGS = (("qacc", mujoco.mjtWarning.mjWARN_BADQACC), ("qvel", mujoco.mjtWarning.mjWARN_BADQVEL),
                     ("qpos", mujoco.mjtWarning.mjWARN_BADQPOS))

    def _check(self) -> None:
        """Raise :class:`SimulationDivergedError` when the last frame went bad: MuJoCo flagged a NaN or
        huge ``qpos``/``qvel``/``qacc`` (and reset its state, which must not pass unnoticed), the state is
        non-finite, or a speed exceeds ``max_speed``."""
        m, d = self.model, self.data
        warn = np.array(d.warning.number, dtype=np.int64)
        problem, dof = None, -1
        for what, w in self._BAD_WARNINGS:
            if warn[int(w)] > self._warn0[int(w)]:
                problem = f"MuJoCo found a NaN or huge {what} and reset the state"
                dof = int(d.warning[int(w)].lastinfo)
                break
        if problem is None:
            if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
                problem = "the state became non-finite (NaN or inf)"
                dof = int(np.argmax(~np.isfinite(d.qvel))) if not np.isfinite(d.qvel).all() else -1
            elif m.nv and float(np.max(np.abs(d.qvel))) > self.config.max_speed:
                dof = int(np.argmax(np.abs(d.qvel)))
                problem = f"a velocity reached {abs(d.qvel[dof]):.3g} (limit {self.config.max_speed:g} m/s or rad/s)"
        if problem is None:
            return
        body = m.body(m.dof_bodyid[dof]).name if 0 <= dof < m.nv else ""
        first = self._step - self.config.substeps + 1
        err = SimulationDivergedError(f"simulation diverged in steps {first}-{self._step} (t <= {self.time:.4f} s)"
                                      f"{f' at body {body!r}' if body else ''}: {problem}", step=self._step,
                                      body=body)
        self._diverged = err
        raise err

    @property
    def diverged(self) -> bool:
        return self._diverged is not None

    # ------------------------------------------------------------------ read back
    def frame_times(self) -> np.ndarray:
        """``(F,)`` world times of the recorded frames."""
        return np.array(self._frame_steps, dtype=np.float64) * self.dt

    def trajectory(self, char: Character, fps: float | None = None, start: float | None = None,
                   stop: float | None = None) -> Motion:
        """The recorded motion of ``char`` as a :class:`Motion` (at the world's fps, or resampled to
        ``fps``), between world times ``start`` and ``stop`` (inclusive; default everything).

        Raises:
            SimulationDivergedError: the simulation diverged; nothing is handed out.
        """
        if self._diverged is not None:
            raise SimulationDivergedError(f"not reading back a diverged simulation: {self._diverged}",
                                          self._diverged.step, self._diverged.body)
        if not self._frames:
            raise SimulationError("nothing recorded yet; step the world first")
        self._ensure()
        bm = char.map
        t = self.frame_times()
        # frames recorded since the character exists
        sel = np.array([len(q) >= char.qadr + bm.nq and (char.mocap_id < 0 or len(mc[0]) > char.mocap_id)
                        for q, mc in zip(self._frames, self._mocap)])
        if start is not None:
            sel &= t >= start - 1e-9
        if stop is not None:
            sel &= t <= stop + 1e-9
        if not sel.any():
            raise ParameterError(f"no recorded frame of {char.name!r} between {start} and {stop} s")
        idx = np.nonzero(sel)[0]
        block = np.array([self._frames[i][char.qadr:char.qadr + bm.nq] for i in idx]).reshape(len(idx), bm.nq)
        if char.mocap_id >= 0:
            root_pos = np.array([self._mocap[i][0][char.mocap_id] for i in idx])
            root_quat = np.array([self._mocap[i][1][char.mocap_id] for i in idx])
            local = qpos_to_local_rot(bm, block, root_quat)
        else:
            root_pos = block[:, :3]
            local = qpos_to_local_rot(bm, block)
        motion = Motion(char.skeleton, root_pos, quat.unroll(local), self.config.fps,
                        name=f"{char.name} (simulated)")
        if fps is not None and abs(fps - self.config.fps) > 1e-9:
            motion = motion.resample(fps)
        return motion

    def get_state(self, spec=mujoco.mjtState.mjSTATE_FULLPHYSICS) -> np.ndarray:
        """The full physics state vector (for :mod:`kinodyn.physics.rollout`)."""
        n = mujoco.mj_stateSize(self.model, spec)
        out = np.empty(n)
        mujoco.mj_getState(self.model, self.data, out, spec)
        return out

    def set_state(self, state, spec=mujoco.mjtState.mjSTATE_FULLPHYSICS) -> None:
        mujoco.mj_setState(self.model, self.data, np.asarray(state, dtype=np.float64), spec)
        self._step = round(self.data.time / self.dt)

    def to_xml(self) -> str:
        """MJCF of the whole world (characters, balls, ground)."""
        return self._spec.to_xml()


def _reach(body: CharacterBody) -> float:
    """Farthest point of a character's geometry from its root joint in the rest pose (m)."""
    m = body.model()
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    root = d.xpos[1]
    return float(max(np.linalg.norm(d.geom_xpos[g] - root) + m.geom_rbound[g] for g in range(1, m.ngeom)))


def _geom_volume(m: mujoco.MjModel, g: int) -> float:
    s = m.geom_size[g]
    t = m.geom_type[g]
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        return 4.0 / 3.0 * np.pi * s[0] ** 3
    if t == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return np.pi * s[0] ** 2 * 2 * s[1] + 4.0 / 3.0 * np.pi * s[0] ** 3
    if t == mujoco.mjtGeom.mjGEOM_BOX:
        return 8.0 * s[0] * s[1] * s[2]
    return 1e-6


def _lowest_point(m: mujoco.MjModel, d: mujoco.MjData, geoms) -> float:
    """Lowest world z over capsules, spheres and boxes (after ``mj_kinematics``)."""
    low = np.inf
    for g in geoms:
        t = m.geom_type[g]
        s = m.geom_size[g]
        c = d.geom_xpos[g]
        r = d.geom_xmat[g].reshape(3, 3)
        if t == mujoco.mjtGeom.mjGEOM_SPHERE:
            z = c[2] - s[0]
        elif t == mujoco.mjtGeom.mjGEOM_CAPSULE:
            z = c[2] - abs(r[2, 2]) * s[1] - s[0]
        elif t == mujoco.mjtGeom.mjGEOM_BOX:
            z = c[2] - np.abs(r[2]) @ s[:3]
        else:
            continue
        low = min(low, z)
    return float(low)


def step_parallel(worlds: list[World], frames: int = 1, threads: int | None = None) -> None:
    """Step several independent worlds on a pool of threads (MuJoCo releases the GIL while it steps).

    Characters that never meet can live in separate worlds and use every core; characters that
    interact must share one world.
    """
    from concurrent.futures import ThreadPoolExecutor

    from kinodyn.physics.rollout import default_threads

    threads = default_threads() if threads is None else int(threads)
    if threads <= 1 or len(worlds) <= 1:
        for w in worlds:
            w.step(frames)
        return
    for w in worlds:  # compile in this thread first
        w._ensure()
    with ThreadPoolExecutor(max_workers=threads) as ex:
        for f in [ex.submit(w.step, frames) for w in worlds]:
            f.result()
