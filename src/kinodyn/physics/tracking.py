"""Inertia-scaled PD servos that drive a simulated character toward a target pose.

Zordan and Hodgins (2002), used by the dynamic-response papers (Zordan et al. 2005; the fast dynamic
response paper, section 6.1: "the controller uses an inertia-scaled PD-servo at each joint"): every joint
``j`` gets the torque ``kp_j * err - kv_j * omega`` with ``kp_j = s_j * I_j * w^2`` and
``kv_j = 2 * zeta * sqrt(s_j) * I_j * w``, where ``I_j`` is the moment of inertia of the subtree below
the joint about the joint, ``s_j`` the joint's row in the gains table and ``w`` the natural frequency
set by a halflife: a critically damped joint carrying its subtree halves its error in ``halflife``
seconds (``w = 1.678 / halflife``). So a hand and a hip respond equally fast, and one table serves every
skeleton and body mass.

The servos run inside MuJoCo: orientation actuators (geodesic PD on the quaternion error, 4 controls =
the target quaternion) on ball joints and position actuators (1 control = the target angle) on hinges, so
a simulation step never calls Python. Gains are model parameters (``actuator_gainprm``/``biasprm``) and
change at run time with :func:`apply_gains` (go limp on impact, stiffen for the return). A small passive
joint damping (``passive_damping * I_j``) stays on always, so a limp body is a damped ragdoll.

Two additions keep a servo from lagging its clip, both folded into the control targets so the engine
still needs nothing from Python: a followed clip is read ``kv/kp`` seconds ahead (``lookahead``; then
``kp (q(t + kv/kp) - q) - kv w ~ kp (q* - q) + kv (w* - w)``, a PD on the velocity error too), and the
static torque of the target pose, gravity less the weight the feet on the floor carry, turns each target
by ``torque / kp`` (``feedforward``, :func:`feedforward_targets`). On the built-in walk they bring the
mean joint error of a body hanging from a fixed root from several degrees to under one. With
``feedforward="dynamics"`` the targets carry the clip's whole inverse dynamics instead (with the servos'
damping of its velocities, so no lookahead), the ground's forces placed at the pose's own contacts.

Shapes: ``B`` segments, ``A`` actuated segments (all but the root). Units: N m/rad, N m s/rad, kg m^2.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import mujoco
import numpy as np

from kinodyn.errors import ParameterError

__all__ = [
    "DEFAULT_GAINS",
    "PDConfig",
    "apply_gains",
    "default_gains",
    "feedforward_targets",
    "gain_multipliers",
    "natural_frequency",
    "set_joint_passives",
    "subtree_inertia",
]

#: Stiffness multiplier ``s_j`` of each segment class (the gains table). Inertia scaling gives every
#: joint the same natural frequency, but a light distal segment (hand, toe) is shaken by its parent's
#: linear acceleration in proportion to 1 / (its length), so those get stiffer rows; the legs and spine
#: carry the body and get a little more than the arms.
DEFAULT_GAINS: Mapping[str, float] = MappingProxyType({
    "pelvis": 1.0, "spine": 1.5, "chest": 1.5, "neck": 1.5, "head": 1.5, "clavicle": 1.5,
    "upperarm": 1.0, "forearm": 1.0, "hand": 3.0, "thigh": 2.5, "shin": 2.5, "foot": 2.0, "toe": 6.0,
    "other": 1.0,
})

#: Largest turn (rad) of a servo target by its feedforward (``"dynamics"``): an orientation servo's pull
#: peaks at half a turn of error and wraps beyond it; a torque its gain cannot reach is delivered up to
#: this turn (an ankle of the built-in humanoid, kp about 40 N m/rad, carries a push-off of 150 N m).
_MAX_TURN = 1.0

#: w * halflife for a critically damped oscillator: (1 + x) exp(-x) = 1/2.
_HALF = 1.6783469900166608


@dataclass(frozen=True)
class PDConfig:
    """Gains of the tracking servos.

    Attributes:
        halflife: seconds in which a critically damped joint halves its error (stiffness 1 row).
        damping_ratio: 1 = critically damped.
        gains: segment class -> stiffness multiplier (:data:`DEFAULT_GAINS`).
        overrides: joint name -> stiffness multiplier, replacing the class row.
        inertia_scaled: scale by the subtree inertia (the paper); otherwise every joint uses
            ``reference_inertia``.
        reference_inertia: kg m^2 used when ``inertia_scaled`` is off.
        passive_damping: joint damping always present, as ``passive_damping * I_j`` (1/s).
        max_torque: torque bound as ``max_torque * I_j * w^2`` (rad of error at full stiffness); ``None``
            for unbounded servos.
        feedforward: joint torques folded into the targets so the servos need not lag to produce
            them (:func:`feedforward_targets`): ``"static"`` (gravity less the body weight carried by
            the feet on the floor), ``"dynamics"`` (inverse dynamics of the clip: also its velocities
            and accelerations and the servos' damping of its velocities, the ground carrying the body
            at the pose's own contacts, ankles included; switched from playback at any time of the
            built-in run, the body is closer to the clip one frame later than with ``"static"``) or
            ``"none"``. It scales with the stiffness (limp = none).
        lookahead: seconds by which a followed clip's targets lead the simulation. The servos have no
            velocity target, so their damping makes them lag by ``kv/kp``; aiming at the pose ``kv/kp``
            ahead cancels that to first order (``kp (q(t + kv/kp) - q) ~ kp (q* - q) + kv dq*/dt``).
            ``None`` uses each servo's own ``kv/kp``, or none with ``feedforward="dynamics"`` (its
            torques carry the servos' damping of the clip's velocities exactly).
    """

    halflife: float = 0.04
    damping_ratio: float = 1.0
    gains: Mapping[str, float] = field(default_factory=lambda: DEFAULT_GAINS)
    overrides: Mapping[str, float] = field(default_factory=dict)
    inertia_scaled: bool = True
    reference_inertia: float = 0.1
    passive_damping: float = 2.0
    max_torque: float | None = None
    feedforward: str = "static"
    lookahead: float | None = None

    def __post_init__(self):
        if not (np.isfinite(self.halflife) and self.halflife > 0):
            raise ParameterError(f"halflife must be a positive number of seconds, got {self.halflife!r}")
        if not (np.isfinite(self.damping_ratio) and self.damping_ratio >= 0):
            raise ParameterError(f"damping_ratio must be a non-negative number, got {self.damping_ratio!r}")
        bad = {k: v for k, v in {**dict(self.gains), **dict(self.overrides)}.items()
               if not (np.isfinite(v) and v >= 0)}
        if bad:
            raise ParameterError(f"gain multipliers must be non-negative numbers, got {bad}")
        if not (np.isfinite(self.reference_inertia) and self.reference_inertia > 0):
            raise ParameterError(f"reference_inertia must be positive, got {self.reference_inertia!r}")
        if not (np.isfinite(self.passive_damping) and self.passive_damping >= 0):
            raise ParameterError(f"passive_damping must be non-negative, got {self.passive_damping!r}")
        if self.max_torque is not None and not (np.isfinite(self.max_torque) and self.max_torque > 0):
            raise ParameterError(f"max_torque must be positive or None, got {self.max_torque!r}")
        if self.feedforward not in ("dynamics", "static", "none"):
            raise ParameterError(f"feedforward must be 'dynamics', 'static' or 'none', got {self.feedforward!r}")
        if self.lookahead is not None and not (np.isfinite(self.lookahead) and self.lookahead >= 0):
            raise ParameterError(f"lookahead must be a non-negative number of seconds or None, got {self.lookahead!r}")



def natural_frequency(cfg: PDConfig) -> float:
    """``w`` (rad/s) of the servos from the halflife."""
    return _HALF / cfg.halflife


def subtree_inertia(model: mujoco.MjModel, bmap, body_offset: int = 1) -> np.ndarray:
    """``(B,)`` moment of inertia (kg m^2) of each segment's subtree about the segment's joint, in the
    rest pose: about the hinge axis for hinges, the mean of the two largest principal moments (the swing
    axes) for ball joints and the root.

    ``body_offset`` is the MuJoCo id of the character's first body (1 for a stand-alone character).
    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    nb = bmap.num_bodies
    ids = np.arange(nb) + body_offset
    mass = model.body_mass[ids]
    com = data.xipos[ids]
    rot = data.ximat[ids].reshape(nb, 3, 3)
    ine = model.body_inertia[ids]
    own = np.einsum("bij,bj,bkj->bik", rot, ine, rot)
    parent = np.array([s.parent for s in bmap.segments])
    out = np.zeros(nb)
    for b in range(nb):
        members = [k for k in range(nb) if _is_under(parent, k, b)]
        p = data.xpos[ids[b]]
        tot = np.zeros((3, 3))
        for k in members:
            r = com[k] - p
            tot += own[k] + mass[k] * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
        s = bmap.segments[b]
        if s.kind == "hinge":
            ax = data.xmat[ids[b]].reshape(3, 3) @ np.asarray(s.axis)
            out[b] = float(ax @ tot @ ax)
        else:
            ev = np.sort(np.linalg.eigvalsh(tot))
            out[b] = float(0.5 * (ev[1] + ev[2]))
    return out


def _is_under(parent, k, b):
    while k >= 0:
        if k == b:
            return True
        k = parent[k]
    return False


def gain_multipliers(bmap, cfg: PDConfig) -> np.ndarray:
    """``(A,)`` stiffness multiplier ``s_j`` of each actuated segment: its joint's override, else its
    class row of the gains table."""
    out = np.zeros(len(bmap.actuated))
    for k, b in enumerate(bmap.actuated):
        s = bmap.segments[b]
        if s.name in cfg.overrides:
            out[k] = cfg.overrides[s.name]
        else:
            out[k] = cfg.gains.get(s.cls, cfg.gains.get("other", 1.0))
    return out


def default_gains(model: mujoco.MjModel, bmap, cfg: PDConfig, body_offset: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(kp (A,), kv (A,))`` of the actuated segments, from the subtree inertias (see module doc)."""
    w = natural_frequency(cfg)
    if cfg.inertia_scaled:
        inertia = subtree_inertia(model, bmap, body_offset)[bmap.actuated]
    else:
        inertia = np.full(len(bmap.actuated), cfg.reference_inertia)
    s = gain_multipliers(bmap, cfg)
    kp = s * inertia * w * w
    kv = 2.0 * cfg.damping_ratio * np.sqrt(s) * inertia * w
    return kp, kv


def set_joint_passives(spec: mujoco.MjSpec, model: mujoco.MjModel, bmap, cfg: PDConfig, armature: float) -> None:
    """Joint damping ``passive_damping * I_j`` and armature ``armature * I_j`` on every actuated joint
    of a character spec."""
    inertia = subtree_inertia(model, bmap)
    for b in bmap.actuated:
        s = bmap.segments[b]
        jt = spec.joint(s.name)
        jt.damping = [float(cfg.passive_damping * inertia[b]), 0.0, 0.0]
        jt.armature = float(armature * inertia[b])


def apply_gains(model: mujoco.MjModel, actuator_ids: np.ndarray, kp: np.ndarray, kv: np.ndarray,
                stiffness=1.0, damping=None) -> None:
    """Set the servo gains of some actuators in a compiled model (takes effect at the next step).

    Args:
        model: the model to edit in place.
        actuator_ids: ``(A,)`` MuJoCo actuator ids.
        kp, kv: ``(A,)`` default gains of those actuators.
        stiffness: multiplier of ``kp``, scalar or ``(A,)`` (0 = limp).
        damping: multiplier of ``kv``, scalar or ``(A,)``; ``None`` keeps the damping ratio
            (``sqrt(stiffness)``).

    Raises:
        ParameterError: negative or non-finite multipliers.
    """
    st = np.broadcast_to(np.asarray(stiffness, dtype=np.float64), np.shape(kp))
    if not np.all(np.isfinite(st)) or np.any(st < 0):
        raise ParameterError(f"stiffness multipliers must be non-negative numbers, got {stiffness!r}")
    dm = np.sqrt(st) if damping is None else np.broadcast_to(np.asarray(damping, dtype=np.float64), np.shape(kv))
    if not np.all(np.isfinite(dm)) or np.any(dm < 0):
        raise ParameterError(f"damping multipliers must be non-negative numbers, got {damping!r}")
    p = kp * st
    d = kv * dm
    model.actuator_gainprm[actuator_ids, 0] = p
    model.actuator_biasprm[actuator_ids, 1] = -p
    model.actuator_biasprm[actuator_ids, 2] = -d


def _box_corners(m, d, g) -> np.ndarray:
    r = d.geom_xmat[g].reshape(3, 3)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
    return d.geom_xpos[g] + (signs * m.geom_size[g]) @ r.T


def feedforward_targets(body, qpos: np.ndarray, ctrl: np.ndarray, qvel: np.ndarray | None = None,
                        dt: float | None = None, root_quat: np.ndarray | None = None,
                        contact_height: float = 0.02, lead_steps: np.ndarray | None = None) -> np.ndarray:
    """Servo targets ``(n, nu)`` with the feedforward torques folded in (``PDConfig.feedforward``).

    Args:
        body: the :class:`~kinodyn.physics.body.CharacterBody`.
        qpos: ``(n, nq)`` the character's target poses (its ``qpos`` block), standing on the floor z = 0.
        ctrl: ``(n, nu)`` the plain targets of those poses.
        qvel: ``(n, nv)`` the clip's velocities (``"dynamics"``); accelerations are their differences.
        dt: seconds between samples (``"dynamics"``).
        root_quat: ``(n, 4)`` root rotations of a fixed-root character (its root is not in ``qpos``).
        contact_height: a foot whose sole is lower than this (m) is on the floor.
        lead_steps: ``(nu,)`` samples by which each control's row is read ahead of time (the servo
            lookahead); the torque folded into row ``r`` is the one of sample ``r - lead``, so it acts
            when it is due.

    The feedforward ``tau`` is what the joints must apply for the body to follow the clip (``mj_rne``).

    ``"static"``: gravity, less the ground's vertical force ``J^T f`` under the feet on the floor (at
    their soles, ``f`` the body's weight split between two feet so that the split lies under the centre
    of mass). Ankles and toes get none (where the sole presses is not known).

    ``"dynamics"``: gravity and the clip's velocities and accelerations (forward differences: a step
    integrated from ``qvel[i]`` with ``qacc[i]`` lands on ``qvel[i + 1]``) and the damping of those
    velocities by the servos (``kv``) and the joints, less the ground's forces at the points where the
    pose touches the floor (MuJoCo's own contacts of the pose, as the simulation finds them): the forces
    within the friction cone that come as close as the cone allows to what the unactuated root needs,
    and among those the ones that leave the servos the least turn (:func:`_ground_forces`). Ankles get
    theirs (a foot on its toes carries the body through its ankle), up to :data:`_MAX_TURN`; toes none
    (their servos are too weak to carry the body; the ground is asked to carry it beside them).

    For a ball joint the target turns by ``exp(tau / kp)`` in the joint's frame, for a hinge by
    ``tau / kp``: near the target the servo then applies ``kp * error + tau``. A fixed-root character's
    feet carry nothing.
    """
    bm = body.map
    mode = body.pd.feedforward
    out = np.array(ctrl, dtype=np.float64, copy=True)
    n = len(out)
    if mode == "none" or n == 0 or len(bm.actuated) == 0:
        return out
    m = body.model()
    d = mujoco.MjData(m)
    if mode == "dynamics" and qvel is not None and dt is not None and n > 1:
        tau = _dynamics_torques(body, m, d, qpos, np.asarray(qvel, dtype=np.float64), dt, root_quat)
        _fold_torques(out, bm, body.kp, tau, lead_steps, skip=("toe",), max_turn=_MAX_TURN)
        return out
    tau, coms, supports = _static_torques(m, d, bm, qpos, root_quat, contact_height)
    _less_body_weight(m, d, qpos, tau, coms, supports)
    _fold_torques(out, bm, body.kp, tau, lead_steps)
    return out


def _sole_geoms(m: mujoco.MjModel, bm) -> dict:
    """Side -> ``(body id, geom)`` of the boxes of the foot and its toes (stand-alone model)."""
    soles = {}
    for side, fb in bm.feet.items():
        segs = [fb] + [b for b, s in enumerate(bm.segments) if s.cls == "toe" and s.side == side]
        soles[side] = [(b + 1, g) for b in segs for g in range(m.body_geomadr[b + 1],
                                                                m.body_geomadr[b + 1] + m.body_geomnum[b + 1])
                       if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX]
    return soles


def _static_torques(m, d, bm, qpos, root_quat, contact_height):
    """Gravity torques of each sample (``mj_rne``): ``tau (n, nv)``, the centres of mass ``(n, 3)`` and
    per sample the feet on the floor as ``(body id, sole point (3,))``."""
    n = len(qpos)
    free = bm.segments[0].kind == "free"
    soles = _sole_geoms(m, bm)
    tau = np.zeros((n, m.nv))
    coms = np.zeros((n, 3))
    supports = []
    for i in range(n):
        d.qpos[:] = qpos[i]
        if root_quat is not None and m.nmocap:
            d.mocap_quat[0] = root_quat[i]
        d.qvel[:] = 0.0
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        mujoco.mj_rne(m, d, 0, tau[i])
        coms[i] = d.subtree_com[1]
        support = []
        if free:
            for geoms in soles.values():
                if not geoms:
                    continue
                corners = np.concatenate([_box_corners(m, d, gg) for _, gg in geoms])
                low = corners[:, 2].min()
                if low < contact_height:
                    support.append((geoms[0][0], corners[corners[:, 2] < low + 0.01].mean(axis=0)))
        supports.append(support)
    return tau, coms, supports


def _less_body_weight(m, d, qpos, tau, coms, supports) -> None:
    """Subtract from ``tau (n, nv)`` the joint torques ``J^T f`` of the ground's vertical force ``f``
    (the body's weight) under the feet on the floor, split between two feet so the shares' centre lies
    under the centre of mass."""
    f = np.array([0.0, 0.0, max(-float(m.body_mass[1:].sum()) * float(m.opt.gravity[2]), 0.0)])
    jacp = np.zeros((3, m.nv))
    for i, support in enumerate(supports):
        if not support:
            continue
        # the recomputation of kinematics is needed for mj_jac at sample i
        d.qpos[:] = qpos[i]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        if len(support) == 2:  # split so the shares' centre lies under the centre of mass
            a2, b2 = support[0][1][:2], support[1][1][:2]
            ab = b2 - a2
            t = float(np.clip(np.dot(coms[i, :2] - a2, ab) / max(np.dot(ab, ab), 1e-12), 0.0, 1.0))
            share = np.array([1.0 - t, t])
        else:
            share = np.ones(len(support)) / len(support)
        for (bid, p), w in zip(support, share):
            mujoco.mj_jac(m, d, jacp, None, p, bid)
            tau[i] -= jacp.T @ (w * f)


def _dynamics_torques(body, m, d, qpos, qvel, dt: float, root_quat) -> np.ndarray:
    """``(n, nv)`` joint torques that make the body follow the clip (see :func:`feedforward_targets`,
    ``"dynamics"``)."""
    bm = body.map
    qacc = np.diff(qvel, axis=0, append=qvel[-1:]) / dt  # a step from qvel[i] lands on qvel[i + 1]
    qacc[-1] = qacc[-2]
    weight = np.zeros(m.nv)  # radians of servo turn per N m, and the servos' damping, at each dof
    kv = np.zeros(m.nv)
    for k, b in enumerate(bm.actuated):
        dofs = slice(bm.dof_adr[b], bm.dof_adr[b] + bm.dof_width[b])
        weight[dofs] = 1.0 / body.kp[k] if body.kp[k] > 0 else 0.0
        kv[dofs] = body.kv[k]
    free = bm.segments[0].kind == "free"
    tau = np.zeros((len(qpos), m.nv))
    for i in range(len(qpos)):
        d.qpos[:] = qpos[i]
        if root_quat is not None and m.nmocap:
            d.mocap_quat[0] = root_quat[i]
        d.qvel[:] = qvel[i]
        d.qacc[:] = qacc[i]
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        mujoco.mj_rne(m, d, 1, tau[i])
        if free:
            g = _contact_edges(m, d, body.config.friction)
            if len(g):
                tau[i] -= _ground_forces(g, tau[i], weight) @ g
    # the servos and the joints' damping resist the clip's own velocities, the armature its accelerations
    return tau + (kv + m.dof_damping) * qvel + m.dof_armature * qacc


def _contact_edges(m, d, mu: float) -> np.ndarray:
    """``(4 k, nv)`` generalized forces of a unit force along each edge of the friction cone (pyramid,
    ``mu``) at each of the ``k`` points where the posed body touches the ground (MuJoCo's collision of
    the stand-alone model, whose ground is on the world body)."""
    mujoco.mj_collision(m, d)
    jacp = np.zeros((3, m.nv))
    rows = []
    for con in d.contact[:d.ncon] if d.ncon else ():
        b1, b2 = int(m.geom_bodyid[con.geom1]), int(m.geom_bodyid[con.geom2])
        if con.dist > 0 or (b1 == 0) == (b2 == 0):
            continue  # not touching, or not between the ground and the body
        frame = con.frame.reshape(3, 3)
        normal = frame[0] if b1 == 0 else -frame[0]  # from the ground into the body
        mujoco.mj_jac(m, d, jacp, None, con.pos, b2 if b1 == 0 else b1)
        rows.append(np.array([normal + s * mu * frame[k] for k in (1, 2) for s in (1.0, -1.0)]) @ jacp)
    return np.concatenate(rows) if rows else np.zeros((0, m.nv))


def _ground_forces(g: np.ndarray, tau: np.ndarray, weight: np.ndarray, ridge: float = 1e-4) -> np.ndarray:
    """``(k,)`` non-negative magnitudes ``x`` along ``k`` friction-cone edges whose generalized forces are
    the rows of ``g (k, nv)``: the free root's need ``tau[:6]`` is met as closely as the cone allows
    (``x @ g[:, :6]``), and among the ways to meet it the one that leaves the joints the least turn of
    their servo targets (``weight (nv,)`` radians per N m) is chosen."""
    from scipy.optimize import nnls

    k = len(g)
    s = np.sqrt(ridge)
    a = np.concatenate([g[:, :6].T, s * (g[:, 6:] * weight[6:]).T, 1e-6 * np.eye(k)])
    b = np.concatenate([tau[:6], s * tau[6:] * weight[6:], np.zeros(k)])
    return nnls(a, b, maxiter=50 * k)[0]


def _fold_torques(out: np.ndarray, bm, kp: np.ndarray, tau: np.ndarray, lead_steps, skip=("foot", "toe"),
                  max_turn: float = np.inf) -> None:
    """Turn each servo target of ``out (n, nu)`` by its torque over its gain ``kp (A,)``, at most
    ``max_turn`` radians (the servos of segment classes ``skip`` excepted), reading ``tau (n, nv)``
    ``lead_steps (nu,)`` samples behind."""
    from kinodyn.math import quat

    n = len(out)
    rows = np.arange(n)
    for k, b in enumerate(bm.actuated):
        s = bm.segments[b]
        a, v = bm.ctrl_adr[b], bm.dof_adr[b]
        if kp[k] <= 0 or s.cls in skip:
            continue
        src = rows if lead_steps is None else np.clip(rows - int(lead_steps[a]), 0, n - 1)
        turn = tau[src, v:v + bm.dof_width[b]] / kp[k]
        norm = np.linalg.norm(turn, axis=1, keepdims=True)
        turn *= np.minimum(1.0, max_turn / np.maximum(norm, 1e-300))
        if s.kind == "ball":
            out[:, a:a + 4] = quat.mul(out[:, a:a + 4], quat.from_rotvec(turn))
        else:
            out[:, a] += turn[:, 0]
