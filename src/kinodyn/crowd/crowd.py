"""Many keyframe characters simulated and posed together (sections 3 to 5, figure 1).

Mitake et al., figure 1: every frame the character AI (:mod:`behaviours`) sets a target, the
controller (:mod:`controller`) computes the friction force and centre-of-pressure torque of each body,
MuJoCo steps all bodies with the floor, the props, thrown balls and each other, and each body's state
is mapped into the keyframe space (:mod:`keyframes`) and posed from the keyframe set
(:mod:`interpolate`) in its frame Sr. All of it runs on arrays over the N characters: one MuJoCo model
holds every body; the control is numpy, the posing one compiled kernel; there is no Python loop over
characters in a frame.

The feet are the controller's: the floor itself is frictionless for the characters (MuJoCo contact
dimension 1), so the only horizontal floor force on a body is the bounded friction force of section
4.2. Characters touch each other frictionlessly, through their contact capsules by default
(:attr:`CrowdConfig.body_contact`, :attr:`~kinodyn.crowd.body.BodyConfig.contact_capsule`); balls and
props have friction and touch the ellipsoids. The controller's forces and the pushes enter MuJoCo as
generalized forces of the free joints (``qfrc_applied``: the force in world axes, the torque in the
body's), which is what MuJoCo makes of the same force and torque at the centre of mass given as
``xfrc_applied``, without a Jacobian per body each step.

:class:`Crowd` is the one mutable simulator here; it says what it changes. Units: metres, seconds,
radians, newtons, kilograms; world Z up.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numba
import numpy as np

from kinodyn.crowd.behaviours import AIConfig, decide_fast, new_ai
from kinodyn.crowd.body import BodyConfig, rigid_state_fast
from kinodyn.crowd.controller import (
    BALANCE,
    STANDING_UP,
    ControllerConfig,
    control_kernel,
    new_control_state,
    pack_config,
)
from kinodyn.crowd.interpolate import interpolate_prepared, scratch
from kinodyn.crowd.keyframes import KeyframeSet, builtin_keyframes, travel
from kinodyn.errors import ParameterError, SimulationDivergedError
from kinodyn.math.kernels import qrot_inv

__all__ = ["BODY_CONTACTS", "Crowd", "CrowdConfig", "Prop", "generalized_forces", "grid"]

BODY_CONTACTS = ("capsule", "ellipsoid")
# contact groups (MuJoCo contype / conaffinity bits): a pair collides when one's type meets the other's
# affinity. The floor, props and balls touch the ellipsoids; the characters touch each other through
# one shape only (their capsules, or their ellipsoids); balls touch balls.
_WORLD, _SHAPE, _PROXY = 1, 2, 4


@dataclass(frozen=True)
class CrowdConfig:
    """How a crowd is stepped and posed.

    Attributes:
        fps: frames per second (control, posing and recording run once per frame).
        substeps: MuJoCo steps per frame (timestep ``1 / (fps * substeps)``).
        balls: ball slots in the model (MuJoCo models are fixed once built; :meth:`Crowd.throw`
            reuses them in turn).
        ball_radius, ball_mass: metres and kilograms of a thrown ball.
        behaviour_ease: seconds to blend from one behaviour value B to another.
        side_halflife: seconds to ease the side-plane weight of the interpolation.
        on_floor_margin: metres above its resting height under which a body touches the floor.
        still_speed: m/s under which a balancing character that is asked to stay is *still*: the AI
            then shows it with the standing-up behaviour, whose keyframe at zero tilt is the standing
            pose (section 6.1: the AI picks B; walking resumes B = walking as soon as it moves).
        body_contact: the shape with which characters touch each other: ``"capsule"`` (their contact
            capsules, solved in closed form) or ``"ellipsoid"`` (the ellipsoids themselves, by MuJoCo's
            iterative convex search: the same shape as with the floor, at about twice the physics cost
            of a dense crowd).
    """

    fps: float = 60.0
    substeps: int = 1
    balls: int = 4
    ball_radius: float = 0.11
    ball_mass: float = 1.0
    behaviour_ease: float = 0.3
    side_halflife: float = 0.15
    on_floor_margin: float = 0.04
    still_speed: float = 0.15
    body_contact: str = "capsule"

    def __post_init__(self):
        if self.body_contact not in BODY_CONTACTS:
            raise ParameterError(f"CrowdConfig.body_contact must be one of {BODY_CONTACTS}, got {self.body_contact!r}")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ParameterError(f"CrowdConfig.fps must be positive, got {self.fps!r}")
        if not (isinstance(self.substeps, int) and self.substeps >= 1):
            raise ParameterError(f"CrowdConfig.substeps must be an int >= 1, got {self.substeps!r}")
        if not (isinstance(self.balls, int) and self.balls >= 0):
            raise ParameterError(f"CrowdConfig.balls must be an int >= 0, got {self.balls!r}")


@dataclass(frozen=True)
class Prop:
    """A static obstacle: ``kind`` ``"box"`` (``size`` = half extents) or ``"cylinder"`` (``size`` =
    radius, half height, unused), centred at ``pos (3,)``."""

    kind: str
    pos: tuple[float, float, float]
    size: tuple[float, float, float]

    def __post_init__(self):
        if self.kind not in ("box", "cylinder"):
            raise ParameterError(f"Prop.kind must be 'box' or 'cylinder', got {self.kind!r}")


def grid(n: int, spacing: float = 1.2, jitter: float = 0.2, seed: int = 0) -> np.ndarray:
    """``(n, 2)`` positions on a square grid around the origin with random jitter (metres)."""
    side = int(np.ceil(np.sqrt(n)))
    i = np.arange(n)
    p = np.stack([i % side, i // side], axis=1).astype(float) * spacing
    p -= p.mean(axis=0)
    return p + np.random.default_rng(seed).uniform(-jitter, jitter, (n, 2))


def _build_model(pos: np.ndarray, heading: np.ndarray, body: BodyConfig, cfg: CrowdConfig, props):
    import mujoco

    spec = mujoco.MjSpec()
    spec.option.timestep = 1.0 / (cfg.fps * cfg.substeps)
    spec.memory = int(64e6 + 60e3 * len(pos))
    spec.option.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
    # Projected Gauss-Seidel: the contacts are frictionless (condim 1) but for the few balls and
    # props, so it converges in a couple of sweeps; Newton's sparse Cholesky of its Hessian cost
    # more than everything else in a step (measured with kinodyn bench crowd).
    spec.option.solver = mujoco.mjtSolver.mjSOL_PGS
    # Each character has two geoms, so MuJoCo's midphase would test the bounding-box trees of every
    # pair of bodies the broadphase finds (the floor's with each character among them) before the
    # geoms' own bounding spheres; the contact groups already keep each pair to one geom pair, so
    # the trees only cost (a third of the collision time of 5,000 characters) and find nothing new.
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_MIDPHASE
    w = spec.worldbody
    w.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], condim=1, contype=_WORLD,
               conaffinity=_SHAPE)
    capsule = cfg.body_contact == "capsule"
    # the ellipsoids touch each other only when they are the characters' contact shape
    shape_bits = dict(contype=_SHAPE | (0 if capsule else _PROXY), conaffinity=_WORLD | (0 if capsule else _PROXY))
    radius, half = body.contact_capsule
    for (x, y), h in zip(pos, heading):
        b = w.add_body(pos=[x, y, body.l], quat=[np.cos(h / 2), 0, 0, np.sin(h / 2)])
        b.add_freejoint()
        b.explicitinertial = True
        b.mass = body.mass
        b.inertia = [body.inertia] * 3
        b.ipos = [0.0, 0.0, 0.0]
        b.add_geom(type=mujoco.mjtGeom.mjGEOM_ELLIPSOID, size=list(body.semi_axes),
                   pos=list(body.shape_offset), condim=1, density=0.0, **shape_bits)
        if capsule:
            b.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[radius, half, 0.0], pos=list(body.shape_offset),
                       condim=1, density=0.0, contype=_PROXY, conaffinity=_PROXY, group=3)
    for k in range(cfg.balls):
        b = w.add_body(pos=[-1000.0 - 3 * k, -1000.0, cfg.ball_radius])
        b.add_freejoint()
        b.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[cfg.ball_radius, 0, 0], mass=cfg.ball_mass,
                   condim=3, friction=[0.6, 0.005, 0.0001], contype=_WORLD, conaffinity=_WORLD | _SHAPE)
    for p in props:
        kind = mujoco.mjtGeom.mjGEOM_BOX if p.kind == "box" else mujoco.mjtGeom.mjGEOM_CYLINDER
        w.add_geom(type=kind, pos=list(p.pos), size=list(p.size), condim=3, friction=[0.8, 0.005, 0.0001],
                   contype=_WORLD, conaffinity=_SHAPE)
    model = spec.compile()
    return model, mujoco.MjData(model)


@dataclass
class _Pushes:
    who: list = field(default_factory=list)
    force: list = field(default_factory=list)
    local: list = field(default_factory=list)
    until: list = field(default_factory=list)


class Crowd:
    """N keyframe characters in one MuJoCo world (mutable: :meth:`step` advances it in place).

    Args:
        positions: ``(N, 2)`` start positions on the floor, metres.
        headings: ``(N,)`` start headings, radians (default 0: facing +X).
        body, controller, ai: configurations of the bodies, their controllers and the behaviours
            (None: the defaults).
        keyframes: the keyframe set (default: the built-in one of figure 8).
        config: stepping and posing (None: :class:`CrowdConfig` defaults).
        props: static :class:`Prop` obstacles.
        seed: seeds the behaviours' randomness and the characters' starting walk phases.
        pose: pose the characters every frame (False: physics and control only).
    """

    def __init__(self, positions, headings=None, *, body: BodyConfig | None = None,
                 controller: ControllerConfig | None = None, ai: AIConfig | None = None,
                 keyframes: KeyframeSet | None = None, config: CrowdConfig | None = None, props=(),
                 seed: int = 0, pose: bool = True):
        body, controller = body or BodyConfig(), controller or ControllerConfig()
        ai, config = ai or AIConfig(), config or CrowdConfig()
        pos = np.asarray(positions, dtype=np.float64)
        if pos.ndim != 2 or pos.shape[1] != 2 or len(pos) == 0 or not np.all(np.isfinite(pos)):
            raise ParameterError(f"positions must be a finite (N, 2) array with N >= 1, got shape {pos.shape}")
        n = len(pos)
        head = np.zeros(n) if headings is None else np.broadcast_to(np.asarray(headings, float), (n,)).copy()
        self.n, self.body, self.controller, self.ai_config, self.config = n, body, controller, ai, config
        self.keyframes = builtin_keyframes() if keyframes is None else keyframes
        self.model, self.data = _build_model(pos, head, body, config, props)
        self.dt = 1.0 / config.fps
        self.time, self.frame = 0.0, 0
        self._qpos = self.data.qpos[: 7 * n].reshape(n, 7)
        self._qvel = self.data.qvel[: 6 * n].reshape(n, 6)
        self._qfrc = self.data.qfrc_applied[: 6 * n].reshape(n, 6)
        rng = np.random.default_rng(seed)
        self.ai = new_ai(n, head, ai, rng)
        self.control_state = new_control_state(n)
        self._params = pack_config(body, controller)
        self._forces = np.zeros((n, 6))
        stride = self.keyframes.stride
        self.d_side = np.zeros(n)
        self.d_front = rng.uniform(0.0, stride, n)
        nb = len(self.keyframes.behaviours)
        self._stand_b = (self.keyframes.behaviours.index("standing_up")
                         if "standing_up" in self.keyframes.behaviours else 0)
        self.behaviour_weights = np.zeros((n, nb))
        self.behaviour_weights[:, 0] = 1.0
        self.side_weight = np.zeros(n)
        self.posing = pose
        j = self.keyframes.key_rot.shape[1]
        # float32 rotations: shown (and recorded) poses need no more, and the sum runs twice as wide
        self.local_rot, self.root_pos = np.zeros((n, j, 4), np.float32), np.zeros((n, 3))
        self.local_rot[..., 0] = 1.0
        #: ``(N, 4)`` each body's current point of Q (Theta_x, Theta_z, D_x, D_z), set by posing.
        self.points = np.zeros((n, 4))
        self._v_target = np.zeros((n, 2))
        self._pushes = _Pushes()
        self._next_ball = 0
        self._record: list | None = None
        #: CPU seconds of this thread spent in each part of :meth:`step` (behaviours and control,
        #: MuJoCo, posing), accumulated; reset it to measure a stretch.
        self.timings = {"control": 0.0, "physics": 0.0, "posing": 0.0}
        self.state, self._on_floor = rigid_state_fast(self._qpos, self._qvel, body, config.on_floor_margin)
        self._work = scratch(n, np.float32)
        if pose:
            self._pose()

    # ------------------------------------------------------------------ outside forces
    def push(self, who, force, point=None, duration: float = 0.1) -> None:
        """Push characters: ``force (k, 3)`` newtons at world ``point (k, 3)`` (default: the centre of
        mass) for ``duration`` seconds; the point is kept fixed on the body while the push lasts."""
        who = np.atleast_1d(np.asarray(who, np.int64))
        if np.any((who < 0) | (who >= self.n)):
            raise ParameterError(f"who must index characters 0..{self.n - 1}, got {who.tolist()}")
        f = np.broadcast_to(np.asarray(force, float), (len(who), 3))
        s = self.state
        p = s.r[who] if point is None else np.broadcast_to(np.asarray(point, float), (len(who), 3))
        from kinodyn.math import quat

        local = quat.inv_mul_vec(s.quat[who], p - s.r[who])
        pu = self._pushes
        pu.who.append(who), pu.force.append(np.array(f)), pu.local.append(local)
        pu.until.append(np.full(len(who), self.time + duration))

    def throw(self, pos, vel) -> int:
        """Throw a ball from world ``pos (3,)`` with velocity ``vel (3,)`` m/s; returns its slot."""
        if self.config.balls == 0:
            raise ParameterError("this crowd has no ball slots (CrowdConfig.balls = 0)")
        k = self._next_ball
        self._next_ball = (k + 1) % self.config.balls
        q0, v0 = 7 * self.n + 7 * k, 6 * self.n + 6 * k
        self.data.qpos[q0: q0 + 7] = [*pos, 1.0, 0.0, 0.0, 0.0]
        self.data.qvel[v0: v0 + 6] = [*vel, 0.0, 0.0, 0.0]
        return k

    def ball_positions(self) -> np.ndarray:
        """``(balls, 3)`` ball centres."""
        q = self.data.qpos[7 * self.n:].reshape(-1, 7)
        return q[:, :3].copy()

    def _apply_pushes(self) -> None:
        pu = self._pushes
        if not pu.who:
            return
        who, f, local, until = (np.concatenate(x) for x in (pu.who, pu.force, pu.local, pu.until))
        live = until > self.time + 1e-9
        if not live.any():
            pu.who, pu.force, pu.local, pu.until = [], [], [], []
            return
        who, f, local, until = who[live], f[live], local[live], until[live]
        pu.who, pu.force, pu.local, pu.until = [who], [f], [local], [until]
        from kinodyn.math import quat

        s = self.state
        arm = quat.mul_vec(s.quat[who], local)
        np.add.at(self._forces, (who, slice(0, 3)), f)
        np.add.at(self._forces, (who, slice(3, 6)), np.cross(arm, f))

    # ------------------------------------------------------------------ stepping
    def step(self, frames: int = 1) -> None:
        """Advance ``frames`` frames: behaviours, control, physics, travel, posing (and recording)."""
        import mujoco

        body, cfg = self.body, self.config
        tm = self.timings
        for _ in range(int(frames)):
            t0 = time.thread_time()
            s = self.state
            v, h = decide_fast(self.ai, s, self.ai_config, self.dt)
            self._v_target = v
            cs = self.control_state
            control_kernel(self._qpos, self._qvel, self._on_floor, v, h, cs.mode, cs.timer, cs.stand_from,
                           self._params, self.dt, self._forces)
            self._apply_pushes()
            generalized_forces(self._qpos, self._forces, self._qfrc)
            t1 = time.thread_time()
            mujoco.mj_step(self.model, self.data, nstep=cfg.substeps)
            t2 = time.thread_time()
            self.time += self.dt
            self.frame += 1
            s, self._on_floor = rigid_state_fast(self._qpos, self._qvel, body, cfg.on_floor_margin)
            self.state = s
            self.d_side, self.d_front = travel(self.d_side, self.d_front, s.vel, s.forward, s.left, self.dt)
            if self.frame % 30 == 0 and not np.all(np.isfinite(self._qpos)):
                bad = int(np.flatnonzero(~np.all(np.isfinite(self._qpos), axis=1))[0])
                raise SimulationDivergedError(f"character {bad} diverged at frame {self.frame}",
                                              step=self.frame, body=str(bad))
            t3 = time.thread_time()
            if self.posing:
                self._pose()
            t4 = time.thread_time()
            tm["control"] += (t1 - t0) + (t3 - t2)
            tm["physics"] += t2 - t1
            tm["posing"] += t4 - t3
            if self._record is not None:
                self._record.append((self.root_pos.astype(np.float32), self.local_rot.astype(np.float32),
                                     self.control_state.mode.astype(np.int8), self._qpos.astype(np.float32)))

    def _pose(self) -> None:
        """Map every body's state into Q and pose it from the keyframe set in its frame Sr (section 5)."""
        s, cfg = self.state, self.config
        bw, sw = self.behaviour_weights, self.side_weight
        _pose_inputs(s.theta_x, s.theta_z, s.vel, s.forward, s.left, self.d_side, self.d_front,
                     self.keyframes.stride, self.control_state.mode, self._v_target, self._stand_b, self.dt,
                     cfg.behaviour_ease, cfg.side_halflife, cfg.still_speed, self.points, bw, sw)
        interpolate_prepared(self.keyframes, self.points, bw, sw, self._work, (self.local_rot, self.root_pos),
                             (s.r, s.quat))

    # ------------------------------------------------------------------ recording
    def start_recording(self) -> None:
        """Keep every frame's poses, modes and body states from now on (memory: ~0.4 kB per
        character-frame)."""
        self._record = []
        if self.posing:
            self._record.append((self.root_pos.astype(np.float32), self.local_rot.astype(np.float32),
                                 self.control_state.mode.astype(np.int8), self._qpos.astype(np.float32)))

    def recording(self) -> dict[str, np.ndarray]:
        """The recorded frames: ``root_pos (F, N, 3)``, ``local_rot (F, N, J, 4)``, ``mode (F, N)``,
        ``body (F, N, 7)`` (centre of mass and rotation)."""
        if not self._record:
            raise ParameterError("nothing recorded: call start_recording() before step()")
        cols = list(zip(*self._record))
        return {"root_pos": np.stack(cols[0]), "local_rot": np.stack(cols[1]), "mode": np.stack(cols[2]),
                "body": np.stack(cols[3])}

    def motions(self, names=None) -> list:
        """One :class:`~kinodyn.motion.Motion` per character from the recording."""
        from kinodyn.motion import Motion

        rec = self.recording()
        names = names or [f"character_{i:04d}" for i in range(self.n)]
        return [Motion(skeleton=self.keyframes.skeleton, root_pos=rec["root_pos"][:, i].astype(np.float64),
                       local_rot=rec["local_rot"][:, i].astype(np.float64), fps=self.config.fps, name=names[i])
                for i in range(self.n)]


@numba.njit(cache=True)
def generalized_forces(qpos, forces, qfrc):
    """The free joints' generalized forces ``qfrc (N, 6)`` of ``forces (N, 6)`` (force, torque) at the
    centres of mass in world axes: the force as it is, the torque turned into the body's axes (MuJoCo's
    free-joint angular dofs), with ``qpos (N, 7)`` the joints' positions. The bodies' frames are at
    their centres of mass, so this is exactly MuJoCo's ``xfrc_applied`` mapping."""
    for i in range(qpos.shape[0]):
        nq = np.sqrt(qpos[i, 3] ** 2 + qpos[i, 4] ** 2 + qpos[i, 5] ** 2 + qpos[i, 6] ** 2)
        qfrc[i, 0], qfrc[i, 1], qfrc[i, 2] = forces[i, 0], forces[i, 1], forces[i, 2]
        qfrc[i, 3], qfrc[i, 4], qfrc[i, 5] = qrot_inv(qpos[i, 3] / nq, qpos[i, 4] / nq, qpos[i, 5] / nq,
                                                      qpos[i, 6] / nq, forces[i, 3], forces[i, 4], forces[i, 5])


@numba.njit(cache=True)
def _pose_inputs(theta_x, theta_z, vel, forward, left, d_side, d_front, stride, mode, v_target, stand_b, dt,
                 ease, side_halflife, still_speed, points, bweights, side_weight):
    """Each body's point of Q (equations 9, 10), its eased behaviour weights and side-plane weight.

    A balancing body that stands still (or one standing up) is shown with the standing-up behaviour;
    the weights move toward the one-hot target by at most ``dt / ease`` per frame; the side-plane
    weight eases with a half-life toward the share of sideways motion and tilt.
    """
    nb = bweights.shape[1]
    step = min(1.0, dt / ease)
    keep = 1.0 - 0.5 ** (dt / side_halflife)
    for i in range(points.shape[0]):
        points[i, 0], points[i, 1] = theta_x[i], theta_z[i]
        ps, pf = d_side[i] / stride, d_front[i] / stride
        ps, pf = ps - np.floor(ps), pf - np.floor(pf)
        points[i, 2], points[i, 3] = (0.0 if ps >= 1.0 else ps), (0.0 if pf >= 1.0 else pf)
        vf = vel[i, 0] * forward[i, 0] + vel[i, 1] * forward[i, 1] + vel[i, 2] * forward[i, 2]
        vs = vel[i, 0] * left[i, 0] + vel[i, 1] * left[i, 1] + vel[i, 2] * left[i, 2]
        still = (mode[i] == BALANCE and np.hypot(vf, vs) < still_speed
                 and np.hypot(v_target[i, 0], v_target[i, 1]) < 0.05 and abs(theta_x[i]) < 0.1)
        target = stand_b if (mode[i] == STANDING_UP or still) else 0
        total = 0.0
        for b in range(nb):
            goal = 1.0 if b == target else 0.0
            bweights[i, b] += min(step, max(-step, goal - bweights[i, b]))
            total += bweights[i, b]
        for b in range(nb):
            bweights[i, b] /= total
        a_side = vs * vs + (3.0 * theta_z[i]) ** 2
        a_fwd = vf * vf + (3.0 * theta_x[i]) ** 2
        side_weight[i] += (a_side / (a_side + a_fwd + 0.02) - side_weight[i]) * keep
