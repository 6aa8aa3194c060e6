"""The character's single rigid body and the rigid body space R (section 4.1).

Mitake et al., "Physics-driven multi dimensional keyframe animation for artist-directable interactive
character", section 4.1 and figure 6. Each character is one rigid body: mass ``M``, centre of mass ``r``,
inertia tensor (the paper's ``10 I`` kg m^2) and a shape. The shape is an ellipsoid standing on its long
axis, thin front to back, wider side to side: the bottom is narrow (radius of curvature
``depth^2 / (height/2)``, a few centimetres) so the body tips forward and back more easily than
sideways, and the sides and top are convex so a fallen body rolls onto its flattest faces and lands
face up or face down, never on its side (lying on the side or standing on the head is an unstable
rest of an ellipsoid).

Between characters the contact shape is by default a capsule of the same height whose radius is the
geometric mean of the ellipsoid's depth and width (the same cross-section area;
:attr:`BodyConfig.contact_capsule`): MuJoCo solves capsule pairs in closed form, while each
ellipsoid pair takes an iterative convex search (GJK, then EPA for the depth): 0.7 of the 2.7 us
per character and step of 5,000 characters 1.1 m apart. The floor, the props and the balls always
touch the ellipsoid itself, so tipping, falling and landing are the ellipsoid's.

Conventions (kinodyn's, Z up): the body frame Sr has +X forward (the face), +Y left, +Z up along the
long axis; its origin is the centre of mass, so MuJoCo's free-joint ``qpos[:3]`` is ``r``. The paper's
frame Sc (``e_xc``, ``e_zc`` on the floor, ``e_yc`` up) is here the *heading frame*: ``forward`` (the
paper's ``e_zc``), ``left`` (``e_xc``) and world +Z (``e_yc``). The body rotation factors exactly as
``q = heading(theta_y) * tilt`` with the tilt's axis on the floor; with ``u`` the body's up axis in the
heading frame:

* ``theta_x = atan2(u . forward, u . up)`` in ``[-pi, pi]``: forward tilt (positive leaning forward,
  ``+pi/2`` lying face down, ``-pi/2`` face up);
* ``theta_z = asin(u . left)`` in ``[-pi/2, pi/2]``: sideways tilt (positive leaning left);
* ``theta_y``: the heading, the angle of ``forward`` about world +Z.

These are the ranges of equation 10. The rigid body space is ``R = {r, theta, dr/dt, dtheta/dt}``
(:class:`RigidState`). Units: metres, seconds, radians, kilograms.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from kinodyn.errors import ParameterError

__all__ = ["GRAVITY", "BodyConfig", "RigidState", "rigid_state", "rigid_state_fast", "support_height",
           "tilt_quat"]

GRAVITY = 9.81


@dataclass(frozen=True)
class BodyConfig:
    """The rigid body of one character (section 4.1, figure 6; defaults are the paper's).

    Attributes:
        height: standing height in metres (1.5); the ellipsoid's long axis.
        mass: kilograms (40).
        inertia: diagonal of the inertia tensor about the centre of mass, kg m^2 (the paper's 10 I).
        com_height: height of the centre of mass above the floor when upright, metres; also the
            pendulum length ``l`` of section 4.2. ``None``: 0.55 of the height (a person's).
        depth: front-to-back half thickness of the ellipsoid, metres (narrow bottom: tips forward).
        width: side-to-side half width of the ellipsoid, metres.
        friction: friction coefficient between feet and floor; bounds the controller's friction force
            ``|f_F| <= friction * M g`` (section 4.2).
        reach_front, reach_back, reach_side: how far the centre of pressure may move from the contact
            point (the legs' reach), metres: they bound the centre-of-pressure torque
            ``tau = (beta - alpha) f_N`` of section 4.2.
    """

    height: float = 1.5
    mass: float = 40.0
    inertia: float = 10.0
    com_height: float | None = None
    depth: float = 0.13
    width: float = 0.22
    friction: float = 0.8
    reach_front: float = 0.25
    reach_back: float = 0.18
    reach_side: float = 0.2

    def __post_init__(self):
        for name in ("height", "mass", "inertia", "depth", "width", "friction", "reach_front", "reach_back",
                     "reach_side"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ParameterError(f"BodyConfig.{name} must be a positive number, got {v!r}")
        if self.depth >= 0.5 * self.height or self.width >= 0.5 * self.height:
            raise ParameterError(f"BodyConfig depth and width must be under half the height "
                                 f"({0.5 * self.height}), got {self.depth} and {self.width}")
        if self.com_height is not None and not (0 < self.com_height < self.height):
            raise ParameterError(f"BodyConfig.com_height must lie in (0, height={self.height}), "
                                 f"got {self.com_height!r}")

    @property
    def l(self) -> float:
        """Pendulum length: centre-of-mass height when upright, metres."""
        return 0.55 * self.height if self.com_height is None else float(self.com_height)

    @property
    def semi_axes(self) -> np.ndarray:
        """Ellipsoid semi-axes ``(3,)`` along the body's X (front), Y (left), Z (up), metres."""
        return np.array([self.depth, self.width, 0.5 * self.height])

    @property
    def shape_offset(self) -> np.ndarray:
        """Ellipsoid centre in the body frame (relative to the centre of mass), ``(3,)`` metres."""
        return np.array([0.0, 0.0, 0.5 * self.height - self.l])

    @property
    def contact_capsule(self) -> tuple[float, float]:
        """``(radius, half_length)`` of the capsule that stands for the body in contacts with other
        characters (module docstring): radius ``sqrt(depth * width)``, end to end as tall as the body,
        centred on the ellipsoid, metres."""
        r = float(np.sqrt(self.depth * self.width))
        return r, max(0.0, 0.5 * self.height - r)

    @classmethod
    def from_skeleton(cls, skeleton, mass: float = 40.0, **kw) -> BodyConfig:
        """A body the size of ``skeleton`` (its rest height), keeping the paper's proportions.

        Args:
            skeleton: a :class:`~kinodyn.skeleton.Skeleton`; its ``height()`` sets the body height,
                the depth, width and reach scale with it, and the inertia scales with ``mass * h^2``.
            mass: kilograms.
        """
        h = float(skeleton.height())
        s = h / cls.height
        base = cls()
        return cls(height=h, mass=mass, inertia=base.inertia * (mass / base.mass) * s * s,
                   depth=base.depth * s, width=base.width * s, reach_front=base.reach_front * s,
                   reach_back=base.reach_back * s, reach_side=base.reach_side * s, **kw)


def support_height(cfg: BodyConfig, theta_x, theta_z=0.0) -> np.ndarray:
    """Height of the centre of mass of a body resting on the floor at tilt ``(theta_x, theta_z)``.

    The ellipsoid's support function in the direction of world up, plus the centre-of-mass offset.

    Args:
        theta_x: forward tilts ``(...)``, radians.
        theta_z: sideways tilts ``(...)``, radians.

    Returns:
        ``(...)`` metres.
    """
    q = tilt_quat(theta_x, theta_z)
    # world up in the body frame: rotate +Z by the inverse tilt.
    w, x, y, z = np.moveaxis(q, -1, 0)
    up = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1)
    a = cfg.semi_axes
    centre = np.sqrt(np.sum((a * up) ** 2, axis=-1))
    return centre - up @ cfg.shape_offset


def tilt_quat(theta_x, theta_z=0.0) -> np.ndarray:
    """The tilt rotation ``(..., 4)`` (w, x, y, z) whose up axis has forward tilt ``theta_x`` and side
    tilt ``theta_z`` (module docstring), with its axis on the floor.

    Args:
        theta_x: ``(...)`` radians in ``[-pi, pi]``.
        theta_z: ``(...)`` radians in ``[-pi/2, pi/2]``.
    """
    tx, tz = np.broadcast_arrays(np.asarray(theta_x, float), np.asarray(theta_z, float))
    u = np.stack([np.sin(tx) * np.cos(tz), np.sin(tz), np.cos(tx) * np.cos(tz)], axis=-1)
    # the shortest rotation from +Z to u: axis z x u = (-u_y, u_x, 0)
    w = np.sqrt(np.maximum(0.5 * (1.0 + u[..., 2]), 0.0))
    safe = np.where(w < 1e-9, 1.0, w)
    q = np.stack([w, -u[..., 1] / (2 * safe), u[..., 0] / (2 * safe), np.zeros_like(w)], axis=-1)
    flip = w < 1e-9  # upside down: a half turn about the left axis
    q[flip] = np.array([0.0, 0.0, 1.0, 0.0])
    return q


@dataclass(frozen=True)
class RigidState:
    """The rigid body space R of N characters (section 4.1), all in world coordinates.

    Attributes:
        r: ``(N, 3)`` centre of mass, metres.
        quat: ``(N, 4)`` body rotation (w, x, y, z).
        heading: ``(N,)`` theta_y, radians.
        theta_x: ``(N,)`` forward tilt, radians.
        theta_z: ``(N,)`` sideways tilt, radians.
        vel: ``(N, 3)`` centre-of-mass velocity, m/s.
        omega: ``(N, 3)`` angular velocity in world coordinates, rad/s.
        forward: ``(N, 3)`` the heading frame's forward axis (``e_zc``) on the floor.
        left: ``(N, 3)`` its left axis (``e_xc``).
        up: ``(N, 3)`` the body's up axis ``e_yr``.
    """

    r: np.ndarray
    quat: np.ndarray
    heading: np.ndarray
    theta_x: np.ndarray
    theta_z: np.ndarray
    vel: np.ndarray
    omega: np.ndarray
    forward: np.ndarray
    left: np.ndarray
    up: np.ndarray

    @property
    def v_forward(self) -> np.ndarray:
        """``(N,)`` velocity along ``forward`` (the paper's ``e_zc . dr/dt``)."""
        return np.einsum("ni,ni->n", self.vel, self.forward)

    @property
    def v_side(self) -> np.ndarray:
        """``(N,)`` velocity along ``left`` (the paper's ``e_xc . dr/dt``)."""
        return np.einsum("ni,ni->n", self.vel, self.left)

    @property
    def tilt_rate(self) -> tuple[np.ndarray, np.ndarray]:
        """``(d theta_x/dt, d theta_z/dt)``, each ``(N,)``: the angular velocity about ``left`` and about
        ``-forward`` (small-tilt rates of the two tilts)."""
        return (np.einsum("ni,ni->n", self.omega, self.left),
                -np.einsum("ni,ni->n", self.omega, self.forward))


def rigid_state(qpos: np.ndarray, qvel: np.ndarray) -> RigidState:
    """The rigid body space of N free bodies from MuJoCo's free-joint state.

    Args:
        qpos: ``(N, 7)`` position (the centre of mass) and rotation (w, x, y, z).
        qvel: ``(N, 6)`` linear velocity (world) and angular velocity (body frame, MuJoCo's convention).

    Returns:
        A :class:`RigidState`.
    """
    r = qpos[:, :3]
    q = qpos[:, 3:7]
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    # q = heading * tilt with the tilt's axis horizontal: heading = 2 atan2(qz, qw) exactly.
    heading = 2.0 * np.arctan2(z, w)
    ch, sh = np.cos(heading), np.sin(heading)
    zero = np.zeros_like(ch)
    forward = np.stack([ch, sh, zero], axis=1)
    left = np.stack([-sh, ch, zero], axis=1)
    up = np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)
    uf = np.einsum("ni,ni->n", up, forward)
    ul = np.einsum("ni,ni->n", up, left)
    theta_x = np.arctan2(uf, up[:, 2])
    theta_z = np.arcsin(np.clip(ul, -1.0, 1.0))
    wl = qvel[:, 3:6]
    # body-frame angular velocity to world: R(q) wl
    t = 2.0 * np.cross(q[:, 1:], wl)
    omega = wl + w[:, None] * t + np.cross(q[:, 1:], t)
    heading = np.where(heading > np.pi, heading - 2 * np.pi, heading)
    heading = np.where(heading <= -np.pi, heading + 2 * np.pi, heading)
    return RigidState(r=r.copy(), quat=q, heading=heading, theta_x=theta_x, theta_z=theta_z,
                      vel=qvel[:, :3].copy(), omega=omega, forward=forward, left=left, up=up)


@numba.njit(cache=True)
def _state_kernel(qpos, qvel, axes, offset, margin, quat, heading, theta_x, theta_z, omega, forward, left, up,
                  on_floor):
    """Compiled :func:`rigid_state` and the floor test of :func:`support_height`, one pass per body."""
    for i in range(qpos.shape[0]):
        nq = np.sqrt(qpos[i, 3] ** 2 + qpos[i, 4] ** 2 + qpos[i, 5] ** 2 + qpos[i, 6] ** 2)
        w, x, y, z = qpos[i, 3] / nq, qpos[i, 4] / nq, qpos[i, 5] / nq, qpos[i, 6] / nq
        quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3] = w, x, y, z
        h = 2.0 * np.arctan2(z, w)
        # cos and sin of the heading 2 atan2(z, w), without evaluating them
        ww, zz = w * w, z * z
        ch, sh = ((ww - zz) / (ww + zz), 2.0 * w * z / (ww + zz)) if ww + zz > 1e-300 else (1.0, 0.0)
        if h > np.pi:
            h -= 2 * np.pi
        elif h <= -np.pi:
            h += 2 * np.pi
        heading[i] = h
        forward[i, 0], forward[i, 1], forward[i, 2] = ch, sh, 0.0
        left[i, 0], left[i, 1], left[i, 2] = -sh, ch, 0.0
        ux, uy, uz = 2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)
        up[i, 0], up[i, 1], up[i, 2] = ux, uy, uz
        theta_x[i] = np.arctan2(ux * ch + uy * sh, uz)
        theta_z[i] = np.arcsin(min(1.0, max(-1.0, -ux * sh + uy * ch)))
        a0, a1, a2 = qvel[i, 3], qvel[i, 4], qvel[i, 5]
        t0, t1, t2 = 2 * (y * a2 - z * a1), 2 * (z * a0 - x * a2), 2 * (x * a1 - y * a0)
        omega[i, 0] = a0 + w * t0 + (y * t2 - z * t1)
        omega[i, 1] = a1 + w * t1 + (z * t0 - x * t2)
        omega[i, 2] = a2 + w * t2 + (x * t1 - y * t0)
        # world up in the body frame (the heading turns about it, so only the tilt matters)
        bx, by, bz = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        rest = (np.sqrt((axes[0] * bx) ** 2 + (axes[1] * by) ** 2 + (axes[2] * bz) ** 2)
                - (bx * offset[0] + by * offset[1] + bz * offset[2]))
        on_floor[i] = qpos[i, 2] < rest + margin


def rigid_state_fast(qpos: np.ndarray, qvel: np.ndarray, cfg: BodyConfig, margin: float
                     ) -> tuple[RigidState, np.ndarray]:
    """:func:`rigid_state` in one compiled pass, with the bodies that touch the floor.

    Args:
        qpos: ``(N, 7)`` and ``qvel`` ``(N, 6)``: MuJoCo's free-joint state (as :func:`rigid_state`).
        cfg: the bodies' configuration (their shape sets the resting height).
        margin: metres above its resting height (:func:`support_height`) under which a body touches
            the floor.

    Returns:
        ``(state, on_floor (N,) bool)``; the state's arrays are new (not views of ``qpos``, ``qvel``).
    """
    n = qpos.shape[0]
    quat, vec = np.empty((n, 4)), np.empty((5, n, 3))
    ang = np.empty((3, n))
    on_floor = np.empty(n, np.bool_)
    omega, forward, left, up = vec[0], vec[1], vec[2], vec[3]
    _state_kernel(qpos, qvel, cfg.semi_axes, cfg.shape_offset, float(margin), quat, ang[0], ang[1], ang[2],
                  omega, forward, left, up, on_floor)
    r, vel = vec[4], qvel[:, :3].copy()
    r[:] = qpos[:, :3]
    return RigidState(r=r, quat=quat, heading=ang[0], theta_x=ang[1], theta_z=ang[2], vel=vel, omega=omega,
                      forward=forward, left=left, up=up), on_floor
