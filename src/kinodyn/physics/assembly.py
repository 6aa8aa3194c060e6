"""Model assembly: one MuJoCo spec for the world's characters, balls and ground, compiled and bound.

The first stage of a :class:`~kinodyn.physics.world.World`. Characters are attached to the world spec as
copies of their :class:`~kinodyn.physics.body.CharacterBody` spec under the prefix ``name/``, each on a
frame that stands its rest pose on the floor; balls are free bodies parked below the floor. After every
compile :func:`bind` writes each handle's addresses in the compiled model (its ``qpos``/``qvel``/control
blocks, body, actuator and geom ids) and checks them against the character's
:class:`~kinodyn.physics.body.BodyMap`.

The functions take the spec or the compiled model and data and the handles; none keeps state of its own
except :func:`rest_lift`'s cache per body. Units: metres, kilograms, seconds.
"""

from __future__ import annotations

import math
import weakref

import mujoco
import numpy as np

from kinodyn.errors import SimulationError
from kinodyn.physics import tracking
from kinodyn.physics.body import CharacterBody

__all__ = [
    "add_ball",
    "attach_character",
    "bind",
    "geom_volume",
    "lowest_point",
    "new_spec",
    "reach",
    "rest_lift",
]


def new_spec(config) -> mujoco.MjSpec:
    """An empty world spec for a :class:`~kinodyn.physics.world.WorldConfig`: options, the ground plane
    (when ``config.ground``) and a light."""
    spec = mujoco.MjSpec()
    spec.modelname = "kinodyn_world"
    spec.option.timestep = config.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.gravity = [0.0, 0.0, -config.gravity]
    spec.copy_during_attach = True
    if config.ground:
        tc = config.contact_timeconst or 2.0 * config.timestep
        spec.worldbody.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05],
                                friction=[config.friction, 0.005, 0.0001], rgba=[0.8, 0.8, 0.8, 1],
                                priority=1, solref=[tc, 1.0])
    spec.worldbody.add_light(pos=[0, 0, 5], dir=[0, 0, -1])
    return spec


def attach_character(spec: mujoco.MjSpec, body: CharacterBody, name: str, at: np.ndarray):
    """Attach a copy of ``body``'s spec under ``name/`` with its rest pose standing on the floor at
    ``at = (x, y, heading)``. Returns the root's ``(pos, quat)`` there (the initial pose of a fixed root)."""
    lift = rest_lift(body)
    pos = [at[0], at[1], lift]
    rot = [math.cos(at[2] / 2), 0, 0, math.sin(at[2] / 2)]
    frame = spec.worldbody.add_frame(pos=pos, quat=rot)
    child = body.spec.copy()
    child.option.timestep = spec.option.timestep
    child.option.integrator = spec.option.integrator
    child.option.gravity = spec.option.gravity
    spec.attach(child, prefix=f"{name}/", frame=frame)
    return pos, rot


def add_ball(spec: mujoco.MjSpec, name: str, k: int, mass: float, radius: float, timeconst: float) -> None:
    """Add ball number ``k`` (a free sphere of ``mass`` kg and ``radius`` m) parked below the floor."""
    # compiled with gravity compensation, so that switching it off when thrown (and on when parked) works:
    # MuJoCo applies it only to bodies that had it at compile time
    b = spec.worldbody.add_body(name=name, pos=[0.0, 3.0 * k, -10.0 - 3.0 * k], gravcomp=1.0)
    b.add_freejoint(name=f"{name}/free")
    b.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], mass=mass,
               rgba=[0.9, 0.3, 0.2, 1.0], priority=1, solref=[timeconst, 1.0], friction=[0.5, 0.005, 0.0001])


_LIFTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def rest_lift(body: CharacterBody) -> float:
    """Height of the root above the floor when the rest pose stands on it (cached per body)."""
    if body not in _LIFTS:
        m = body.compile()
        d = mujoco.MjData(m)
        mujoco.mj_kinematics(m, d)
        _LIFTS[body] = float(-lowest_point(m, d, np.arange(1, m.ngeom)))
    return _LIFTS[body]


def _bind_character(m: mujoco.MjModel, c, owner: np.ndarray) -> None:
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
    tracking.apply_gains(m, acts, c.body.kp, c.body.kv, c.stiffness, c.damping)


def bind(model: mujoco.MjModel, characters, projectiles) -> tuple[np.ndarray, np.ndarray]:
    """Write the compiled model's addresses into the character and projectile handles and apply their
    servo gains.

    Returns:
        ``owner (ngeom,)``: ``c >= 0`` for character ``c``'s geoms, ``-1`` the static world, ``-2 - p``
        projectile ``p`` (as :func:`~kinodyn.physics.impacts.contact_impulses` reads it), and
        ``reach (C,)``: each character's reach (:func:`reach`).
    """
    owner = np.full(model.ngeom, -1, dtype=np.int64)
    for c in characters:
        _bind_character(model, c, owner)
    for p in projectiles:
        p.bind(model)
        owner[model.body_geomadr[p.body_id]] = -2 - p.index
    return owner, np.array([reach(c.body) for c in characters])


# --------------------------------------------------------------------------- geometry


def reach(body: CharacterBody) -> float:
    """Farthest point of a character's geometry from its root joint in the rest pose (m)."""
    m = body.model()
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    root = d.xpos[1]
    return float(max(np.linalg.norm(d.geom_xpos[g] - root) + m.geom_rbound[g] for g in range(1, m.ngeom)))


def geom_volume(m: mujoco.MjModel, g: int) -> float:
    """Volume (m^3) of a sphere, capsule or box geom (1e-6 for other types)."""
    s = m.geom_size[g]
    t = m.geom_type[g]
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        return 4.0 / 3.0 * np.pi * s[0] ** 3
    if t == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return np.pi * s[0] ** 2 * 2 * s[1] + 4.0 / 3.0 * np.pi * s[0] ** 3
    if t == mujoco.mjtGeom.mjGEOM_BOX:
        return 8.0 * s[0] * s[1] * s[2]
    return 1e-6


def lowest_point(m: mujoco.MjModel, d: mujoco.MjData, geoms) -> float:
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
