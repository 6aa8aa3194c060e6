"""kinodyn.math.xform: ground transforms (x, y, heading) against 3x3 homogeneous matrices and quaternions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from kinodyn.math import quat, xform

_TOL = 1e-12  # metres and radians
_SEED = 31415
_SETTINGS = settings(max_examples=80, deadline=None, derandomize=True)

_coord = st.floats(-50.0, 50.0, allow_nan=False, allow_infinity=False)
_angle = st.one_of(
    st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False),
    st.sampled_from([0.0, np.pi, -np.pi, np.pi / 2, -np.pi / 2, 2 * np.pi]),
)
ground = st.tuples(_coord, _coord, _angle).map(np.array)


def rand_ground(rng, n=200) -> np.ndarray:
    return np.stack([rng.uniform(-5, 5, n), rng.uniform(-5, 5, n), rng.uniform(-4, 4, n)], axis=-1)


def assert_same_ground(a, b, tol=_TOL, err_msg=""):
    """Equal positions and headings equal modulo 2 pi."""
    a, b = np.asarray(a), np.asarray(b)
    assert_allclose(a[..., :2], b[..., :2], atol=tol, err_msg=err_msg + " (position)")
    assert_allclose(
        xform.wrap_angle(a[..., 2] - b[..., 2] + 1.0) - 1.0, 0.0, atol=tol, err_msg=err_msg + " (heading)"
    )


def test_wrap_angle_range():
    a = np.array([-np.pi, np.pi, 3 * np.pi, -3 * np.pi, 0.0, 1.0, -7.0, 2 * np.pi])
    w = xform.wrap_angle(a)
    assert np.all((w >= -np.pi) & (w < np.pi)), "wrapped to [-pi, pi)"
    assert_allclose(np.exp(1j * w), np.exp(1j * a), atol=_TOL, err_msg="same angle")
    assert xform.wrap_angle(np.pi) == pytest.approx(-np.pi)


def test_matrix_equivalence():
    rng = np.random.default_rng(_SEED)
    a, b = rand_ground(rng), rand_ground(rng)
    ma, mb = xform.to_matrix(a), xform.to_matrix(b)
    assert ma.shape == (200, 3, 3)
    assert_allclose(ma[:, 2], np.broadcast_to([0.0, 0.0, 1.0], (200, 3)), err_msg="last row")
    assert_same_ground(xform.from_matrix(ma), a, err_msg="from_matrix(to_matrix)")
    assert_allclose(
        xform.to_matrix(xform.compose(a, b)), ma @ mb, atol=_TOL, err_msg="compose = matrix product"
    )
    assert_allclose(
        xform.to_matrix(xform.inverse(a)), np.linalg.inv(ma), atol=_TOL, err_msg="inverse = matrix inverse"
    )
    p = rng.normal(size=(200, 2))
    ph = np.concatenate([p, np.ones((200, 1))], axis=-1)
    assert_allclose(xform.apply(a, p), np.einsum("nij,nj->ni", ma, ph)[:, :2], atol=_TOL, err_msg="apply")
    assert_allclose(
        xform.apply_vector(a, p), np.einsum("nij,nj->ni", ma[:, :2, :2], p), atol=_TOL, err_msg="apply_vector"
    )


def test_compose_inverse_relative_identities():
    rng = np.random.default_rng(_SEED + 1)
    a, b, c = rand_ground(rng), rand_ground(rng), rand_ground(rng)
    ident = np.zeros(3)
    assert_same_ground(xform.compose(a, ident), a, err_msg="a . id")
    assert_same_ground(xform.compose(ident, a), a, err_msg="id . a")
    assert_same_ground(xform.compose(a, xform.inverse(a)), np.zeros_like(a), err_msg="a . a^-1")
    assert_same_ground(xform.compose(xform.inverse(a), a), np.zeros_like(a), err_msg="a^-1 . a")
    assert_same_ground(xform.inverse(xform.inverse(a)), a, err_msg="inverse twice")
    assert_same_ground(
        xform.compose(xform.compose(a, b), c),
        xform.compose(a, xform.compose(b, c)),
        tol=1e-11,
        err_msg="associative",
    )
    assert_same_ground(
        xform.relative(a, b), xform.compose(xform.inverse(a), b), err_msg="relative definition"
    )
    assert_same_ground(
        xform.compose(a, xform.relative(a, b)), b, tol=1e-11, err_msg="a . (b seen from a) = b"
    )
    assert_same_ground(xform.relative(a, a), np.zeros_like(a), err_msg="relative to itself")
    # broadcasting: one transform against many
    assert_same_ground(
        xform.compose(a[0], b), np.array([xform.compose(a[0], bi) for bi in b]), err_msg="broadcast"
    )
    for g in (xform.compose(a, b), xform.inverse(a), xform.relative(a, b)):
        assert np.all((g[:, 2] >= -np.pi) & (g[:, 2] < np.pi)), "headings wrapped"


def test_apply_keeps_height_and_broadcasts():
    g = np.array([1.0, 2.0, np.pi / 2])
    p = np.array([[1.0, 0.0, 0.7], [0.0, 1.0, -0.2]])
    assert_allclose(
        xform.apply(g, p), [[1.0, 3.0, 0.7], [0.0, 2.0, -0.2]], atol=_TOL, err_msg="points, z kept"
    )
    assert_allclose(
        xform.apply_vector(g, p), [[0.0, 1.0, 0.7], [-1.0, 0.0, -0.2]], atol=_TOL, err_msg="vectors"
    )
    many = np.array([g, [0.0, 0.0, 0.0]])
    assert_allclose(
        xform.apply(many, p[0]), [[1.0, 3.0, 0.7], [1.0, 0.0, 0.7]], atol=_TOL, err_msg="(N, 3) g, (3,) p"
    )
    p0 = p.copy()
    xform.apply(g, p)
    assert_allclose(p, p0, err_msg="input untouched")


def test_to_quat_pos_agrees_with_quaternions():
    rng = np.random.default_rng(_SEED + 2)
    g = rand_ground(rng)
    q, pos = xform.to_quat_pos(g)
    assert_allclose(pos[:, 2], 0.0)
    assert_allclose(pos[:, :2], g[:, :2])
    assert_allclose(
        quat.to_matrix(q)[:, :2, :2], xform.to_matrix(g)[:, :2, :2], atol=_TOL, err_msg="rotation"
    )
    p = rng.normal(size=(200, 3))
    assert_allclose(quat.mul_vec(q, p) + pos, xform.apply(g, p), atol=_TOL, err_msg="same action on points")


def test_from_root():
    rng = np.random.default_rng(_SEED + 3)
    h = rng.uniform(-np.pi, np.pi, 100)
    tilt = quat.from_axis_angle(rng.normal(size=(100, 3)) * [1.0, 1.0, 0.0], rng.uniform(0.0, 1.0, 100))
    rot = quat.mul(quat.from_heading(h), tilt)
    pos = rng.normal(size=(100, 3))
    g = xform.from_root(pos, rot)
    assert_allclose(g[:, :2], pos[:, :2], err_msg="floor position")
    assert_allclose(g[:, 2], xform.wrap_angle(quat.heading(rot)), atol=_TOL, err_msg="heading")
    assert np.all((g[:, 2] >= -np.pi) & (g[:, 2] < np.pi))
    untilted = xform.from_root(pos, quat.from_heading(h))
    assert_same_ground(untilted, np.stack([pos[:, 0], pos[:, 1], h], -1), err_msg="pure heading")
    fwd = xform.from_root(pos, rot, forward=[1.0, 0.0, 0.0])
    f = quat.mul_vec(rot, [1.0, 0.0, 0.0])
    assert_allclose(
        fwd[:, 2], xform.wrap_angle(np.arctan2(f[:, 1], f[:, 0])), atol=_TOL, err_msg="forward axis"
    )


def test_ground_of_moved_root_composes():
    """Moving a root by g on the floor moves its ground transform by g (what alignment relies on)."""
    rng = np.random.default_rng(_SEED + 4)
    rot = quat.normalize(rng.normal(size=(100, 4)))
    pos = rng.normal(size=(100, 3))
    g = rand_ground(rng, 100)
    q, p = xform.to_quat_pos(g)
    moved = xform.from_root(quat.mul_vec(q, pos) + p, quat.mul(q, rot))
    assert_same_ground(
        moved, xform.compose(g, xform.from_root(pos, rot)), tol=1e-9, err_msg="from_root equivariant"
    )


@_SETTINGS
@given(ground, ground)
def test_property_compose_and_inverse(a, b):
    assert_allclose(
        xform.to_matrix(xform.compose(a, b)),
        xform.to_matrix(a) @ xform.to_matrix(b),
        atol=1e-9 * (1 + np.abs(a).max() + np.abs(b).max()),
        err_msg="compose",
    )
    assert_same_ground(
        xform.compose(a, xform.inverse(a)), np.zeros(3), tol=1e-9 * (1 + np.abs(a).max()), err_msg="inverse"
    )
    batched = xform.relative(np.stack([a, b]), np.stack([b, a]))
    assert_same_ground(batched[0], xform.relative(a, b), tol=1e-12, err_msg="batched == looped")
    assert_same_ground(batched[1], xform.relative(b, a), tol=1e-12, err_msg="batched == looped")
