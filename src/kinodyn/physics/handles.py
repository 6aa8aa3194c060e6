"""Handles of what lives in a :class:`~kinodyn.physics.world.World`: characters and projectiles.

A handle names a thing and knows its addresses in the world's compiled model (written by
:func:`kinodyn.physics.assembly.bind` after every compile); its state lives in the world's ``MjData``.
:class:`Character` forwards its control methods to the world it belongs to.

Shapes: ``nq``/``nv``/``nu`` of the character's blocks (:class:`~kinodyn.physics.body.BodyMap`), ``A``
actuated segments.
"""

from __future__ import annotations

import mujoco
import numpy as np

from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.physics import playback
from kinodyn.physics.body import CharacterBody, pose_to_ctrl
from kinodyn.skeleton import Skeleton

__all__ = ["Character", "Projectile"]


class Projectile:
    """A ball in the world (a handle; its state lives in the world's MjData)."""

    def __init__(self, world, index: int, name: str, mass: float, radius: float):
        self.world = world
        self.index = index
        self.name = name
        self.mass = mass
        self.radius = radius
        self.active = False
        #: addresses of the ball in the world model (set when the model is compiled)
        self.qadr = self.vadr = self.body_id = self.geom_id = -1

    def bind(self, model: mujoco.MjModel) -> None:
        """Read the ball's addresses in a newly compiled model."""
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

    def __init__(self, world, index: int, name: str, body: CharacterBody):
        self.world = world
        self.index = index
        self.name = name
        self.body = body
        self.mode = "dynamic"
        self.on_impact = "switch"
        #: the clip being played or followed (sampled at the physics rate), or None
        self.clip = None
        #: fixed servo targets ``(nu,)`` when not following a clip (set by :meth:`track`), else None
        self.ctrl_target: np.ndarray | None = None
        #: ``(A,)`` multipliers of the default servo stiffness and damping (see :meth:`set_gains`)
        self.stiffness = np.ones(len(body.map.actuated))
        self.damping = np.ones(len(body.map.actuated))
        self.switch_time: float | None = None
        #: initial ``(pos, quat)`` of a fixed root, applied at the next compile
        self.mocap0 = None
        #: physics steps by which each control's clip target leads (kv/kp of its servo, see
        #: PDConfig.lookahead)
        self.lead_steps = playback.lead_steps(body, world.dt)
        self.ctrl_cols = np.arange(body.map.nu)
        #: servo targets of the rest pose (identity quaternions, zero hinge angles)
        self.rest_ctrl = pose_to_ctrl(body.map, quat.identity((body.map.skeleton.num_joints,)))
        # addresses in the world model (set by assembly.bind)
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
