"""Inverted-pendulum control of the single rigid body and the state machine of figure 3 (section 4.2).

Mitake et al., section 4.2. The body is treated as an inverted pendulum (point mass ``M`` on a massless
rod of length ``l``) standing on the floor. A person balances by moving the floor reaction force: the
controller applies a friction force ``f_F`` at the foot (bounded by ``fFmax = friction * f_N``: the
friction cone and the legs' strength) and a torque ``tau = (beta - alpha) f_N`` from moving the centre
of pressure ``beta`` away from the contact point ``alpha`` within the legs' reach (``taumin..taumax``).
In each vertical plane (forward: tilt ``theta_x`` and velocity along ``forward``; sideways:
``theta_z`` and the velocity along ``left``), with ``theta`` the lean toward the plane's axis:

    M  d2r/dt2     = f_F                                   (equations 1 and 4)
    I  d2theta/dt2 = M g l theta - l f_F + tau             (equation 5, linearized; signs for kinodyn's
                                                            axes: a forward push at the foot tilts back)

A state feedback (LQR on this linear model) drives ``(theta, dtheta/dt, dr/dt)`` toward the target
``(0, 0, v0)`` the behaviour asks for; the heading follows a PD law on the yaw torque. When the tilt
passes ``fall_angle`` the body falls: the feet hold (a friction force against the foot's velocity), then
PD control of ``f_F`` and ``tau`` brakes it on the floor, it lies still, and stands up by driving its
tilt back to zero along a smooth ramp. States (figure 3): :data:`BALANCE` (balancing and walking),
:data:`FALLING`, :data:`BRAKING`, :data:`LYING`, :data:`STANDING_UP`.

Everything is vectorized over the N characters: arrays are ``(N,)`` or ``(N, 3)``; forces are world
vectors in newtons applied at the centre of mass, torques in newton metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numba
import numpy as np

from kinodyn.crowd.body import GRAVITY, BodyConfig, RigidState
from kinodyn.errors import ParameterError

__all__ = [
    "BALANCE",
    "BRAKING",
    "FALLING",
    "LYING",
    "STANDING_UP",
    "STATE_NAMES",
    "ControlState",
    "ControllerConfig",
    "control",
    "control_kernel",
    "lqr_gains",
    "new_control_state",
    "pack_config",
]

BALANCE, FALLING, BRAKING, LYING, STANDING_UP = 0, 1, 2, 3, 4
STATE_NAMES = ("balance", "falling", "braking", "lying", "standing_up")


@dataclass(frozen=True)
class ControllerConfig:
    """Gains, limits and thresholds of the controller and its state machine.

    Attributes:
        q_tilt, q_rate, q_vel: LQR state weights on tilt (1/rad^2), tilt rate and velocity errors.
        r_force, r_torque: LQR input weights on the friction force (1/N^2) and torque (1/(N m)^2).
        yaw_halflife: seconds for the heading to close half its error (PD on the yaw torque).
        yaw_torque: largest yaw torque the feet give, N m.
        fall_angle: tilt (rad, from vertical) beyond which balancing gives up: state FALLING.
        landed_angle: tilt (rad) at which a falling body is on the floor: state BRAKING.
        foot_hold: N s/m, the feet's hold against sliding while falling (bounded by the friction).
        brake_force: N s/m of the braking PD on the centre-of-mass velocity.
        brake_torque: N m s of the braking PD on the angular velocity.
        rest_speed: m/s (and rad/s for turning) below which a braked body lies still: state LYING.
        lie_time: seconds lying still before standing up.
        stand_time: seconds of the stand-up ramp from lying to upright.
        stand_strength: the torque available while standing up, as a multiple of ``M g l`` (the whole
            body pushes on the floor, so the centre of pressure reaches further than on the feet).
        stand_halflife: seconds for the PD servo on the tilt while standing up.
        upright_angle: tilt (rad) below which a standing body balances again.
        max_side_lying: sideways tilt (rad) under which a lying body is face up or down and stands up.
        roll_torque: N m, the largest torque about the body's long axis with which a falling or lying
            body turns its front or back to the floor (a person twists to land on the hands or the
            back, never on the side; with the convex sides of the shape this makes it land face up
            or face down).
        roll_damping: N m s of damping on that roll.
    """

    q_tilt: float = 400.0
    q_rate: float = 20.0
    q_vel: float = 40.0
    r_force: float = 1e-3
    r_torque: float = 2e-3
    yaw_halflife: float = 0.25
    yaw_torque: float = 60.0
    fall_angle: float = 0.55
    landed_angle: float = 1.2
    foot_hold: float = 600.0
    brake_force: float = 300.0
    brake_torque: float = 120.0
    rest_speed: float = 0.08
    lie_time: float = 1.2
    stand_time: float = 1.8
    stand_strength: float = 1.6
    stand_halflife: float = 0.12
    upright_angle: float = 0.12
    max_side_lying: float = 0.6
    roll_torque: float = 150.0
    roll_damping: float = 40.0

    def __post_init__(self):
        for k, v in self.__dict__.items():
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ParameterError(f"ControllerConfig.{k} must be a positive number, got {v!r}")
        if not self.upright_angle < self.fall_angle < self.landed_angle < np.pi / 2:
            raise ParameterError("ControllerConfig angles must satisfy upright_angle < fall_angle < "
                                 f"landed_angle < pi/2, got {self.upright_angle}, {self.fall_angle}, "
                                 f"{self.landed_angle}")


@lru_cache(maxsize=32)
def lqr_gains(body: BodyConfig, cfg: ControllerConfig) -> np.ndarray:
    """State-feedback gains ``K (2, 3)`` of the linearized pendulum (equations 4 and 5).

    The state is ``(theta, dtheta/dt, v)``, the input ``(f_F, tau)``; ``u = -K (x - x0)``.
    """
    from scipy.linalg import solve_continuous_are

    m, l, i = body.mass, body.l, body.inertia
    a = np.array([[0.0, 1.0, 0.0], [m * GRAVITY * l / i, 0.0, 0.0], [0.0, 0.0, 0.0]])
    b = np.array([[0.0, 0.0], [-l / i, 1.0 / i], [1.0 / m, 0.0]])
    q = np.diag([cfg.q_tilt, cfg.q_rate, cfg.q_vel])
    r = np.diag([cfg.r_force, cfg.r_torque])
    p = solve_continuous_are(a, b, q, r)
    k = np.linalg.solve(r, b.T @ p)
    k.setflags(write=False)
    return k


@dataclass
class ControlState:
    """The mutable state of the N controllers (the simulator's, changed by :func:`control`).

    Attributes:
        mode: ``(N,)`` int state of figure 3.
        timer: ``(N,)`` seconds spent in the current state.
        stand_from: ``(N,)`` forward tilt at which standing up began, radians.
    """

    mode: np.ndarray
    timer: np.ndarray
    stand_from: np.ndarray


def new_control_state(n: int) -> ControlState:
    """N controllers balancing."""
    return ControlState(mode=np.zeros(n, np.int64), timer=np.zeros(n), stand_from=np.zeros(n))


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _transitions(s: RigidState, cs: ControlState, body: BodyConfig, cfg: ControllerConfig, dt: float,
                 on_floor: np.ndarray) -> None:
    """Advance the state machine of figure 3 in place."""
    tilt = np.arccos(np.clip(s.up[:, 2], -1.0, 1.0))
    speed = np.linalg.norm(s.vel[:, :2], axis=1)
    spin = np.linalg.norm(s.omega, axis=1)
    m = cs.mode
    new = m.copy()
    new[(m == BALANCE) & (tilt > cfg.fall_angle)] = FALLING
    new[(m == FALLING) & (tilt > cfg.landed_angle) & on_floor] = BRAKING
    w, x, y, z = s.quat.T
    on_side = np.abs(2 * (y * z + w * x)) > np.sin(cfg.max_side_lying)
    new[(m == BRAKING) & (speed < cfg.rest_speed) & (spin < 2 * cfg.rest_speed) & ~on_side] = LYING
    moving = (speed > 3 * cfg.rest_speed) | (spin > 6 * cfg.rest_speed)
    new[(m == LYING) & moving] = BRAKING
    getup = (m == LYING) & (cs.timer > cfg.lie_time) & (np.abs(s.theta_z) < cfg.max_side_lying)
    new[getup] = STANDING_UP
    cs.stand_from[getup] = s.theta_x[getup]
    done = (m == STANDING_UP) & (cs.timer > cfg.stand_time) & (tilt < cfg.upright_angle)
    new[done] = BALANCE
    # a standing body that is knocked far over again falls again
    new[(m == STANDING_UP) & (cs.timer > 0.3) & (np.abs(s.theta_x) > np.abs(cs.stand_from) + 0.3)] = FALLING
    changed = new != m
    cs.timer[changed] = 0.0
    cs.timer[~changed] += dt
    cs.mode[:] = new


def control(s: RigidState, cs: ControlState, v_target: np.ndarray, heading_target: np.ndarray,
            body: BodyConfig, cfg: ControllerConfig, dt: float, on_floor: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
    """One control step for N characters: advance the state machine, return the forces to apply.

    Args:
        s: the rigid body space of the N bodies.
        cs: controller states, updated in place.
        v_target: ``(N, 2)`` target horizontal velocity (world x, y), m/s.
        heading_target: ``(N,)`` target heading, radians.
        body, cfg: the body and the controller's configuration.
        dt: seconds since the last call.
        on_floor: ``(N,)`` bool, the body touches the floor (None: every body does).

    Returns:
        ``(force (N, 3), torque (N, 3))`` in world coordinates, to apply at the centre of mass
        (the friction force acts at the foot, so its moment about the centre is included).
    """
    n = s.r.shape[0]
    on_floor = np.ones(n, bool) if on_floor is None else on_floor
    _transitions(s, cs, body, cfg, dt, on_floor)
    fn = body.mass * GRAVITY * on_floor
    f_fwd, f_side, tau_x, tau_z = _balance(s, v_target, body, cfg, fn)
    mode = cs.mode
    rate_x, rate_z = s.tilt_rate
    foot = s.vel - np.cross(s.omega, body.l * s.up)  # velocity of the rod's foot r - l u
    hold = mode == FALLING
    brake = (mode == BRAKING) | (mode == LYING)
    stand = mode == STANDING_UP
    v_fwd_foot = np.einsum("ni,ni->n", foot, s.forward)
    v_side_foot = np.einsum("ni,ni->n", foot, s.left)
    f_fwd = np.where(hold | stand, -cfg.foot_hold * v_fwd_foot, f_fwd)
    f_side = np.where(hold | stand, -cfg.foot_hold * v_side_foot, f_side)
    f_fwd = np.where(brake, -cfg.brake_force * s.v_forward, f_fwd)
    f_side = np.where(brake, -cfg.brake_force * s.v_side, f_side)
    tau_x = np.where(hold, 0.0, tau_x)
    tau_z = np.where(hold, 0.0, tau_z)
    tau_x = np.where(brake, 0.0, tau_x)
    tau_z = np.where(brake, 0.0, tau_z)
    sx, sz = _stand_torques(s, cs, body, cfg, rate_x, rate_z)
    tau_x = np.where(stand, sx, tau_x)
    tau_z = np.where(stand, sz, tau_z)
    # friction cone: |f_F| <= friction * f_N
    fmag = np.hypot(f_fwd, f_side)
    scale = np.minimum(1.0, body.friction * fn / np.maximum(fmag, 1e-9))
    f_fwd, f_side = f_fwd * scale, f_side * scale
    fh = f_fwd[:, None] * s.forward + f_side[:, None] * s.left
    # torques about the plane axes: n_x = up x forward = left, n_z = up x left = -forward
    tau = tau_x[:, None] * s.left - tau_z[:, None] * s.forward
    yaw = _yaw_torque(s, heading_target, body, cfg, mode)
    tau[:, 2] += yaw * on_floor
    lever = -body.l * s.up
    tau += np.cross(lever, fh)
    tau[brake] -= cfg.brake_torque * s.omega[brake]
    down = hold | brake
    tau[down] += _roll_torque(s, cfg)[down]
    return fh, tau


def _roll_torque(s: RigidState, cfg: ControllerConfig) -> np.ndarray:
    """``(N, 3)`` torque about the long axis that turns the body's side (its Y axis) off the floor."""
    w, x, y, z = s.quat.T
    side_up = 2 * (y * z + w * x)  # body Y . world Z
    front_up = 2 * (x * z - w * y)  # body X . world Z
    sign = np.where(front_up >= 0.0, 1.0, -1.0)
    spin = np.einsum("ni,ni->n", s.omega, s.up)
    t = np.clip(cfg.roll_torque * 4.0 * sign * side_up, -cfg.roll_torque, cfg.roll_torque)
    return (t - cfg.roll_damping * spin)[:, None] * s.up


def _balance(s: RigidState, v_target, body: BodyConfig, cfg: ControllerConfig, fn):
    """LQR friction force and centre-of-pressure torque in both planes, bounded (section 4.2)."""
    k = lqr_gains(body, cfg)
    rate_x, rate_z = s.tilt_rate
    v_fwd0 = np.einsum("ni,ni->n", v_target, s.forward[:, :2])
    v_side0 = np.einsum("ni,ni->n", v_target, s.left[:, :2])
    ex = np.stack([s.theta_x, rate_x, s.v_forward - v_fwd0], axis=1)
    ez = np.stack([s.theta_z, rate_z, s.v_side - v_side0], axis=1)
    ux = -ex @ k.T
    uz = -ez @ k.T
    # tau = (beta - alpha) f_N: a centre of pressure ahead of the contact tilts the body back.
    tau_x = np.clip(ux[:, 1], -body.reach_front * fn, body.reach_back * fn)
    tau_z = np.clip(uz[:, 1], -body.reach_side * fn, body.reach_side * fn)
    return ux[:, 0], uz[:, 0], tau_x, tau_z


def _stand_torques(s: RigidState, cs: ControlState, body: BodyConfig, cfg: ControllerConfig, rate_x, rate_z):
    """PD servo of the tilt along a smooth ramp from lying to upright, with gravity compensation."""
    ramp = np.clip(cs.timer / cfg.stand_time, 0.0, 1.0)
    ramp = 0.5 - 0.5 * np.cos(np.pi * ramp)
    target = cs.stand_from * (1.0 - ramp)
    w = np.log(2.0) / cfg.stand_halflife
    kp, kd = body.inertia * w * w, 2.0 * body.inertia * w
    mgl = body.mass * GRAVITY * body.l
    limit = cfg.stand_strength * mgl
    tx = kp * (target - s.theta_x) - kd * rate_x - mgl * np.sin(s.theta_x)
    tz = -kp * s.theta_z - kd * rate_z - mgl * np.sin(s.theta_z)
    return np.clip(tx, -limit, limit), np.clip(tz, -limit, limit)


def _yaw_torque(s: RigidState, heading_target, body: BodyConfig, cfg: ControllerConfig, mode):
    w = np.log(2.0) / cfg.yaw_halflife
    kp, kd = body.inertia * w * w, 2.0 * body.inertia * w
    err = _wrap(heading_target - s.heading)
    turning = mode == BALANCE
    tau = np.where(turning, kp * err, 0.0) - kd * s.omega[:, 2]
    return np.clip(tau, -cfg.yaw_torque, cfg.yaw_torque)



# --------------------------------------------------------------------------- compiled path
# The same control law and state machine as :func:`control`, one compiled pass per character (the
# crowd's hot path; ``tests/test_crowd_controller.py`` checks it against the numpy code above).


def pack_config(body: BodyConfig, cfg: ControllerConfig) -> np.ndarray:
    """The parameters the compiled controller reads, as one float array."""
    k = lqr_gains(body, cfg)
    return np.array([body.mass, body.l, body.inertia, body.friction, body.reach_front, body.reach_back,
                     body.reach_side, cfg.fall_angle, cfg.landed_angle, cfg.foot_hold, cfg.brake_force,
                     cfg.brake_torque, cfg.rest_speed, cfg.lie_time, cfg.stand_time, cfg.stand_strength,
                     np.log(2.0) / cfg.stand_halflife, cfg.upright_angle, cfg.max_side_lying, cfg.roll_torque,
                     cfg.roll_damping, np.log(2.0) / cfg.yaw_halflife, cfg.yaw_torque, *k.ravel()])


@numba.njit(cache=True)
def _next_mode(m, timer, tilt, speed, spin, on_floor, side_up, tx, tz, sf, p):
    fall, landed, rest, lie, stand_t, upright, side_max = p[7], p[8], p[12], p[13], p[14], p[17], p[18]
    new = m
    if m == BALANCE and tilt > fall:
        new = FALLING
    elif m == FALLING and tilt > landed and on_floor:
        new = BRAKING
    elif m == BRAKING and speed < rest and spin < 2 * rest and abs(side_up) <= np.sin(side_max):
        new = LYING
    elif m == LYING:
        if speed > 3 * rest or spin > 6 * rest:
            new = BRAKING
        if timer > lie and abs(tz) < side_max:
            new = STANDING_UP
            sf = tx
    elif m == STANDING_UP:
        if timer > stand_t and tilt < upright:
            new = BALANCE
        if timer > 0.3 and abs(tx) > abs(sf) + 0.3:
            new = FALLING
    return new, sf


# long kernel: the whole control law per character in one pass, so the crowd has no per-step numpy
@numba.njit(cache=True, parallel=True)
def control_kernel(qpos, qvel, on_floor, v_target, heading_target, mode, timer, stand_from, p, dt, out):
    """Compiled :func:`control` on MuJoCo's free-joint state: ``qpos (N, 7)``, ``qvel (N, 6)``,
    ``on_floor (N,)``, ``v_target (N, 2)``, ``heading_target (N,)``; updates ``mode``, ``timer``,
    ``stand_from`` in place and writes ``out (N, 6)`` (force, torque at the centre of mass, world)."""
    m_, l, inertia, mu, r_front, r_back, r_side = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    g = 9.81
    for i in numba.prange(qpos.shape[0]):
        nq = np.sqrt(qpos[i, 3] ** 2 + qpos[i, 4] ** 2 + qpos[i, 5] ** 2 + qpos[i, 6] ** 2)
        w, x, y, z = qpos[i, 3] / nq, qpos[i, 4] / nq, qpos[i, 5] / nq, qpos[i, 6] / nq
        h = 2.0 * np.arctan2(z, w)
        ww, zz = w * w, z * z  # cos and sin of h without evaluating them
        ch, sh = ((ww - zz) / (ww + zz), 2.0 * w * z / (ww + zz)) if ww + zz > 1e-300 else (1.0, 0.0)
        ux, uy, uz = 2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)
        uf, ul = ux * ch + uy * sh, -ux * sh + uy * ch
        tx, tz = np.arctan2(uf, uz), np.arcsin(min(1.0, max(-1.0, ul)))
        a0, a1, a2 = qvel[i, 3], qvel[i, 4], qvel[i, 5]
        t0, t1, t2 = 2 * (y * a2 - z * a1), 2 * (z * a0 - x * a2), 2 * (x * a1 - y * a0)
        ox, oy, oz = a0 + w * t0 + (y * t2 - z * t1), a1 + w * t1 + (z * t0 - x * t2), a2 + w * t2 + (x * t1 - y * t0)
        vx, vy = qvel[i, 0], qvel[i, 1]
        vf, vs = vx * ch + vy * sh, -vx * sh + vy * ch
        rate_x, rate_z = -ox * sh + oy * ch, -(ox * ch + oy * sh)
        tilt = np.arccos(min(1.0, max(-1.0, uz)))
        speed, spin = np.sqrt(vx * vx + vy * vy), np.sqrt(ox * ox + oy * oy + oz * oz)
        side_up = 2 * (y * z + w * x)
        old = mode[i]
        new, stand_from[i] = _next_mode(old, timer[i], tilt, speed, spin, on_floor[i], side_up, tx, tz,
                                        stand_from[i], p)
        if new != old:
            timer[i] = 0.0
        else:
            timer[i] += dt
        mode[i] = new
        fn = m_ * g if on_floor[i] else 0.0
        # balance (LQR on both planes), bounded centre-of-pressure torque
        v0f = v_target[i, 0] * ch + v_target[i, 1] * sh
        v0s = -v_target[i, 0] * sh + v_target[i, 1] * ch
        ff = -(p[23] * tx + p[24] * rate_x + p[25] * (vf - v0f))
        fs = -(p[23] * tz + p[24] * rate_z + p[25] * (vs - v0s))
        tqx = min(max(-(p[26] * tx + p[27] * rate_x + p[28] * (vf - v0f)), -r_front * fn), r_back * fn)
        tqz = min(max(-(p[26] * tz + p[27] * rate_z + p[28] * (vs - v0s)), -r_side * fn), r_side * fn)
        # foot velocity: v - omega x (l u)
        fvx = vx - l * (oy * uz - oz * uy)
        fvy = vy - l * (oz * ux - ox * uz)
        hold, brake, stand = new == FALLING, new == BRAKING or new == LYING, new == STANDING_UP
        if hold or stand:
            ff, fs = -p[9] * (fvx * ch + fvy * sh), -p[9] * (-fvx * sh + fvy * ch)
        if brake:
            ff, fs = -p[10] * vf, -p[10] * vs
        if hold or brake:
            tqx, tqz = 0.0, 0.0
        if stand:
            ramp = min(max(timer[i] / p[14], 0.0), 1.0)
            target = stand_from[i] * (0.5 + 0.5 * np.cos(np.pi * ramp))
            wn = p[16]
            kp, kd = inertia * wn * wn, 2.0 * inertia * wn
            mgl = m_ * g * l
            lim = p[15] * mgl
            tqx = min(max(kp * (target - tx) - kd * rate_x - mgl * np.sin(tx), -lim), lim)
            tqz = min(max(-kp * tz - kd * rate_z - mgl * np.sin(tz), -lim), lim)
        fmag = np.sqrt(ff * ff + fs * fs)
        sc = min(1.0, mu * fn / max(fmag, 1e-9))
        ff, fs = ff * sc, fs * sc
        fx, fy = ff * ch - fs * sh, ff * sh + fs * ch
        # torques: tau_x about left (-sh, ch, 0), tau_z about -forward
        tax = tqx * (-sh) - tqz * ch
        tay = tqx * ch - tqz * sh
        taz = 0.0
        # yaw
        wy = p[21]
        kpy, kdy = inertia * wy * wy, 2.0 * inertia * wy
        err = (heading_target[i] - h + np.pi) % (2 * np.pi) - np.pi
        yaw = (kpy * err if new == BALANCE else 0.0) - kdy * oz
        yaw = min(max(yaw, -p[22]), p[22])
        if on_floor[i]:
            taz += yaw
        # moment of the foot force: (-l u) x (fx, fy, 0)
        tax += -l * (uy * 0.0 - uz * fy)
        tay += -l * (uz * fx - ux * 0.0)
        taz += -l * (ux * fy - uy * fx)
        if brake:
            tax -= p[11] * ox
            tay -= p[11] * oy
            taz -= p[11] * oz
        if hold or brake:
            front_up = 2 * (x * z - w * y)
            sign = 1.0 if front_up >= 0.0 else -1.0
            rt = min(max(p[19] * 4.0 * sign * side_up, -p[19]), p[19]) - p[20] * (ox * ux + oy * uy + oz * uz)
            tax += rt * ux
            tay += rt * uy
            taz += rt * uz
        out[i, 0], out[i, 1], out[i, 2] = fx, fy, 0.0
        out[i, 3], out[i, 4], out[i, 5] = tax, tay, taz
