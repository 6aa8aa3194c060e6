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
  kinematic starts from the clip's positions and velocities at that instant. One frame later the body
  is within about 1.4 cm of the clip, but its velocities are up to 12-14 % (built-in walk and run) and
  23 % (CMU 02_01) off where the ground does not carry what the clip needs: a stance foot on its toes
  whose ankle carries nothing, a frame asking for more than friction gives, a captured stance foot a
  few millimetres above the floor (the sweep in ``tests/test_physics_switch.py`` and its measured
  causes). With ``PDConfig(feedforward="dynamics")`` the servos carry the clip's inverse dynamics from
  the first step (on the built-in run 9 % at worst).

A character can also be given a fixed root (``BodyConfig(root="fixed")``): its pelvis hangs where it is
placed (a mocap body) and the limbs are simulated.

Time advances in output frames (``fps``, default 60) of ``substeps`` physics steps each (default 4, i.e.
dt = 1/240 s). After every frame the state is checked: a non-finite or exploding state raises
:class:`~kinodyn.errors.SimulationDivergedError` naming the step and the body, and the world refuses to
go on or to hand out its trajectory. Each frame's ``qpos`` is recorded; :meth:`World.trajectory` turns a
character's record into a Motion at any frame rate.

The world is a thin public surface over stages that take the model, the data and the handles, so a new
capability adds a stage rather than a method: model assembly (:mod:`~kinodyn.physics.assembly`),
playback of clips and servo targets (:mod:`~kinodyn.physics.playback`), impacts
(:mod:`~kinodyn.physics.impacts`), recording and divergence checks (:mod:`~kinodyn.physics.recording`);
the handles are in :mod:`~kinodyn.physics.handles`.

Shapes: ``nq``/``nv``/``nu`` are the world model's sizes; per-character blocks are described by
:class:`~kinodyn.physics.body.BodyMap`.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from kinodyn.clips import unroll_loops
from kinodyn.errors import (
    MotionError,
    ParameterError,
    SimulationDivergedError,
    SimulationError,
    UnknownNameError,
)
from kinodyn.math import quat, xform
from kinodyn.motion import Motion
from kinodyn.physics import assembly, playback, recording, tracking
from kinodyn.physics import impacts as _impacts
from kinodyn.physics.body import BodyConfig, CharacterBody, build_body, pose_to_ctrl
from kinodyn.physics.config import MAX_SPEED, WorldConfig
from kinodyn.physics.handles import Character, Projectile
from kinodyn.physics.playback import clip_qvel
from kinodyn.physics.rollout import step_parallel
from kinodyn.skeleton import Skeleton

__all__ = ["MAX_SPEED", "Character", "Projectile", "World", "WorldConfig", "clip_qvel", "step_parallel"]

# --------------------------------------------------------------------------- clips


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
        g = unroll_loops(self.cycle, self.cycle, rep - 1)  # rep whole loops of the clip, composed
        q, v = q.copy(), v.copy()
        q[:2] = xform.apply(g, q[:2])
        q[3:7] = quat.mul(quat.from_heading(g[2]), q[3:7])
        c, s_ = np.cos(g[2]), np.sin(g[2])
        v[:2] = (c * v[0] - s_ * v[1], s_ * v[0] + c * v[1])  # world linear velocity turns with the heading
        return q, v


# --------------------------------------------------------------------------- world


class World:
    """Characters, projectiles and a ground plane in one MuJoCo model (mutable).

    The world holds the model, the data and the bookkeeping between steps (step count, impact log,
    recording, pending throws); the work is done by stages that take them: model assembly
    (:mod:`~kinodyn.physics.assembly`), playback (:mod:`~kinodyn.physics.playback`), impacts
    (:mod:`~kinodyn.physics.impacts`), recording and checks (:mod:`~kinodyn.physics.recording`).

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
        self._spec = assembly.new_spec(config)
        self._model: mujoco.MjModel | None = None
        self._data: mujoco.MjData | None = None
        self._dirty = True
        self._step = 0
        self._log = _impacts.ImpactLog(config.impact_gap)
        self._rec = recording.Recording()
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
        root = assembly.attach_character(self._spec, body, name, at)  # rest pose on the floor
        char = Character(self, len(self.characters), name, body)
        if body.config.root == "fixed":
            char.mocap0 = root
        self.characters.append(char)
        self._dirty = True  # compiled when the model is next needed
        return char

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
        assembly.add_ball(self._spec, name, k, mass, radius, self.config.contact_timeconst or 2.0 * self.dt)
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
        self._owner, self._reach = assembly.bind(self._model, self.characters, self.projectiles)
        d = self._data
        self._warn0 = recording.warning_counts(d)
        for c in self.characters:
            if c.mocap0 is not None:
                d.mocap_pos[c.mocap_id], d.mocap_quat[c.mocap_id] = c.mocap0
                c.mocap0 = None
            if c.mode == "kinematic" and c.clip is not None:
                playback.set_kinematic(d, c, self._step)
            playback.set_ctrl(d, c, self._step)

    def character(self, name: str) -> Character:
        for c in self.characters:
            if c.name == name:
                return c
        raise UnknownNameError(f"no character named {name!r}; characters: {', '.join(c.name for c in self.characters)}")

    # ------------------------------------------------------------------ clips and modes
    def _sample_clip(self, char: Character, motion: Motion, start_step: int, loop: bool, align_floor) -> _Clip:
        root_quat = None if char.mocap_id < 0 else self.data.mocap_quat[char.mocap_id]
        qpos, qvel, ctrl, cycle = playback.sample_clip(char, motion, self.dt, root_quat, align_floor, loop)
        return _Clip(motion, start_step, qpos, qvel, ctrl, loop, char.map.segments[0].kind == "free", cycle)

    def play(self, char: Character, motion: Motion, start: float = 0.0, at=None, loop: bool = False,
             align_floor=True) -> None:
        """Play ``motion`` kinematically on ``char`` from clip time ``start`` (s), beginning now.

        Args:
            start: clip time (s) to begin at; with ``loop`` a phase in the cycle.
            at: ``(x, y, heading)`` ground transform for the clip's frame at ``start`` (default: as
                recorded).
            loop: repeat the clip (for cyclic clips: each repetition starts where the last one ended, moved
                on the floor); otherwise hold the last frame.
            align_floor: ``True`` moves each frame vertically so the floor the clip was captured on
                (a plane fitted to the body's lowest points, which follows a floor that is not level)
                lies on the world's floor; ``False`` plays it as is; a number shifts by that.
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
        playback.set_kinematic(self.data, char, self._step)
        playback.set_ctrl(self.data, char, self._step)

    def switch_to_dynamic(self, char: Character, stiffness=None, damping=None) -> None:
        """Let MuJoCo integrate ``char`` from now on, starting from the clip's current positions and
        velocities; its servos keep tracking the clip (or its :meth:`track` target). Optionally set gains."""
        self._ensure()
        if char.mode == "kinematic" and char.clip is not None:
            playback.set_kinematic(self.data, char, self._step)
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
            playback.set_kinematic(self.data, char, self._step)
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
        playback.set_ctrl(self.data, char, self._step)

    def set_gains(self, char: Character, stiffness=1.0, damping=None, joints=None) -> None:
        """Scale ``char``'s servo gains now (0 = limp, 1 = the defaults; see :func:`tracking.apply_gains`).

        Args:
            joints: segment/joint names or landmarks to change (default all).
        """
        self._ensure()
        a = len(char.map.actuated)
        sel = np.arange(a) if joints is None else playback.actuator_index(char, joints)
        st = np.broadcast_to(np.asarray(stiffness, dtype=np.float64), (len(sel),))
        dm = np.sqrt(np.maximum(st, 0)) if damping is None else \
            np.broadcast_to(np.asarray(damping, dtype=np.float64), (len(sel),))
        if not np.all(np.isfinite(st)) or np.any(st < 0) or not np.all(np.isfinite(dm)) or np.any(dm < 0):
            raise ParameterError(f"gain multipliers must be non-negative numbers, got stiffness={stiffness!r}, "
                                 f"damping={damping!r}")
        char.stiffness[sel] = st
        char.damping[sel] = dm
        tracking.apply_gains(self.model, char.actuator_ids, char.body.kp, char.body.kv, char.stiffness,
                             char.damping)

    def place_root(self, char: Character, pos, quat_=None) -> None:
        """Move a fixed-root character's root (a mocap body) to ``pos`` with rotation ``quat_``."""
        self._ensure()
        if char.mocap_id < 0:
            raise SimulationError(f"character {char.name!r} has a free root; place it by playing a clip")
        self.data.mocap_pos[char.mocap_id] = pos
        if quat_ is not None:
            self.data.mocap_quat[char.mocap_id] = quat.normalize(np.asarray(quat_, dtype=np.float64))

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
        start, vel, t_launch = _impacts.aim(lambda t: self.landmark_point(char, b, t), self.time, at, speed,
                                            direction, height, distance, self.config.gravity)
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
        """``(3,)`` world position of the centre of segment ``b``'s geometry at time ``t`` (clip-predicted
        for kinematic characters, current otherwise)."""
        return _impacts.landmark_point(self.model, self.data, char, b, round(t / self.dt))

    def push(self, char: Character, body: str, impulse, point=None) -> None:
        """An impulsive push, now: ``impulse (3,)`` N s at ``point`` (world, default the segment's centre
        of mass) on ``body``. The velocities jump by ``M^-1 J^T impulse`` at the current pose, so the
        character's momentum changes by exactly the impulse (contacts react from the next step on).
        Switches a kinematic character to dynamic when its ``on_impact`` says so. Recorded as an impact.

        Raises:
            ParameterError: the impulse is not a finite 3-vector, or it would make a speed exceed
                ``max_speed`` (the state would count as exploded); the world is left as it was.
        """
        self._ensure()
        imp = np.asarray(impulse, dtype=np.float64)
        if imp.shape != (3,) or not np.all(np.isfinite(imp)):
            raise ParameterError(f"impulse must be a finite (3,) vector in N s, got {impulse!r}")
        b = char.map.body(body)
        bid = int(char.body_ids[b])
        before = (char.mode, char.switch_time, self.data.qpos.copy(), self.data.qvel.copy())
        if char.mode == "kinematic":
            if char.on_impact != "switch":
                raise SimulationError(f"character {char.name!r} plays a clip and ignores impacts; switch it to "
                                      "dynamic (or set on_impact='switch') to push it")
            self.switch_to_dynamic(char)
        dv, p = _impacts.push_velocity(self.model, self.data, bid, imp, point)
        err = _impacts.check_push(self.model, self.data.qvel + dv, self.config.max_speed, imp,
                                  f"{char.name}/{char.map.segments[b].name}")
        if err is not None:  # leave the world as it was
            char.mode, char.switch_time = before[:2]
            self.data.qpos[:], self.data.qvel[:] = before[2:]
            raise err
        self.data.qvel[:] += dv
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
        if self.record and not len(self._rec):
            self._rec.append(d, self._step)
        for _ in range(frames):
            self._frame(m, d)

    def _frame(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """One output frame: playback, physics steps, impacts, then the checks and the recording."""
        nsub = self.config.substeps
        # who needs what this frame (modes change only between steps, on impacts)
        kin = [c for c in self.characters if c.mode == "kinematic" and c.clip is not None]
        watch = any(p.active for p in self.projectiles) or \
            _impacts.characters_close(d, self.characters, self._reach)
        ctrl = playback.frame_controls(self.characters, d, self._step, nsub)
        for _s in range(nsub):
            if self._pending_throws:
                self._launch_due()
                watch = True
            if ctrl is not None:
                d.ctrl[:] = ctrl[_s]
            mujoco.mj_step(m, d)
            self._step += 1
            if watch and _impacts.watch_contacts(m, d, self._owner, self.dt, self.time, self.characters,
                                                 self.projectiles, self._log):
                kin = [c for c in kin if c.mode == "kinematic"]
                # someone was hit and turned dynamic: follow its clip now
                ctrl = playback.frame_controls(self.characters, d, self._step, nsub - _s - 1, ctrl_prev=ctrl,
                                               offset=_s + 1)
            for c in kin:
                playback.set_kinematic(d, c, self._step)
        err = recording.divergence(m, d, self._warn0, self.config.max_speed, self._step, nsub, self.time)
        if err is not None:
            self._diverged = err
            raise err
        if self.record:
            self._rec.append(d, self._step)

    def run(self, seconds: float) -> None:
        """Advance by ``seconds`` (rounded to whole frames)."""
        if not (np.isfinite(seconds) and seconds >= 0):
            raise ParameterError(f"seconds must be a non-negative number, got {seconds!r}")
        self.step(round(seconds * self.config.fps))

    @property
    def diverged(self) -> bool:
        return self._diverged is not None

    # ------------------------------------------------------------------ read back
    def frame_times(self) -> np.ndarray:
        """``(F,)`` world times of the recorded frames."""
        return self._rec.times(self.dt)

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
        if not len(self._rec):
            raise SimulationError("nothing recorded yet; step the world first")
        self._ensure()
        motion = recording.trajectory(self._rec, char, self.dt, self.config.fps, f"{char.name} (simulated)",
                                      start, stop)
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
