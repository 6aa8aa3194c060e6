"""The compiled scalar quaternion kernels agree with the numpy quaternion functions (the oracle)."""

from __future__ import annotations

import numba
import numpy as np

from kinodyn.math import kernels, quat

_TOL = 1e-12


@numba.njit(cache=False)
def _apply(q, p, v, ang):  # pragma: no cover - compiled
    n = q.shape[0]
    mul = np.empty((n, 4))
    rot = np.empty((n, 3))
    rot_add = np.empty((n, 3))
    rot_inv = np.empty((n, 3))
    aa = np.empty((n, 4))
    for i in range(n):
        mul[i] = kernels.qmul(q[i, 0], q[i, 1], q[i, 2], q[i, 3], q[n - 1 - i, 0], q[n - 1 - i, 1],
                              q[n - 1 - i, 2], q[n - 1 - i, 3])
        rot[i] = kernels.qrot(q[i, 0], q[i, 1], q[i, 2], q[i, 3], v[i, 0], v[i, 1], v[i, 2])
        rot_add[i] = kernels.qrot_add(p[i, 0], p[i, 1], p[i, 2], q[i, 0], q[i, 1], q[i, 2], q[i, 3],
                                      v[i, 0], v[i, 1], v[i, 2])
        rot_inv[i] = kernels.qrot_inv(q[i, 0], q[i, 1], q[i, 2], q[i, 3], v[i, 0], v[i, 1], v[i, 2])
        aa[i] = kernels.axis_angle(v[i, 0], v[i, 1], v[i, 2], ang[i])
    return mul, rot, rot_add, rot_inv, aa


def test_kernels_match_numpy_quaternions(rng):
    q = quat.normalize(rng.normal(size=(50, 4)))
    p = rng.normal(size=(50, 3))
    v = rng.normal(size=(50, 3))
    ang = rng.uniform(-np.pi, np.pi, 50)
    mul, rot, rot_add, rot_inv, aa = _apply(q, p, v, ang)
    np.testing.assert_allclose(mul, quat.mul(q, q[::-1]), atol=_TOL, err_msg="qmul")
    np.testing.assert_allclose(rot, quat.mul_vec(q, v), atol=_TOL, err_msg="qrot")
    np.testing.assert_allclose(rot_add, p + quat.mul_vec(q, v), atol=_TOL, err_msg="qrot_add")
    np.testing.assert_allclose(rot_inv, quat.inv_mul_vec(q, v), atol=_TOL, err_msg="qrot_inv")
    np.testing.assert_allclose(aa, quat.from_axis_angle(v / np.linalg.norm(v, axis=1, keepdims=True), ang),
                               atol=_TOL, err_msg="axis_angle")


@numba.njit(cache=False)
def _small(x):  # pragma: no cover - compiled
    return kernels.axis_angle(0.0, 0.0, 0.0, 1.0), kernels.unit(x, 0.0, 0.0), kernels.acos_clipped(1.0 + x)


def test_kernels_special_values():
    """A zero axis gives the identity, a tiny vector is left as it is, arccos is clipped."""
    ident, small, ac = _small(1e-12)
    assert ident == (1.0, 0.0, 0.0, 0.0)
    assert small == (1e-12, 0.0, 0.0, 1e-12)
    assert ac == 0.0
