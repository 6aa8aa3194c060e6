"""Batch-first unit-quaternion math as pure functions.

Glossary (the one rotation convention of kinodyn):

* A rotation is a unit quaternion stored as ``(w, x, y, z)`` in the last axis of a float64 array, shape
  ``(..., 4)``. Every function broadcasts over all leading axes (``(F, J, 4)`` for a clip, ``(N, J, 4)``
  for a crowd) and never modifies its inputs.
* ``q`` and ``-q`` are the same rotation. Functions that return a rotation make no promise about the
  sign unless they say so; compare rotations with :func:`angle_between` or after :func:`abs`.
* Rotations act on column vectors: ``mul_vec(q, v)`` is ``R(q) @ v``, and ``mul(a, b)`` is the rotation
  ``R(a) @ R(b)`` (first ``b``, then ``a``). Frames are right-handed.
* Matrices are ``(..., 3, 3)`` with column-vector convention: the columns of ``to_matrix(q)`` are the
  rotated basis vectors.
* Euler angles exist only at file boundaries. An order string of three distinct letters from ``xyz``
  names *intrinsic* rotations: ``from_euler(e, "zyx")`` is ``Rz(e0) @ Ry(e1) @ Rx(e2)``, the reading of
  a BVH ``Zrotation Yrotation Xrotation`` channel list. Upper-case strings mean the same here; pass
  ``extrinsic=True`` for extrinsic (fixed-axis) angles, where ``"xyz"`` is ``Rz(e2) @ Ry(e1) @ Rx(e0)``.
* The up axis is +Z. *Heading* is the rotation about +Z; :func:`heading` returns its angle.
* ``log(q)`` is the quaternion logarithm, ``axis * angle / 2``; ``to_rotvec`` is ``axis * angle``.
* scipy's ``Rotation`` stores ``(x, y, z, w)``; :func:`to_scipy` and :func:`from_scipy` are the only
  places that convert.
"""

from __future__ import annotations

import numpy as np

from kinodyn.errors import ParameterError

__all__ = [
    "identity", "normalize", "abs", "conj", "inv", "mul", "inv_mul", "mul_inv", "mul_vec", "inv_mul_vec",
    "between", "angle", "angle_between", "dot", "slerp", "nlerp", "average", "unroll",
    "to_matrix", "from_matrix", "to_rotvec", "from_rotvec", "from_axis_angle", "to_axis_angle", "exp", "log",
    "from_euler", "to_euler", "heading", "from_heading", "remove_heading", "swing_twist",
    "to_scipy", "from_scipy", "fk", "ik", "EULER_ORDERS",
]

EPS = 1e-12
EULER_ORDERS = ("xyz", "xzy", "yxz", "yzx", "zxy", "zyx")
_AXIS = {"x": 0, "y": 1, "z": 2}


def _arr(q) -> np.ndarray:
    return np.asarray(q, dtype=np.float64)


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    """Identity rotations of the given batch shape, ``(*shape, 4)``."""
    out = np.zeros(tuple(shape) + (4,))
    out[..., 0] = 1.0
    return out


def normalize(q, eps: float = EPS) -> np.ndarray:
    """Unit quaternions ``(..., 4)``; a zero quaternion becomes the identity."""
    q = _arr(q)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    safe = np.where(n < eps, 1.0, n)
    return np.where(n < eps, identity(q.shape[:-1]), q / safe)


def abs(q) -> np.ndarray:  # noqa: A001 - orangeduck's name, read as "quat.abs"
    """The representative with non-negative ``w`` of each rotation ``(..., 4)``."""
    q = _arr(q)
    return np.where(q[..., :1] < 0.0, -q, q)


def conj(q) -> np.ndarray:
    """Quaternion conjugate ``(w, -x, -y, -z)``, the inverse of a unit quaternion."""
    q = _arr(q)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


inv = conj


def mul(a, b) -> np.ndarray:
    """Hamilton product ``a * b`` (apply ``b`` first, then ``a``), shapes broadcast to ``(..., 4)``."""
    a = _arr(a)
    b = _arr(b)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def inv_mul(a, b) -> np.ndarray:
    """``inv(a) * b``: ``b`` expressed in the frame of ``a``."""
    return mul(conj(a), b)


def mul_inv(a, b) -> np.ndarray:
    """``a * inv(b)``."""
    return mul(a, conj(b))


def mul_vec(q, v) -> np.ndarray:
    """Rotate vectors ``v (..., 3)`` by ``q (..., 4)``: ``R(q) @ v``."""
    q = _arr(q)
    v = _arr(v)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def inv_mul_vec(q, v) -> np.ndarray:
    """Rotate vectors by the inverse of ``q``: ``R(q).T @ v``."""
    return mul_vec(conj(q), v)


def dot(a, b) -> np.ndarray:
    """Four-dimensional dot product, shape ``(...)``."""
    return np.sum(_arr(a) * _arr(b), axis=-1)


def angle(q) -> np.ndarray:
    """Rotation angle in ``[0, pi]`` of each quaternion, shape ``(...)``."""
    q = _arr(q)
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def angle_between(a, b) -> np.ndarray:
    """Angle in ``[0, pi]`` of the rotation taking ``b`` to ``a``; sign-invariant."""
    return angle(inv_mul(b, a))


def between(u, v, eps: float = EPS) -> np.ndarray:
    """Shortest-arc rotation taking direction ``u (..., 3)`` to direction ``v (..., 3)``.

    Built from axis and angle: the axis ``u x (u + v)`` (equal to ``u x v`` but without its cancellation
    when ``v ~ -u``) and the angle ``atan2(|u x v|, u . v)``, so nearly opposite directions stay accurate.
    Exactly opposite directions give a half turn about an axis perpendicular to ``u``; a vector shorter
    than ``eps`` gives the identity.
    """
    u = _arr(u)
    v = _arr(v)
    nu = np.linalg.norm(u, axis=-1, keepdims=True)
    nv = np.linalg.norm(v, axis=-1, keepdims=True)
    zero = (nu < eps) | (nv < eps)
    u = u / np.where(nu < eps, 1.0, nu)
    v = v / np.where(nv < eps, 1.0, nv)
    n = np.cross(u, u + v)
    s = np.linalg.norm(n, axis=-1, keepdims=True)
    c = np.sum(u * v, axis=-1, keepdims=True)
    half = 0.5 * np.arctan2(s, c)
    parallel = s < 1e-150
    q = np.concatenate([np.cos(half), np.sin(half) * n / np.where(parallel, 1.0, s)], axis=-1)
    # Opposite vectors: rotate by pi about any axis perpendicular to u.
    alt = np.cross(u, np.array([1.0, 0.0, 0.0]))
    alt2 = np.cross(u, np.array([0.0, 1.0, 0.0]))
    alt = np.where(np.linalg.norm(alt, axis=-1, keepdims=True) < 1e-6, alt2, alt)
    opposite = np.concatenate([np.zeros(alt.shape[:-1] + (1,)), alt], axis=-1)
    q = np.where(parallel & (c < 0.0), opposite, q)
    return normalize(np.where(zero, identity(zero.shape[:-1]), q))


def unroll(q, axis: int = 0) -> np.ndarray:
    """Flip signs along ``axis`` (time) so consecutive quaternions lie in the same hemisphere."""
    q = np.moveaxis(_arr(q).copy(), axis, 0)
    if q.shape[0] > 1:
        d = np.sum(q[1:] * q[:-1], axis=-1)
        flips = np.cumprod(np.where(d < 0.0, -1.0, 1.0), axis=0)
        q[1:] *= flips[..., None]
    return np.moveaxis(q, 0, axis)


def slerp(a, b, t, eps: float = 1e-8) -> np.ndarray:
    """Spherical interpolation along the shortest arc; ``t`` broadcasts against ``(...)``.

    ``t=0`` gives ``a`` and ``t=1`` gives ``b`` (or ``-b``). Nearly equal rotations fall back to nlerp.
    """
    a = _arr(a)
    b = _arr(b)
    t = _arr(t)[..., None]
    d = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(d < 0.0, -b, b)
    d = np.abs(d)
    theta = np.arccos(np.clip(d, -1.0, 1.0))
    s = np.sin(theta)
    small = s < eps
    safe = np.where(small, 1.0, s)
    wa = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    wb = np.where(small, t, np.sin(t * theta) / safe)
    return normalize(wa * a + wb * b)


def nlerp(a, b, t) -> np.ndarray:
    """Normalized linear interpolation along the shortest arc (cheap, not constant speed)."""
    a = _arr(a)
    b = _arr(b)
    t = _arr(t)[..., None]
    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -b, b)
    return normalize((1.0 - t) * a + t * b)


def average(q, weights=None, axis: int = 0) -> np.ndarray:
    """Weighted average rotation along ``axis`` (Markley et al. 2007, the chordal L2 mean).

    The mean is the eigenvector of ``sum_i w_i q_i q_i^T`` with the largest eigenvalue, so it is
    sign-invariant and exact for any number of rotations. The result has non-negative ``w``.

    Args:
        q: rotations ``(..., 4)``; the averaged axis is ``axis`` of ``q.shape[:-1]``.
        weights: non-negative weights broadcastable to ``q.shape[:-1]``, or one weight per rotation along
            ``axis`` (1-D, length ``q.shape[axis]``); uniform when ``None``.
    """
    q = _arr(q)
    ax = axis % (q.ndim - 1)
    if weights is None:
        w = np.ones(q.shape[:-1])
    else:
        w = _arr(weights)
        if w.ndim == 1 and q.ndim > 2 and len(w) == q.shape[ax]:  # along `axis`, not the last batch axis
            w = np.expand_dims(w, tuple(i for i in range(q.ndim - 1) if i != ax))
        w = np.broadcast_to(w, q.shape[:-1])
    q = np.moveaxis(q, ax, -2)
    w = np.moveaxis(w, ax, -1)
    if np.any(w < 0):
        raise ParameterError(f"average weights must be non-negative, got minimum {np.min(w)}")
    m = np.einsum("...n,...ni,...nj->...ij", w, q, q)
    _, vecs = np.linalg.eigh(m)
    return abs(vecs[..., :, -1])


# --------------------------------------------------------------------------- conversions


def to_matrix(q) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of unit quaternions ``(..., 4)``."""
    q = _arr(q)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    m = np.stack(
        [
            1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy),
            2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx),
            2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy),
        ],
        axis=-1,
    )
    return m.reshape(q.shape[:-1] + (3, 3))


def from_matrix(m) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` with ``w >= 0`` from rotation matrices ``(..., 3, 3)``.

    Shepperd's method: of the four algebraically equivalent formulas, use the one whose divisor is
    largest, so the result is accurate for every rotation, including half turns.
    """
    m = _arr(m)
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    tr = m00 + m11 + m22
    cand = np.stack([tr, m00, m11, m22], axis=-1)
    k = np.argmax(cand, axis=-1)
    r = np.sqrt(np.maximum(1.0 + 2.0 * np.take_along_axis(cand, k[..., None], -1)[..., 0] - tr, EPS))
    s = 0.5 / r
    q0 = np.stack([0.5 * r, (m[..., 2, 1] - m[..., 1, 2]) * s, (m[..., 0, 2] - m[..., 2, 0]) * s,
                   (m[..., 1, 0] - m[..., 0, 1]) * s], axis=-1)
    q1 = np.stack([(m[..., 2, 1] - m[..., 1, 2]) * s, 0.5 * r, (m[..., 0, 1] + m[..., 1, 0]) * s,
                   (m[..., 0, 2] + m[..., 2, 0]) * s], axis=-1)
    q2 = np.stack([(m[..., 0, 2] - m[..., 2, 0]) * s, (m[..., 0, 1] + m[..., 1, 0]) * s, 0.5 * r,
                   (m[..., 1, 2] + m[..., 2, 1]) * s], axis=-1)
    q3 = np.stack([(m[..., 1, 0] - m[..., 0, 1]) * s, (m[..., 0, 2] + m[..., 2, 0]) * s,
                   (m[..., 1, 2] + m[..., 2, 1]) * s, 0.5 * r], axis=-1)
    q = np.choose(k[..., None], [q0, q1, q2, q3])
    return abs(normalize(q))


def exp(v, eps: float = 1e-8) -> np.ndarray:
    """Quaternion exponential of pure vectors ``(..., 3)``: ``(cos|v|, sin|v| v/|v|)``."""
    v = _arr(v)
    h = np.linalg.norm(v, axis=-1, keepdims=True)
    small = h < eps
    sinc = np.where(small, 1.0 - h * h / 6.0, np.sin(h) / np.where(small, 1.0, h))
    return np.concatenate([np.cos(h), sinc * v], axis=-1)


def log(q, eps: float = 1e-8) -> np.ndarray:
    """Quaternion logarithm ``axis * angle / 2``, shape ``(..., 3)``, taken on the ``w >= 0`` branch."""
    q = abs(q)
    n = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    small = n < eps
    half = np.arctan2(n, q[..., :1])
    scale = np.where(small, 1.0 / np.maximum(q[..., :1], eps), half / np.where(small, 1.0, n))
    return scale * q[..., 1:]


def to_rotvec(q) -> np.ndarray:
    """Rotation vectors ``axis * angle`` (angle in ``[0, pi]``), shape ``(..., 3)``."""
    return 2.0 * log(q)


def from_rotvec(v) -> np.ndarray:
    """Unit quaternions from rotation vectors ``axis * angle``, ``(..., 3)``."""
    return exp(0.5 * _arr(v))


def from_axis_angle(axis, angle_rad) -> np.ndarray:
    """Rotation by ``angle_rad (...)`` about unit-normalized ``axis (..., 3)``; the two broadcast."""
    axis = _arr(axis)
    axis = axis / np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), EPS)
    half = 0.5 * _arr(angle_rad)
    shape = np.broadcast_shapes(axis.shape[:-1], half.shape)
    half = np.broadcast_to(half, shape)[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * np.broadcast_to(axis, shape + (3,))], axis=-1)


def to_axis_angle(q) -> tuple[np.ndarray, np.ndarray]:
    """Unit axis ``(..., 3)`` and angle in ``[0, pi]`` ``(...)``; the axis is +X for the identity."""
    v = to_rotvec(q)
    a = np.linalg.norm(v, axis=-1)
    ax = np.where(a[..., None] < 1e-12, np.array([1.0, 0.0, 0.0]), v / np.where(a < 1e-12, 1.0, a)[..., None])
    return ax, a


def _check_order(order: str) -> str:
    o = str(order).lower()
    if o not in EULER_ORDERS:
        raise ParameterError(f"Euler order must be one of {', '.join(EULER_ORDERS)}, got {order!r}")
    return o


def from_euler(e, order: str = "zyx", extrinsic: bool = False) -> np.ndarray:
    """Quaternions from Euler angles in radians ``(..., 3)``.

    Intrinsic by default: ``order="zyx"`` gives ``Rz(e0) @ Ry(e1) @ Rx(e2)``.
    """
    o = _check_order(order)
    e = _arr(e)
    if extrinsic:
        o = o[::-1]
        e = e[..., ::-1]
    half = 0.5 * e
    c = np.cos(half)
    s = np.sin(half)
    k0 = _AXIS[o[0]]
    q = [c[..., 0], np.zeros(e.shape[:-1]), np.zeros(e.shape[:-1]), np.zeros(e.shape[:-1])]
    q[1 + k0] = s[..., 0]
    for i in (1, 2):
        q = _mul_axis(q, c[..., i], s[..., i], _AXIS[o[i]])
    out = np.empty(e.shape[:-1] + (4,))
    for i in range(4):
        out[..., i] = q[i]
    return out


def _mul_axis(a, c, s, k):
    """Components of ``a * (c, s * e_k)``: a product with a rotation about one coordinate axis."""
    aw, ax, ay, az = a
    if k == 0:
        return [aw * c - ax * s, aw * s + ax * c, ay * c + az * s, az * c - ay * s]
    if k == 1:
        return [aw * c - ay * s, ax * c - az * s, aw * s + ay * c, az * c + ax * s]
    return [aw * c - az * s, ax * c + ay * s, ay * c - ax * s, aw * s + az * c]


def to_euler(q, order: str = "zyx", extrinsic: bool = False) -> np.ndarray:
    """Euler angles in radians ``(..., 3)`` such that ``from_euler(to_euler(q, o), o)`` equals ``q``.

    The middle angle lies in ``[-pi/2, pi/2]``. At gimbal lock (middle angle at +-pi/2) the first angle
    absorbs the whole remaining rotation and the last is zero (up to rounding). The last angle is always
    solved from what the first two leave, so the round trip is accurate near gimbal lock as well.
    """
    o = _check_order(order)
    if extrinsic:
        return to_euler(q, o[::-1])[..., ::-1]
    i, j, k = (_AXIS[ch] for ch in o)
    sign = 1.0 if (j - i) % 3 == 1 else -1.0
    r = to_matrix(q)
    cb = np.hypot(r[..., i, i], r[..., i, j])
    b = np.arctan2(sign * r[..., i, k], cb)  # accurate near +-pi/2, unlike arcsin
    # At (numerical) gimbal lock take the convention c = 0; elsewhere c is solved below, which keeps the
    # round trip exact to rounding even when a itself is poorly determined (cb tiny).
    lock = cb < 1e-14
    a = np.where(lock, np.arctan2(sign * r[..., k, j], r[..., j, j]), np.arctan2(-sign * r[..., j, k], r[..., k, k]))
    # Row j of R_i(a)^T R equals row j of R_k(c): (sign sin c, cos c) at columns (i, j).
    sa, ca = np.sin(a), np.cos(a)
    c = np.arctan2(sign * ca * r[..., j, i] + sa * r[..., k, i], ca * r[..., j, j] + sign * sa * r[..., k, j])
    return np.stack([a, b, c], axis=-1)


# --------------------------------------------------------------------------- heading (Z up)


def heading(q, forward=None) -> np.ndarray:
    """Heading angle (rotation about +Z) of each rotation, in ``(-pi, pi]``, shape ``(...)``.

    Without ``forward`` this is the twist angle about +Z (swing-twist decomposition). With a local
    ``forward`` axis ``(3,)`` it is the azimuth of the rotated forward axis, which stays defined for
    bodies lying down as long as that axis is not vertical.
    """
    q = _arr(q)
    if forward is None:
        q = abs(q)
        h = 2.0 * np.arctan2(q[..., 3], q[..., 0])
    else:
        f = mul_vec(q, np.broadcast_to(_arr(forward), q.shape[:-1] + (3,)))
        h = np.arctan2(f[..., 1], f[..., 0])
    return np.where(h <= -np.pi, h + 2.0 * np.pi, h)  # -pi -> pi: the documented (-pi, pi]


def from_heading(h) -> np.ndarray:
    """Rotations about +Z by angles ``h (...)``."""
    half = 0.5 * _arr(h)
    z = np.zeros_like(half)
    return np.stack([np.cos(half), z, z, np.sin(half)], axis=-1)


def remove_heading(q, forward=None) -> np.ndarray:
    """``inv(from_heading(heading(q))) * q``: the rotation with its heading taken out."""
    return inv_mul(from_heading(heading(q, forward)), q)


def swing_twist(q, axis, eps: float = EPS) -> tuple[np.ndarray, np.ndarray]:
    """Decompose ``q = swing * twist`` where ``twist`` rotates about ``axis (..., 3)`` (in q's frame).

    Returns ``(swing, twist)``, each ``(..., 4)``. When the rotation is a half turn perpendicular to
    the axis the twist is undefined and returned as the identity.
    """
    q = _arr(q)
    axis = _arr(axis)
    axis = axis / np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), eps)
    proj = np.sum(q[..., 1:] * axis, axis=-1, keepdims=True) * axis
    twist = normalize(np.concatenate([q[..., :1] * np.ones(proj.shape[:-1] + (1,)), proj], axis=-1), eps)
    swing = mul(q, conj(twist))
    return swing, twist


# --------------------------------------------------------------------------- scipy bridge


def to_scipy(q) -> np.ndarray:
    """``(w, x, y, z)`` to scipy's ``(x, y, z, w)`` ordering."""
    q = _arr(q)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def from_scipy(q) -> np.ndarray:
    """scipy's ``(x, y, z, w)`` to ``(w, x, y, z)``."""
    q = _arr(q)
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


# --------------------------------------------------------------------------- kinematic chains


def fk(local_rot, local_pos, parents) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics over a parents array.

    Args:
        local_rot: local joint rotations ``(..., J, 4)``.
        local_pos: local joint translations ``(..., J, 3)`` (the root's is its global position).
        parents: ``(J,)`` ints with ``parents[0] == -1`` and ``parents[j] < j``.

    Returns:
        Global rotations ``(..., J, 4)`` and global positions ``(..., J, 3)``.
    """
    local_rot = _arr(local_rot)
    local_pos = _arr(local_pos)
    shape = np.broadcast_shapes(local_rot.shape[:-1], local_pos.shape[:-1])
    gr = np.empty(shape + (4,))
    gp = np.empty(shape + (3,))
    gr[..., 0, :] = local_rot[..., 0, :]
    gp[..., 0, :] = local_pos[..., 0, :]
    for j in range(1, len(parents)):
        p = parents[j]
        gr[..., j, :] = mul(gr[..., p, :], local_rot[..., j, :])
        gp[..., j, :] = gp[..., p, :] + mul_vec(gr[..., p, :], local_pos[..., j, :])
    return gr, gp


def ik(global_rot, global_pos, parents) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`fk`: local rotations ``(..., J, 4)`` and translations ``(..., J, 3)``."""
    global_rot = _arr(global_rot)
    global_pos = _arr(global_pos)
    parents = np.asarray(parents)
    lr = global_rot.copy()
    lp = global_pos.copy()
    p = parents[1:]
    lr[..., 1:, :] = inv_mul(global_rot[..., p, :], global_rot[..., 1:, :])
    lp[..., 1:, :] = inv_mul_vec(global_rot[..., p, :], global_pos[..., 1:, :] - global_pos[..., p, :])
    return lr, lp
