"""Cyclic coordinate descent inverse kinematics with hinge limits and reach cones (equations 4 and 5).

Schmidl and Lin, "Geometric and kinematic overlap avoidance", after Wang and Chen (1991): to bring an
end effector ``ee`` on link ``i`` of a chain to a goal, each joint ``h`` from link ``i`` inwards to the
chain's root turns about its axis ``a_h`` (origin ``o_h``) by the angle between the projections of
``ee`` and the goal onto the joint's plane,

    p' = p - (a_h . (p - o_h)) a_h                                           (4)
    phi_h = acos(ee' . goal')     (signed by a_h . (ee' x goal'))             (5)

A hinge (elbow, knee) has one axis and a range; a ball joint is three planar joints with a common
centre (the parent frame's axes) whose result is projected back into its reach cone
(:mod:`kinodyn.ik.cones`). Sweeps repeat until ``|ee - goal|`` is within the tolerance. The
special case of a link lying along the surface moves the link's origin instead and keeps the link's
world orientation ("reconnect limb i-1").

:func:`ccd_solve` is the public, self-contained solver (arrays in, :class:`IKResult` out); the avatar
loop that finds the links, end effectors and goals is :mod:`kinodyn.contact.resolve`; scene
generation reuses the solver on its own chains.
Shapes: ``n`` chain joints, ``K`` cone vertices; metres, radians, rotations ``(w, x, y, z)``.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numba
import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.ik.cones import KIND_BALL, KIND_FIXED, KIND_HINGE, cone_contains, project_joint
from kinodyn.kinematics import fk_link
from kinodyn.math.array_kernels import qaxis, qmul, qrot

__all__ = [
    "CCDConfig",
    "ChainLimits",
    "IKResult",
    "Status",
    "ccd_solve",
    "chain_fk",
    "chain_limits",
    "limits_hold",
    "project_chain",
    "warm_up",
]


class Status(enum.Enum):
    """Why :func:`ccd_solve` stopped."""

    CONVERGED = "converged"
    MAX_SWEEPS = "max_sweeps"


@dataclass(frozen=True)
class CCDConfig:
    """CCD settings.

    Attributes:
        tolerance: end-effector distance to the goal that counts as reached (m).
        max_sweeps: sweeps from the link to the chain root per solve.
    """

    tolerance: float = 1e-4
    max_sweeps: int = 10

    def __post_init__(self):
        if not (self.tolerance > 0 and self.max_sweeps >= 1):
            raise ParameterError(f"tolerance must be > 0 and max_sweeps >= 1, got {self.tolerance}, {self.max_sweeps}")


@dataclass(frozen=True)
class ChainLimits:
    """Joint limits of one chain, as arrays for the compiled solver.

    Attributes:
        kind: ``(n,)`` 0 ball (reach cone), 1 hinge, 2 nearly fixed.
        axis: ``(n, 3)`` hinge axes (local frames).
        lower, upper: ``(n,)`` hinge ranges (rad).
        max_angle: ``(n,)`` bound of the total rotation of ball and fixed joints (rad).
        axes: ``(n, 4, 3)`` reach-cone rest direction, centre and chart axes; poly: ``(n, K, 2)`` cone
            polygons (:func:`kinodyn.ik.cones.reach_cones`).
    """

    kind: np.ndarray
    axis: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    max_angle: np.ndarray
    axes: np.ndarray
    poly: np.ndarray


@dataclass(frozen=True)
class IKResult:
    """Result of :func:`ccd_solve`.

    Attributes:
        local_rot: ``(n, 4)`` solved local rotations of the chain.
        status: why it stopped; sweeps: sweeps used; error: final ``|ee - goal|`` (m).
    """

    local_rot: np.ndarray
    status: Status
    sweeps: int
    error: float


def chain_limits(limits, cone_axes, cone_points, joints) -> ChainLimits:
    """:class:`ChainLimits` of ``joints (n,)`` from :func:`kinodyn.limits.limits_for` rows and an
    avatar's cones (``cone_axes (J, 4, 3)``, ``cone_points (J, K, 2)``)."""
    joints = np.asarray(joints, dtype=np.int64)
    rows = [limits[j] for j in joints]
    kind = np.array([KIND_HINGE if r.kind == "hinge" else KIND_FIXED if r.kind == "fixed" else KIND_BALL
                     for r in rows], dtype=np.int64)
    return ChainLimits(kind, np.array([r.axis for r in rows], float), np.array([r.lower for r in rows], float),
                       np.array([r.upper for r in rows], float), np.array([r.max_angle for r in rows], float),
                       np.ascontiguousarray(cone_axes[joints]), np.ascontiguousarray(cone_points[joints]))


@numba.njit(cache=True)
def _fk(base_rot, base_pos, offsets, q, gr, gp):  # pragma: no cover - compiled
    """Chain FK in place: ``gr (n + 1, 4)``, ``gp (n + 1, 3)`` with row 0 the base, row k + 1 joint k."""
    gr[0] = base_rot
    gp[0] = base_pos
    for k in range(q.shape[0]):
        fk_link(gr, gp, k, k + 1, q[k], offsets[k])


@numba.njit(cache=True)
def _turn(u, v, a):  # pragma: no cover - compiled
    """Equations 4-5: signed angle about ``a`` taking ``u`` to ``v`` after projection on the plane."""
    pu = u - (a[0] * u[0] + a[1] * u[1] + a[2] * u[2]) * a
    pv = v - (a[0] * v[0] + a[1] * v[1] + a[2] * v[2]) * a
    nu = np.sqrt(pu[0] ** 2 + pu[1] ** 2 + pu[2] ** 2)
    nv = np.sqrt(pv[0] ** 2 + pv[1] ** 2 + pv[2] ** 2)
    if nu < 1e-9 or nv < 1e-9:
        return 0.0
    c = (pu[0] * pv[0] + pu[1] * pv[1] + pu[2] * pv[2]) / (nu * nv)
    s = (a[0] * (pu[1] * pv[2] - pu[2] * pv[1]) + a[1] * (pu[2] * pv[0] - pu[0] * pv[2])
         + a[2] * (pu[0] * pv[1] - pu[1] * pv[0])) / (nu * nv)
    return np.arctan2(s, c)


# long kernel: the CCD sweep loop (joints from the link inwards, axes per joint, limits after each turn)
@numba.njit(cache=True)
def _ccd_kernel(base_rot, base_pos, offsets, q, link, top, ee_local, goal, kind, axis, lower, upper,
                max_angle, axes, poly, tol, max_sweeps):  # pragma: no cover - compiled
    n = q.shape[0]
    gr = np.empty((n + 1, 4))
    gp = np.empty((n + 1, 3))
    eye = np.eye(3)
    err = 0.0
    for sweep in range(max_sweeps):
        _fk(base_rot, base_pos, offsets, q, gr, gp)
        ee = gp[link + 1] + qrot(gr[link + 1], ee_local)
        err = np.sqrt(((ee - goal) ** 2).sum())
        if err < tol:
            return sweep, err
        for h in range(top, -1, -1):
            if kind[h] == KIND_FIXED:
                continue
            naxes = 1 if kind[h] == KIND_HINGE else 3
            for k in range(naxes):
                a_local = axis[h] if kind[h] == KIND_HINGE else eye[k]
                a = qrot(gr[h], a_local)  # row h is the parent of joint h
                ee = gp[link + 1] + qrot(gr[link + 1], ee_local)
                phi = _turn(ee - gp[h + 1], goal - gp[h + 1], a)
                if phi == 0.0:
                    continue
                q[h] = project_joint(qmul(qaxis(a_local, phi), q[h]), kind[h], axis[h], lower[h], upper[h],
                                     max_angle[h], axes[h], poly[h])
                _fk(base_rot, base_pos, offsets, q, gr, gp)
    _fk(base_rot, base_pos, offsets, q, gr, gp)
    ee = gp[link + 1] + qrot(gr[link + 1], ee_local)
    return max_sweeps, np.sqrt(((ee - goal) ** 2).sum())


@numba.njit(cache=True)
def _project_all(q, kind, axis, lower, upper, max_angle, axes, poly):  # pragma: no cover - compiled
    for h in range(q.shape[0]):
        q[h] = project_joint(q[h], kind[h], axis[h], lower[h], upper[h], max_angle[h], axes[h], poly[h])


def chain_fk(base_rot, base_pos, offsets, local_rot) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations ``(n, 4)`` and positions ``(n, 3)`` of a chain's joints from the frame of its
    root's parent (``base_rot (4,)``, ``base_pos (3,)``), ``offsets (n, 3)``, ``local_rot (n, 4)``."""
    q = np.ascontiguousarray(local_rot, dtype=np.float64)
    gr, gp = np.empty((len(q) + 1, 4)), np.empty((len(q) + 1, 3))
    _fk(np.asarray(base_rot, float), np.asarray(base_pos, float), np.asarray(offsets, float), q, gr, gp)
    return gr[1:], gp[1:]


def ccd_solve(base_rot, base_pos, offsets, local_rot, link: int, ee_local, goal, limits: ChainLimits,
              config: CCDConfig | None = None, top: int | None = None) -> IKResult:
    """Turn the joints ``top, top - 1, ..., 0`` of a chain (default ``top = link``) so that the point
    ``ee_local (3,)`` of link ``link`` (in its joint's frame) reaches ``goal (3,)``, within the limits.

    Args:
        base_rot, base_pos: ``(4,)``, ``(3,)`` world frame of the chain root's parent joint.
        offsets: ``(n, 3)`` chain joint offsets (the first from the base joint).
        local_rot: ``(n, 4)`` starting local rotations (projected into the limits first).
        limits: :func:`chain_limits` of the chain.
    """
    cfg = config or CCDConfig()
    q = np.array(local_rot, dtype=np.float64, copy=True).reshape(-1, 4)
    n = len(q)
    if not (0 <= link < n):
        raise ParameterError(f"link must be in [0, {n}), got {link}")
    top = link if top is None else int(top)
    lim = limits
    _project_all(q, lim.kind, lim.axis, lim.lower, lim.upper, lim.max_angle, lim.axes, lim.poly)
    sweeps, err = _ccd_kernel(np.array(base_rot, dtype=np.float64), np.array(base_pos, dtype=np.float64),
                              np.array(offsets, dtype=np.float64), q, int(link), top,
                              np.array(ee_local, dtype=np.float64), np.array(goal, dtype=np.float64), lim.kind,
                              lim.axis, lim.lower,
                              lim.upper, lim.max_angle, lim.axes, lim.poly, float(cfg.tolerance),
                              int(cfg.max_sweeps))
    status = Status.CONVERGED if err < cfg.tolerance else Status.MAX_SWEEPS
    return IKResult(q, status, int(sweeps), float(err))


def project_chain(local_rot, limits: ChainLimits) -> np.ndarray:
    """``(n, 4)`` local rotations projected into the chain's limits and reach cones."""
    q = np.array(local_rot, dtype=np.float64, copy=True).reshape(-1, 4)
    _project_all(q, limits.kind, limits.axis, limits.lower, limits.upper, limits.max_angle, limits.axes,
                 limits.poly)
    return q


def limits_hold(local_rot, limits: ChainLimits, tol: float = 1e-6) -> np.ndarray:
    """``(n,)`` True where a chain joint is inside its limits (hinge range and axis, total angle) and
    reach cone: the check the tests and the benchmark count violations with."""
    q = np.asarray(local_rot, dtype=np.float64).reshape(-1, 4)
    ok = np.ones(len(q), dtype=bool)
    for h in range(len(q)):
        qh = q[h] if q[h, 0] >= 0 else -q[h]
        if limits.kind[h] == KIND_HINGE:
            s = float(qh[1:] @ limits.axis[h])
            theta = 2.0 * np.arctan2(s, qh[0])
            off = np.linalg.norm(qh[1:] - s * limits.axis[h])
            ok[h] = limits.lower[h] - tol <= theta <= limits.upper[h] + tol and off < tol
        else:
            ang = 2.0 * np.arccos(min(1.0, qh[0]))
            ok[h] = ang <= limits.max_angle[h] + tol
            if limits.kind[h] == KIND_BALL:
                ok[h] &= bool(cone_contains(qh, limits.axes[h], limits.poly[h]))
    return ok


def warm_up() -> None:
    """Compile (or load from numba's cache) every kernel of the solver on a two-joint chain, so that a
    timed loop does not pay for it at its first contact."""
    kind = np.array([KIND_BALL, KIND_HINGE], dtype=np.int64)
    rest_down = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    az = np.arange(8) * np.pi / 4
    octagon = np.stack([np.cos(az), np.sin(az)], axis=1)
    lim = ChainLimits(kind, np.tile([0.0, 1.0, 0.0], (2, 1)), np.zeros(2), np.array([0.0, 2.5]), np.full(2, 2.0),
                      np.tile(rest_down, (2, 1, 1)), np.tile(octagon, (2, 1, 1)))
    offs = np.array([[0.0, 0.2, 0.0], [0.0, 0.0, -0.3]])
    q = np.tile([1.0, 0.0, 0.0, 0.0], (2, 1))
    r = ccd_solve(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), offs, q, 1, np.array([0.0, 0.0, -0.3]),
                  np.array([0.2, 0.2, -0.4]), lim)
    limits_hold(project_chain(r.local_rot, lim), lim)
