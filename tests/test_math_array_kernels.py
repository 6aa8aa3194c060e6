"""The array-form compiled kernels agree with kinodyn.math.quat (the numpy reference)."""

import numpy as np

from kinodyn.math import array_kernels as ak
from kinodyn.math import quat


def test_products_rotations_and_matrices_match_the_numpy_versions(rng):
    for _ in range(50):
        a, b = quat.normalize(rng.normal(size=4)), quat.normalize(rng.normal(size=4))
        v = rng.normal(size=3)
        np.testing.assert_allclose(ak.qmul(a, b), quat.mul(a, b), atol=1e-14)
        np.testing.assert_allclose(ak.qrot(a, v), quat.mul_vec(a, v), atol=1e-14)
        np.testing.assert_allclose(ak.qmat(a) @ v, quat.mul_vec(a, v), atol=1e-14)
        np.testing.assert_allclose(ak.cross3(v, b[1:]), np.cross(v, b[1:]), atol=1e-14)


def test_axis_angle_and_shortest_arc(rng):
    for _ in range(50):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        ang = rng.uniform(-3, 3)
        np.testing.assert_allclose(ak.qaxis(axis, ang), quat.from_axis_angle(axis, ang), atol=1e-14)
        u, v = rng.normal(size=3), rng.normal(size=3)
        u, v = u / np.linalg.norm(u), v / np.linalg.norm(v)
        q = ak.qbetween(u, v)
        np.testing.assert_allclose(ak.qrot(q, u), v, atol=1e-12)
        assert abs(np.linalg.norm(q) - 1.0) < 1e-12
    np.testing.assert_array_equal(ak.qbetween(np.array([1.0, 0, 0]), np.array([-1.0, 0, 0])), [1.0, 0, 0, 0])
