"""kinodyn.math.quat against scipy's Rotation (the oracle), plus property tests.

Every conversion goes through ``quat.to_scipy``/``quat.from_scipy``, the one place that swaps
``(w, x, y, z)`` and scipy's ``(x, y, z, w)``. Rotations are compared sign-invariantly (``q`` and ``-q``
are the same rotation) with :func:`assert_same_rotation`.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation, Slerp

from kinodyn.errors import ParameterError
from kinodyn.math import quat

_TOL = 1e-12  # absolute tolerance on quaternion components, matrices, vectors and angles
_SEED = 20261122
_N = 400  # rotations per batch test
_SETTINGS = settings(max_examples=60, deadline=None, derandomize=True)

ORDERS = quat.EULER_ORDERS


# --------------------------------------------------------------------------- helpers


def sp(q) -> Rotation:
    """scipy Rotation of our ``(w, x, y, z)`` quaternions."""
    return Rotation.from_quat(quat.to_scipy(q))


def from_sp(r: Rotation) -> np.ndarray:
    return quat.from_scipy(r.as_quat())


def assert_same_rotation(a, b, tol=_TOL, err_msg=""):
    """Equal as rotations: ``a == b`` or ``a == -b`` for each quaternion."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    d = np.minimum(np.abs(a - b).max(axis=-1), np.abs(a + b).max(axis=-1))
    assert np.all(d <= tol), f"{err_msg}: max sign-invariant difference {d.max():.3g} > {tol:g}"


def rand_quat(rng, n=_N) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def special_quats() -> np.ndarray:
    """Identity, half turns and quarter turns about the coordinate axes and a diagonal, both signs."""
    out = [quat.identity()]
    axes = [np.eye(3)[i] for i in range(3)] + [
        np.ones(3) / np.sqrt(3.0),
        np.array([1.0, -1.0, 0.0]) / np.sqrt(2),
    ]
    for ax in axes:
        for ang in (np.pi, -np.pi / 2, np.pi / 2, np.pi - 1e-9, 1e-9):
            out.append(quat.from_axis_angle(ax, ang))
    q = np.array(out)
    return np.concatenate([q, -q])


@pytest.fixture
def qs():
    rng = np.random.default_rng(_SEED)
    return np.concatenate([rand_quat(rng), special_quats()])


# hypothesis strategies
_finite = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
_raw4 = hnp.arrays(np.float64, (4,), elements=_finite).filter(lambda q: np.linalg.norm(q) > 1e-3)
quats = st.one_of(_raw4.map(lambda q: q / np.linalg.norm(q)), st.sampled_from(list(special_quats())))
vec3 = st.one_of(
    hnp.arrays(np.float64, (3,), elements=st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)),
    st.sampled_from(
        [np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -1.0]), np.array([1e-9, 0.0, 0.0])]
    ),
)
batch_quats = (
    hnp.arrays(np.float64, st.tuples(st.integers(1, 6), st.just(4)), elements=_finite)
    .filter(lambda q: np.all(np.linalg.norm(q, axis=-1) > 1e-3))
    .map(lambda q: q / np.linalg.norm(q, axis=-1, keepdims=True))
)


# --------------------------------------------------------------------------- scipy bridge and basics


def test_scipy_bridge_orders_components():
    q = np.array([0.1, 0.2, 0.3, 0.4])
    assert_allclose(quat.to_scipy(q), [0.2, 0.3, 0.4, 0.1], err_msg="to_scipy")
    assert_allclose(quat.from_scipy(quat.to_scipy(q)), q, err_msg="round trip")
    assert_allclose(quat.to_scipy(quat.identity()), Rotation.identity().as_quat(), err_msg="identity")
    assert quat.identity((2, 3)).shape == (2, 3, 4)


def test_normalize_and_abs(qs):
    rng = np.random.default_rng(_SEED)
    raw = rng.normal(size=(50, 4)) * rng.uniform(0.1, 10.0, size=(50, 1))
    n = quat.normalize(raw)
    assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=_TOL, err_msg="unit norm")
    assert_allclose(quat.normalize(np.zeros((2, 4))), quat.identity((2,)), err_msg="zero -> identity")
    a = quat.abs(qs)
    assert np.all(a[:, 0] >= 0.0)
    assert_same_rotation(a, qs, err_msg="abs keeps the rotation")


def test_mul_conj_inv_match_scipy(qs):
    rng = np.random.default_rng(_SEED + 1)
    b = np.concatenate([rand_quat(rng), special_quats()[::-1]])
    assert_same_rotation(quat.mul(qs, b), from_sp(sp(qs) * sp(b)), err_msg="mul")
    assert_same_rotation(quat.inv(qs), from_sp(sp(qs).inv()), err_msg="inv")
    assert_same_rotation(quat.conj(qs), from_sp(sp(qs).inv()), err_msg="conj")
    assert_same_rotation(quat.inv_mul(qs, b), from_sp(sp(qs).inv() * sp(b)), err_msg="inv_mul")
    assert_same_rotation(quat.mul_inv(qs, b), from_sp(sp(qs) * sp(b).inv()), err_msg="mul_inv")
    assert_same_rotation(quat.mul(qs, quat.inv(qs)), quat.identity((len(qs),)), err_msg="q q^-1")


def test_mul_is_matrix_product(qs):
    rng = np.random.default_rng(_SEED + 2)
    b = rand_quat(rng, len(qs))
    assert_allclose(
        quat.to_matrix(quat.mul(qs, b)),
        quat.to_matrix(qs) @ quat.to_matrix(b),
        atol=_TOL,
        err_msg="R(a b) = R(a) R(b)",
    )


def test_mul_vec_matches_scipy_and_broadcasts(qs):
    rng = np.random.default_rng(_SEED + 3)
    v = rng.normal(size=(len(qs), 3)) * 3.0
    v[:5] = 0.0  # zero vectors stay zero
    assert_allclose(quat.mul_vec(qs, v), sp(qs).apply(v), atol=_TOL, err_msg="mul_vec")
    assert_allclose(quat.inv_mul_vec(qs, v), sp(qs).inv().apply(v), atol=_TOL, err_msg="inv_mul_vec")
    assert_allclose(quat.mul_vec(qs, v)[:5], 0.0, err_msg="zero vectors")
    # one rotation, many vectors; many rotations, one vector
    assert_allclose(quat.mul_vec(qs[7], v), sp(qs[7]).apply(v), atol=_TOL, err_msg="q (4,), v (N, 3)")
    assert_allclose(quat.mul_vec(qs, v[9]), sp(qs).apply(v[9]), atol=_TOL, err_msg="q (N, 4), v (3,)")
    assert_allclose(
        quat.mul_vec(qs, v),
        np.einsum("nij,nj->ni", quat.to_matrix(qs), v),
        atol=_TOL,
        err_msg="mul_vec = R @ v",
    )


def test_inputs_are_not_modified(qs):
    q0 = qs.copy()
    v = np.ones((len(qs), 3))
    for f in (
        quat.abs,
        quat.conj,
        quat.normalize,
        quat.to_matrix,
        quat.log,
        quat.heading,
        quat.remove_heading,
        lambda q: quat.unroll(q),
        lambda q: quat.mul_vec(q, v),
        lambda q: quat.swing_twist(q, v),
    ):
        f(qs)
    assert_allclose(qs, q0, err_msg="inputs untouched")
    assert np.all(v == 1.0)


def test_dot_angle_angle_between(qs):
    rng = np.random.default_rng(_SEED + 4)
    b = rand_quat(rng, len(qs))
    assert_allclose(quat.dot(qs, b), np.sum(qs * b, axis=-1), atol=_TOL, err_msg="dot")
    assert_allclose(quat.angle(qs), sp(qs).magnitude(), atol=1e-9, err_msg="angle")
    assert_allclose(quat.angle(-qs), quat.angle(qs), atol=_TOL, err_msg="angle sign-invariant")
    assert np.all((quat.angle(qs) >= 0.0) & (quat.angle(qs) <= np.pi + _TOL))
    assert_allclose(
        quat.angle_between(qs, b), (sp(b).inv() * sp(qs)).magnitude(), atol=1e-9, err_msg="between"
    )
    assert_allclose(quat.angle_between(qs, -qs), 0.0, atol=1e-7, err_msg="q vs -q")


# --------------------------------------------------------------------------- matrices, rotation vectors


def test_to_matrix_matches_scipy(qs):
    m = quat.to_matrix(qs)
    assert_allclose(m, sp(qs).as_matrix(), atol=_TOL, err_msg="to_matrix")
    assert_allclose(
        m @ np.swapaxes(m, -1, -2), np.broadcast_to(np.eye(3), m.shape), atol=_TOL, err_msg="orthogonal"
    )
    assert_allclose(np.linalg.det(m), 1.0, atol=_TOL, err_msg="proper")
    assert_allclose(quat.to_matrix(-qs), m, atol=_TOL, err_msg="q and -q")


def test_from_matrix_matches_scipy(qs):
    q = quat.from_matrix(sp(qs).as_matrix())
    assert_same_rotation(q, qs, err_msg="from_matrix(to_matrix(q))")
    assert np.all(q[:, 0] >= 0.0), "w >= 0"
    assert_same_rotation(q, from_sp(Rotation.from_matrix(sp(qs).as_matrix())), err_msg="vs scipy")


@pytest.mark.parametrize("delta", [0.0, 1e-12, 1e-8, 1e-4])
def test_from_matrix_near_half_turns(delta):
    """Half turns make w ~ 0: the trace formula alone divides by ~0 (Shepperd's branch choice matters)."""
    rng = np.random.default_rng(_SEED + 5)
    axes = np.concatenate([np.eye(3), -np.eye(3), rng.normal(size=(200, 3))])
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    q = quat.from_axis_angle(axes, np.pi - delta)
    m = Rotation.from_rotvec(axes * (np.pi - delta)).as_matrix()
    got = quat.from_matrix(m)
    assert_same_rotation(got, q, tol=1e-12, err_msg=f"angle pi - {delta}")
    assert_allclose(np.linalg.norm(got, axis=-1), 1.0, atol=_TOL)
    assert_allclose(quat.to_matrix(got), m, atol=_TOL, err_msg="matrix round trip")


def test_rotvec_and_axis_angle_match_scipy(qs):
    rv = quat.to_rotvec(qs)
    assert_allclose(rv, sp(quat.abs(qs)).as_rotvec(), atol=1e-9, err_msg="to_rotvec")
    assert np.all(np.linalg.norm(rv, axis=-1) <= np.pi + _TOL)
    rng = np.random.default_rng(_SEED + 6)
    v = rng.normal(size=(_N, 3)) * 2.0
    assert_same_rotation(quat.from_rotvec(v), from_sp(Rotation.from_rotvec(v)), err_msg="from_rotvec")
    ax, ang = quat.to_axis_angle(qs)
    assert_allclose(np.linalg.norm(ax, axis=-1), 1.0, atol=_TOL, err_msg="unit axis")
    assert_same_rotation(quat.from_axis_angle(ax, ang), qs, tol=1e-9, err_msg="axis-angle round trip")
    ax0, ang0 = quat.to_axis_angle(quat.identity())
    assert_allclose(ax0, [1.0, 0.0, 0.0], err_msg="identity axis is +X")
    assert ang0 == 0.0
    # the axis is normalized; axis and angle broadcast against each other
    assert_same_rotation(
        quat.from_axis_angle([0.0, 0.0, 5.0], np.pi / 2),
        from_sp(Rotation.from_euler("z", np.pi / 2)),
        err_msg="unnormalized axis",
    )
    many = quat.from_axis_angle([0.0, 0.0, 1.0], np.array([0.1, 0.2, 0.3]))
    assert many.shape == (3, 4)
    assert_same_rotation(
        many,
        from_sp(Rotation.from_euler("z", np.array([0.1, 0.2, 0.3])[:, None])),
        err_msg="(3,) axis, (K,) angles",
    )


def test_from_axis_angle_many_axes_one_angle():
    """Regression: an (N, 3) axis with a scalar angle failed to concatenate ((N,) vs (1,) leading shapes)."""
    axes = np.eye(3)
    q = quat.from_axis_angle(axes, np.pi / 3)
    assert q.shape == (3, 4)
    assert_same_rotation(
        q, from_sp(Rotation.from_rotvec(axes * np.pi / 3)), err_msg="(N, 3) axes, scalar angle"
    )


# --------------------------------------------------------------------------- exp / log


def test_exp_log_match_scipy_and_round_trip():
    rng = np.random.default_rng(_SEED + 7)
    v = rng.normal(size=(_N, 3))
    v *= rng.uniform(0.0, np.pi / 2 - 1e-6, size=(_N, 1)) / np.linalg.norm(v, axis=-1, keepdims=True)
    q = quat.exp(v)
    assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=_TOL)
    assert_same_rotation(q, from_sp(Rotation.from_rotvec(2.0 * v)), err_msg="exp(v) = rotation by 2 v")
    assert_allclose(quat.log(q), v, atol=_TOL, err_msg="log(exp(v))")
    qq = rand_quat(rng)
    assert_same_rotation(quat.exp(quat.log(qq)), qq, err_msg="exp(log(q))")
    assert_allclose(quat.log(-qq), quat.log(qq), atol=_TOL, err_msg="log takes the w >= 0 branch")
    assert_allclose(quat.to_rotvec(qq), 2.0 * quat.log(qq), atol=_TOL)


@pytest.mark.parametrize("scale", [0.0, 1e-300, 1e-15, 1e-9, 1e-8 * (1 - 1e-9), 1e-8 * (1 + 1e-9), 1e-6])
def test_exp_log_small_angle_branches(scale):
    """Both sides of the eps = 1e-8 small-angle switch agree with the Taylor series to rounding."""
    rng = np.random.default_rng(_SEED + 8)
    d = rng.normal(size=(50, 3))
    v = scale * d / np.linalg.norm(d, axis=-1, keepdims=True)
    q = quat.exp(v)
    h = np.linalg.norm(v, axis=-1, keepdims=True)
    series = np.concatenate([1.0 - h**2 / 2.0, v * (1.0 - h**2 / 6.0)], axis=-1)
    assert np.all(np.isfinite(q))
    assert_allclose(q, series, rtol=1e-15, atol=1e-300, err_msg="exp series")
    assert_allclose(quat.log(q), v, rtol=1e-12, atol=1e-300, err_msg="log(exp(v)) small")
    assert_allclose(quat.log(-q), v, rtol=1e-12, atol=1e-300, err_msg="log(-exp(v)) small")


def test_exp_log_half_turns():
    q = special_quats()
    assert np.all(np.isfinite(quat.log(q)))
    assert_same_rotation(quat.exp(quat.log(q)), q, err_msg="half and quarter turns")
    assert_allclose(
        np.linalg.norm(quat.log(quat.from_axis_angle([0.0, 1.0, 0.0], np.pi))), np.pi / 2, atol=_TOL
    )


# --------------------------------------------------------------------------- Euler angles


@pytest.mark.parametrize("extrinsic", [False, True])
@pytest.mark.parametrize("order", ORDERS)
def test_euler_matches_scipy(order, extrinsic):
    rng = np.random.default_rng(_SEED + 9)
    e = rng.uniform(-np.pi, np.pi, size=(_N, 3))
    e[:, 1] = rng.uniform(-np.pi / 2 + 0.01, np.pi / 2 - 0.01, size=_N)  # away from gimbal lock
    seq = order if extrinsic else order.upper()  # scipy: upper case = intrinsic, lower case = extrinsic
    q = quat.from_euler(e, order, extrinsic=extrinsic)
    assert_same_rotation(
        q, from_sp(Rotation.from_euler(seq, e)), err_msg=f"from_euler {order} ext={extrinsic}"
    )
    assert_allclose(
        quat.to_euler(q, order, extrinsic=extrinsic),
        e,
        atol=1e-10,
        err_msg=f"to_euler {order} ext={extrinsic} (unique angles away from lock)",
    )
    assert_allclose(quat.to_euler(q, order, extrinsic), sp(q).as_euler(seq), atol=1e-10, err_msg="vs scipy")


@pytest.mark.parametrize("order", ORDERS)
def test_euler_intrinsic_convention_and_upper_case(order):
    """Intrinsic ``"zyx"`` is ``Rz(e0) @ Ry(e1) @ Rx(e2)``; extrinsic reverses the product."""
    e = np.array([0.3, -0.7, 1.1])
    mats = [Rotation.from_euler(ax, a).as_matrix() for ax, a in zip(order, e)]
    assert_allclose(quat.to_matrix(quat.from_euler(e, order)), mats[0] @ mats[1] @ mats[2], atol=_TOL)
    assert_allclose(
        quat.to_matrix(quat.from_euler(e, order, extrinsic=True)), mats[2] @ mats[1] @ mats[0], atol=_TOL
    )
    assert_allclose(
        quat.from_euler(e, order.upper()), quat.from_euler(e, order), atol=_TOL, err_msg="upper case"
    )


@pytest.mark.parametrize("extrinsic", [False, True])
@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize(
    "mid",
    [
        np.pi / 2,
        -np.pi / 2,
        np.pi / 2 - 1e-15,
        np.pi / 2 - 1e-12,
        -np.pi / 2 + 1e-10,
        np.pi / 2 - 1e-7,
        np.pi / 2 - 1e-4,
    ],
)
def test_euler_round_trip_at_gimbal_lock(order, extrinsic, mid):
    """Compared by rotation: at lock the angles are not unique. Regression: near lock (|cos b| ~ 1e-10) the
    old arcsin/threshold scheme lost ~1e-7 rad; the last angle is now solved from the first two."""
    rng = np.random.default_rng(_SEED + 10)
    e = rng.uniform(-np.pi, np.pi, size=(_N, 3))
    e[:, 1] = mid
    if extrinsic:
        e = e[:, ::-1]  # the middle angle is the middle one in both readings
    q = quat.from_euler(e, order, extrinsic)
    back = quat.to_euler(q, order, extrinsic)
    assert np.all(np.isfinite(back))
    assert_same_rotation(
        quat.from_euler(back, order, extrinsic), q, tol=1e-12, err_msg=f"{order} ext={extrinsic} mid={mid}"
    )
    assert np.all(np.abs(back[:, 1]) <= np.pi / 2 + _TOL), "middle angle in [-pi/2, pi/2]"


@pytest.mark.parametrize("order", ORDERS)
def test_euler_exact_lock_puts_everything_in_first_angle(order):
    e = np.array([[0.4, np.pi / 2, -0.3], [1.0, -np.pi / 2, 0.5]])
    back = quat.to_euler(quat.from_euler(e, order), order)
    assert_allclose(back[:, 2], 0.0, atol=1e-12, err_msg="last angle zero at lock")
    assert_allclose(np.abs(back[:, 1]), np.pi / 2, atol=1e-7)


def test_euler_bad_order_raises():
    with pytest.raises(
        ParameterError, match=r"^Euler order must be one of xyz, xzy, yxz, yzx, zxy, zyx, got 'xyx'$"
    ):
        quat.from_euler(np.zeros(3), "xyx")
    with pytest.raises(ParameterError, match="got 'ab'"):
        quat.to_euler(quat.identity(), "ab")


# --------------------------------------------------------------------------- interpolation


def test_slerp_endpoints_midpoint_and_scipy():
    rng = np.random.default_rng(_SEED + 11)
    a, b = rand_quat(rng, 100), rand_quat(rng, 100)
    assert_same_rotation(quat.slerp(a, b, 0.0), a, err_msg="t=0")
    assert_same_rotation(quat.slerp(a, b, 1.0), b, err_msg="t=1")
    mid = quat.slerp(a, b, 0.5)
    assert_allclose(quat.angle_between(mid, a), quat.angle_between(mid, b), atol=1e-10, err_msg="midpoint")
    assert_allclose(2 * quat.angle_between(mid, a), quat.angle_between(a, b), atol=1e-10)
    assert_same_rotation(mid, quat.nlerp(a, b, 0.5), err_msg="nlerp midpoint is the slerp midpoint")
    for i in range(5):
        t = rng.uniform(size=7)
        oracle = Slerp([0.0, 1.0], sp(np.stack([a[i], b[i]])))(t)
        assert_same_rotation(quat.slerp(a[i], b[i], t), from_sp(oracle), err_msg="vs scipy Slerp")
    assert_same_rotation(quat.slerp(a, -b, 0.3), quat.slerp(a, b, 0.3), err_msg="shortest arc, sign of b")


def test_slerp_constant_angular_speed():
    rng = np.random.default_rng(_SEED + 12)
    a, b = rand_quat(rng, 20), rand_quat(rng, 20)
    t = np.linspace(0.0, 1.0, 41)[:, None]
    path = quat.slerp(a, b, t)  # (41, 20, 4)
    steps = quat.angle_between(path[1:], path[:-1])
    assert_allclose(
        steps,
        np.broadcast_to(quat.angle_between(a, b) / 40, steps.shape),
        atol=1e-10,
        err_msg="equal angle per equal t",
    )
    # the whole path lies on the great arc: the angle from a grows linearly
    assert_allclose(quat.angle_between(path, a), t * quat.angle_between(a, b), atol=1e-10)


def test_slerp_nearly_equal_rotations_use_the_fallback():
    rng = np.random.default_rng(_SEED + 13)
    a = rand_quat(rng, 50)
    for d in (0.0, 1e-12, 1e-9, 1e-7):
        b = quat.mul(quat.from_axis_angle(rng.normal(size=(50, 3)), d), a)
        for t in (0.0, 0.25, 1.0):
            got = quat.slerp(a, b, t)
            assert np.all(np.isfinite(got))
            assert_allclose(np.linalg.norm(got, axis=-1), 1.0, atol=_TOL)
            assert_allclose(quat.angle_between(got, a), t * d, atol=1e-12, err_msg=f"d={d} t={t}")


def test_nlerp_endpoints_and_shortest_arc():
    rng = np.random.default_rng(_SEED + 14)
    a, b = rand_quat(rng, 50), rand_quat(rng, 50)
    assert_same_rotation(quat.nlerp(a, b, 0.0), a)
    assert_same_rotation(quat.nlerp(a, b, 1.0), b)
    assert_same_rotation(quat.nlerp(a, -b, 0.4), quat.nlerp(a, b, 0.4), err_msg="sign of b")


def test_average_of_identical_rotations():
    rng = np.random.default_rng(_SEED + 15)
    q = rand_quat(rng, 1)[0]
    many = np.tile(q, (9, 1))
    many[::2] *= -1.0
    assert_same_rotation(quat.average(many), q, err_msg="identical inputs, mixed signs")
    assert quat.average(many)[0] >= 0.0
    assert_same_rotation(quat.average(q[None]), q, err_msg="single rotation")


def test_average_matches_scipy_mean_and_is_sign_invariant():
    rng = np.random.default_rng(_SEED + 16)
    for k in range(10):
        q = rand_quat(rng, 8)
        center = rand_quat(rng, 1)[0]
        q = quat.mul(center, quat.from_rotvec(rng.normal(size=(8, 3)) * 0.5))  # a plausible cluster
        w = rng.uniform(0.1, 2.0, size=8)
        got = quat.average(q, w)
        assert_same_rotation(got, from_sp(sp(q).mean(weights=w)), tol=1e-10, err_msg=f"weighted mean {k}")
        assert_same_rotation(quat.average(q), from_sp(sp(q).mean()), tol=1e-10, err_msg=f"mean {k}")
        flips = np.where(rng.uniform(size=(8, 1)) < 0.5, -1.0, 1.0)
        assert_same_rotation(quat.average(q * flips, w), got, tol=1e-10, err_msg="sign-invariant")
        assert_same_rotation(quat.average(q, 3.0 * w), got, tol=1e-10, err_msg="scale of weights")


def test_average_two_rotations_is_slerp_for_small_angles():
    """The chordal mean of two rotations differs from slerp by O(angle^3); measured <= 0.016 angle^3."""
    rng = np.random.default_rng(_SEED + 17)
    for _ in range(50):
        a = rand_quat(rng, 1)[0]
        theta = rng.uniform(0.0, 0.2)
        b = quat.mul(quat.from_axis_angle(rng.normal(size=3), theta), a)
        t = rng.uniform()
        got = quat.average(np.stack([a, b]), np.array([1.0 - t, t]))
        assert quat.angle_between(got, quat.slerp(a, b, t)) <= 0.02 * theta**3 + 1e-12
    a, b = rand_quat(rng, 2)
    assert_same_rotation(
        quat.average(np.stack([a, b])), quat.slerp(a, b, 0.5), tol=1e-10, err_msg="equal weights"
    )


def test_average_along_axis_and_bad_weights():
    rng = np.random.default_rng(_SEED + 18)
    q = rand_quat(rng, 5 * 3).reshape(5, 3, 4)
    got = quat.average(q, axis=0)
    assert got.shape == (3, 4)
    for j in range(3):
        assert_same_rotation(got[j], quat.average(q[:, j]), tol=1e-10, err_msg=f"column {j}")
    got1 = quat.average(q, axis=1)
    assert got1.shape == (5, 4)
    assert_same_rotation(got1[2], quat.average(q[2]), tol=1e-10, err_msg="axis=1")
    with pytest.raises(ParameterError, match=r"average weights must be non-negative, got minimum -1.0"):
        quat.average(q[:, 0], np.array([1.0, 1.0, -1.0, 1.0, 1.0]))


def test_average_one_weight_per_rotation_along_axis():
    """Regression: 1-D weights for a batch ``(N, J, 4)`` were broadcast against the last batch axis ``J``: an
    error when N != J, and silently wrong weights when N == J."""
    rng = np.random.default_rng(_SEED + 26)
    for n, j in ((4, 4), (5, 3)):
        center = rand_quat(rng, j)
        q = quat.mul(center, quat.from_rotvec(rng.normal(size=(n, j, 3)) * 0.4))
        w = rng.uniform(0.1, 2.0, size=n)
        got = quat.average(q, w, axis=0)
        for k in range(j):
            assert_same_rotation(got[k], quat.average(q[:, k], w), tol=1e-10, err_msg=f"N={n} column {k}")
        got1 = quat.average(np.swapaxes(q, 0, 1), w, axis=1)
        assert_same_rotation(got1, got, tol=1e-10, err_msg="axis=1")
        assert_same_rotation(quat.average(q, w[:, None], axis=0), got, tol=1e-10, err_msg="explicit (N, 1)")


def test_unroll_makes_a_continuous_path():
    rng = np.random.default_rng(_SEED + 19)
    q = quat.from_rotvec(np.cumsum(rng.normal(size=(60, 4, 3)) * 0.2, axis=0))
    flipped = q * np.where(rng.uniform(size=(60, 4, 1)) < 0.5, -1.0, 1.0)
    u = quat.unroll(flipped)
    assert np.all(np.sum(u[1:] * u[:-1], axis=-1) >= 0.0), "consecutive in one hemisphere"
    assert_same_rotation(u, q, err_msg="same rotations")
    assert_allclose(u[0], flipped[0], err_msg="first frame kept")
    ua = quat.unroll(np.swapaxes(flipped, 0, 1), axis=1)
    assert_allclose(ua, np.swapaxes(u, 0, 1), err_msg="axis=1")
    assert_allclose(quat.unroll(q[:1]), q[:1])


# --------------------------------------------------------------------------- between


def test_between_maps_u_to_v_along_the_shortest_arc():
    rng = np.random.default_rng(_SEED + 20)
    u = rng.normal(size=(_N, 3)) * rng.uniform(0.1, 5.0, size=(_N, 1))
    v = rng.normal(size=(_N, 3))
    q = quat.between(u, v)
    un = u / np.linalg.norm(u, axis=-1, keepdims=True)
    vn = v / np.linalg.norm(v, axis=-1, keepdims=True)
    assert_allclose(quat.mul_vec(q, un), vn, atol=_TOL, err_msg="maps u to v")
    assert_allclose(
        quat.angle(q),
        np.arccos(np.clip(np.sum(un * vn, axis=-1), -1, 1)),
        atol=1e-7,
        err_msg="angle is the angle between u and v",
    )
    ax, _ = quat.to_axis_angle(q)
    c = np.cross(un, vn)
    assert_allclose(ax, c / np.linalg.norm(c, axis=-1, keepdims=True), atol=1e-9, err_msg="axis along u x v")
    for i in range(20):  # scipy's minimal rotation aligning one vector pair
        oracle, _ = Rotation.align_vectors(v[i][None], u[i][None])
        assert_same_rotation(q[i], from_sp(oracle), tol=1e-12, err_msg=f"vs scipy align_vectors {i}")


def test_between_parallel_opposite_and_zero():
    rng = np.random.default_rng(_SEED + 21)
    u = np.concatenate([np.eye(3), -np.eye(3), rng.normal(size=(20, 3))])
    assert_same_rotation(quat.between(u, 2.0 * u), quat.identity((len(u),)), err_msg="parallel")
    q = quat.between(u, -u)
    assert_allclose(quat.angle(q), np.pi, atol=_TOL, err_msg="opposite: half turn")
    un = u / np.linalg.norm(u, axis=-1, keepdims=True)
    assert_allclose(quat.mul_vec(q, un), -un, atol=_TOL, err_msg="opposite maps u to -u")
    assert_same_rotation(quat.between(np.zeros(3), [1.0, 0.0, 0.0]), quat.identity(), err_msg="zero u")
    assert_same_rotation(quat.between([0.0, 1.0, 0.0], np.zeros(3)), quat.identity(), err_msg="zero v")
    assert_same_rotation(quat.between(np.zeros(3), np.zeros(3)), quat.identity(), err_msg="both zero")


@pytest.mark.parametrize("delta", [1e-3, 1e-5, 1e-7, 1e-9, 1e-12])
def test_between_nearly_opposite(delta):
    """Regression: directions within ~4.5e-5 rad of opposite were snapped to an exact half turn, so
    ``between(u, v)`` mapped ``u`` to ``-u`` instead of ``v`` (error up to 4.5e-5)."""
    rng = np.random.default_rng(_SEED + 22)
    u = rng.normal(size=(200, 3))
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    perp = np.cross(u, rng.normal(size=(200, 3)))
    perp /= np.linalg.norm(perp, axis=-1, keepdims=True)
    v = -u * np.cos(delta) + perp * np.sin(delta)
    q = quat.between(u, v)
    assert_allclose(quat.mul_vec(q, u), v, atol=1e-12, err_msg=f"maps u to v, delta={delta}")
    assert_allclose(quat.angle(q), np.pi - delta, atol=1e-9, err_msg="shortest arc")


# --------------------------------------------------------------------------- heading and swing-twist


def test_heading_of_from_heading():
    h = np.concatenate([np.linspace(-np.pi + 1e-9, np.pi, 101), [np.pi, 0.0, -0.0]])
    assert_allclose(quat.heading(quat.from_heading(h)), h, atol=_TOL, err_msg="heading(from_heading(h))")
    assert_allclose(quat.heading(-quat.from_heading(h)), h, atol=_TOL, err_msg="sign-invariant")
    assert_same_rotation(
        quat.from_heading(h), from_sp(Rotation.from_euler("z", h[:, None])), err_msg="about +Z"
    )


def test_heading_range_is_minus_pi_exclusive():
    """Regression: a half turn about -Z reported -pi, outside the documented (-pi, pi]."""
    for q in (quat.from_heading(-np.pi), quat.from_heading(np.pi), -quat.from_heading(np.pi)):
        assert quat.heading(q) == pytest.approx(np.pi, abs=_TOL)
    q = quat.from_heading(-np.pi)
    assert quat.heading(q, forward=[1.0, 0.0, 0.0]) == pytest.approx(np.pi, abs=1e-9)


def test_heading_is_twist_about_up_and_remove_heading(qs):
    h = quat.heading(qs)
    assert np.all((h > -np.pi) & (h <= np.pi + _TOL))
    _, twist = quat.swing_twist(qs, [0.0, 0.0, 1.0])
    assert_same_rotation(quat.from_heading(h), twist, tol=1e-9, err_msg="heading = twist about +Z")
    r = quat.remove_heading(qs)
    assert_allclose(quat.heading(r), 0.0, atol=1e-9, err_msg="removed rotation has zero heading")
    assert_same_rotation(quat.mul(quat.from_heading(h), r), qs, err_msg="heading * rest == q")
    # a heading applied in the world frame adds to the heading
    rng = np.random.default_rng(_SEED + 23)
    dh = rng.uniform(-1.0, 1.0, size=len(qs))
    moved = quat.heading(quat.mul(quat.from_heading(dh), qs))
    assert_allclose(np.angle(np.exp(1j * (moved - h - dh))), 0.0, atol=1e-9, err_msg="heading is additive")


def test_heading_with_forward_axis(qs):
    fwd = np.array([1.0, 0.0, 0.0])
    f = sp(qs).apply(fwd)
    ok = np.hypot(f[:, 0], f[:, 1]) > 1e-6  # the forward axis is not vertical
    h = quat.heading(qs, forward=fwd)
    assert_allclose(h[ok], np.arctan2(f[ok, 1], f[ok, 0]), atol=1e-9, err_msg="azimuth of forward")
    r = quat.remove_heading(qs[ok], forward=fwd)
    assert_allclose(quat.heading(r, forward=fwd), 0.0, atol=1e-9, err_msg="removed, forward")
    rf = quat.mul_vec(r, fwd)
    assert_allclose(rf[:, 1], 0.0, atol=1e-9)
    assert np.all(rf[:, 0] >= -1e-9), "forward points at +X after removal"
    lying = quat.mul(quat.from_heading(0.7), quat.from_axis_angle([0.0, 1.0, 0.0], np.pi / 2 - 0.2))
    assert quat.heading(lying, forward=fwd) == pytest.approx(0.7, abs=1e-12)


def test_swing_twist_decomposition(qs):
    rng = np.random.default_rng(_SEED + 24)
    axis = rng.normal(size=(len(qs), 3)) * 3.0
    swing, twist = quat.swing_twist(qs, axis)
    an = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    assert_same_rotation(quat.mul(swing, twist), qs, err_msg="swing * twist == q")
    assert_allclose(np.cross(twist[:, 1:], an), 0.0, atol=_TOL, err_msg="twist axis parallel to axis")
    assert_allclose(np.sum(swing[:, 1:] * an, axis=-1), 0.0, atol=_TOL, err_msg="swing axis perpendicular")
    assert_allclose(np.linalg.norm(twist, axis=-1), 1.0, atol=_TOL)
    # a pure twist is all twist; a pure swing is all swing
    pure = quat.from_axis_angle(an, rng.uniform(-3, 3, size=len(qs)))
    s2, t2 = quat.swing_twist(pure, an)
    assert_same_rotation(t2, pure, err_msg="pure twist")
    assert_same_rotation(s2, quat.identity((len(qs),)), err_msg="pure twist has no swing")
    # one axis for all
    s3, t3 = quat.swing_twist(qs, [0.0, 0.0, 2.0])
    assert_same_rotation(quat.mul(s3, t3), qs, err_msg="shared axis")


def test_swing_twist_half_turn_perpendicular_to_axis():
    q = quat.from_axis_angle([1.0, 0.0, 0.0], np.pi)
    swing, twist = quat.swing_twist(q, [0.0, 0.0, 1.0])
    assert_same_rotation(twist, quat.identity(), err_msg="undefined twist -> identity")
    assert_same_rotation(swing, q, err_msg="all swing")


# --------------------------------------------------------------------------- fk / ik


def _loop_fk(local_rot, local_pos, parents):
    """Independent reference: scipy rotations and a dictionary walk."""
    gr, gp = {}, {}
    for j, p in enumerate(parents):
        r = sp(local_rot[j])
        if p < 0:
            gr[j], gp[j] = r, local_pos[j]
        else:
            gr[j], gp[j] = gr[p] * r, gp[p] + gr[p].apply(local_pos[j])
    return np.array([from_sp(gr[j]) for j in range(len(parents))]), np.array(
        [gp[j] for j in range(len(parents))]
    )


def test_fk_matches_scipy_chain_and_ik_inverts_it():
    rng = np.random.default_rng(_SEED + 25)
    parents = np.array([-1, 0, 1, 2, 1, 4, 0, 6])
    lr = rand_quat(rng, 3 * 8).reshape(3, 8, 4)
    lp = rng.normal(size=(3, 8, 3))
    gr, gp = quat.fk(lr, lp, parents)
    for f in range(3):
        rr, rp = _loop_fk(lr[f], lp[f], parents)
        assert_same_rotation(gr[f], rr, err_msg=f"global rotations frame {f}")
        assert_allclose(gp[f], rp, atol=_TOL, err_msg=f"global positions frame {f}")
    lr2, lp2 = quat.ik(gr, gp, parents)
    assert_same_rotation(lr2, lr, err_msg="ik(fk) rotations")
    assert_allclose(lp2, lp, atol=_TOL, err_msg="ik(fk) positions")
    # leading axes broadcast: one set of offsets for every frame
    gr_b, gp_b = quat.fk(lr, lp[0], parents)
    for f in range(3):
        assert_allclose(gp_b[f], quat.fk(lr[f], lp[0], parents)[1], atol=_TOL)


# --------------------------------------------------------------------------- hypothesis properties


@_SETTINGS
@given(batch_quats, batch_quats.map(lambda q: q[::-1]))
def test_property_batched_equals_looped(a, b):
    n = min(len(a), len(b))
    a, b = a[:n], b[:n]
    v = np.linspace(-1.0, 2.0, 3 * n).reshape(n, 3)
    batched = {
        "mul": quat.mul(a, b),
        "mul_vec": quat.mul_vec(a, v),
        "to_matrix": quat.to_matrix(a),
        "from_matrix": quat.from_matrix(quat.to_matrix(a)),
        "log": quat.log(a),
        "exp": quat.exp(v),
        "slerp": quat.slerp(a, b, 0.3),
        "heading": quat.heading(a),
        "to_euler": quat.to_euler(a, "yzx"),
        "between": quat.between(v, a[:, 1:]),
        "swing": quat.swing_twist(a, v)[0],
        "twist": quat.swing_twist(a, v)[1],
        "average": quat.average(np.stack([a, b]), axis=0),
    }
    for i in range(n):
        looped = {
            "mul": quat.mul(a[i], b[i]),
            "mul_vec": quat.mul_vec(a[i], v[i]),
            "to_matrix": quat.to_matrix(a[i]),
            "from_matrix": quat.from_matrix(quat.to_matrix(a[i])),
            "log": quat.log(a[i]),
            "exp": quat.exp(v[i]),
            "slerp": quat.slerp(a[i], b[i], 0.3),
            "heading": quat.heading(a[i]),
            "to_euler": quat.to_euler(a[i], "yzx"),
            "between": quat.between(v[i], a[i, 1:]),
            "swing": quat.swing_twist(a[i], v[i])[0],
            "twist": quat.swing_twist(a[i], v[i])[1],
            "average": quat.average(np.stack([a[i], b[i]])),
        }
        for k, val in looped.items():
            if k == "average":  # sign is free; 180 degrees apart the mean is not unique
                if abs(quat.dot(a[i], b[i])) > 1e-6:
                    assert_same_rotation(batched[k][i], val, tol=1e-9, err_msg=k)
            else:
                assert_allclose(batched[k][i], val, atol=1e-12, err_msg=k)


@_SETTINGS
@given(quats, quats, vec3)
def test_property_q_and_minus_q_are_the_same_rotation(q, r, v):
    assert_allclose(quat.mul_vec(-q, v), quat.mul_vec(q, v), atol=1e-12, err_msg="mul_vec")
    assert_allclose(quat.to_matrix(-q), quat.to_matrix(q), atol=1e-12, err_msg="to_matrix")
    if q[0] != 0.0:  # a half turn has two equally valid logarithms, +-axis * pi / 2
        assert_allclose(quat.log(-q), quat.log(q), atol=1e-12, err_msg="log")
        assert_allclose(quat.to_rotvec(-q), quat.to_rotvec(q), atol=1e-12, err_msg="to_rotvec")
    assert_same_rotation(quat.exp(quat.log(-q)), q, err_msg="exp(log(-q))")
    assert_allclose(quat.angle(-q), quat.angle(q), atol=1e-12, err_msg="angle")
    assert_allclose(quat.heading(-q), quat.heading(q), atol=1e-12, err_msg="heading")
    assert_same_rotation(quat.from_matrix(quat.to_matrix(-q)), q, err_msg="from_matrix")
    assert_same_rotation(quat.mul(-q, r), quat.mul(q, r), err_msg="mul")
    if abs(quat.dot(q, r)) > 1e-6:  # 180 degrees apart, two shortest arcs (and means) exist
        assert_same_rotation(quat.slerp(-q, r, 0.7), quat.slerp(q, r, 0.7), err_msg="slerp")
        assert_same_rotation(
            quat.average(np.stack([-q, r])), quat.average(np.stack([q, r])), tol=1e-9, err_msg="average"
        )
    for order in ("xyz", "zxy"):
        assert_same_rotation(quat.from_euler(quat.to_euler(-q, order), order), q, err_msg=f"euler {order}")
    assert_same_rotation(quat.remove_heading(-q), quat.remove_heading(q), err_msg="remove_heading")


@_SETTINGS
@given(quats, vec3)
def test_property_round_trips(q, v):
    assert_same_rotation(quat.from_matrix(quat.to_matrix(q)), q, err_msg="matrix")
    assert_same_rotation(quat.from_rotvec(quat.to_rotvec(q)), q, err_msg="rotvec")
    assert_same_rotation(quat.exp(quat.log(q)), q, err_msg="exp/log")
    ax, ang = quat.to_axis_angle(q)
    assert_same_rotation(quat.from_axis_angle(ax, ang), q, err_msg="axis-angle")
    for order in ORDERS:
        for ext in (False, True):
            assert_same_rotation(
                quat.from_euler(quat.to_euler(q, order, ext), order, ext),
                q,
                err_msg=f"euler {order} ext={ext}",
            )
    assert_allclose(
        quat.inv_mul_vec(q, quat.mul_vec(q, v)),
        v,
        atol=1e-12 * (1 + np.abs(v).max()),
        err_msg="rotate and back",
    )
    assert_allclose(
        np.linalg.norm(quat.mul_vec(q, v)),
        np.linalg.norm(v),
        atol=1e-12 * (1 + np.abs(v).max()),
        err_msg="length kept",
    )
    swing, twist = quat.swing_twist(q, [0.0, 0.0, 1.0])
    assert_same_rotation(quat.mul(swing, twist), q, err_msg="swing-twist")
    assert_allclose(quat.heading(quat.remove_heading(q)), 0.0, atol=1e-9, err_msg="remove_heading")


@_SETTINGS
@given(vec3, vec3)
def test_property_between(u, v):
    q = quat.between(u, v)
    assert_allclose(np.linalg.norm(q), 1.0, atol=1e-12)
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if nu > 1e-6 and nv > 1e-6:
        assert_allclose(quat.mul_vec(q, u / nu), v / nv, atol=1e-12, err_msg="maps u to v")
    elif nu < 1e-12 or nv < 1e-12:
        assert_same_rotation(q, quat.identity(), err_msg="(near-)zero vector -> identity")
