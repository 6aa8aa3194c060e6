"""The single rigid body and the rigid body space R (section 4.1 of the keyframe-crowd paper)."""

import numpy as np
import pytest

from kinodyn.crowd.body import BodyConfig, rigid_state, support_height, tilt_quat
from kinodyn.errors import ParameterError
from kinodyn.math import quat

_TOL = 1e-9


def _random_states(n, seed=0):
    rng = np.random.default_rng(seed)
    heading = rng.uniform(-np.pi, np.pi, n)
    tx = rng.uniform(-np.pi + 0.01, np.pi - 0.01, n)
    tz = rng.uniform(-np.pi / 2 + 0.01, np.pi / 2 - 0.01, n)
    return heading, tx, tz


def test_rigid_state_recovers_heading_and_tilts():
    heading, tx, tz = _random_states(200)
    q = quat.mul(quat.from_heading(heading), tilt_quat(tx, tz))
    qpos = np.concatenate([np.zeros((200, 3)), q], axis=1)
    s = rigid_state(qpos, np.zeros((200, 6)))
    np.testing.assert_allclose(np.cos(s.heading - heading), 1.0, atol=_TOL, err_msg="heading")
    np.testing.assert_allclose(s.theta_x, tx, atol=1e-7, err_msg="theta_x")
    np.testing.assert_allclose(s.theta_z, tz, atol=1e-7, err_msg="theta_z")


def test_tilt_definitions_match_the_paper():
    """sin(theta_z) = e_yr . e_xc (up . left); theta_x leans the up axis toward forward."""
    heading, tx, tz = _random_states(100, seed=1)
    q = quat.mul(quat.from_heading(heading), tilt_quat(tx, tz))
    s = rigid_state(np.concatenate([np.zeros((100, 3)), q], axis=1), np.zeros((100, 6)))
    up = quat.mul_vec(q, [0.0, 0.0, 1.0])
    np.testing.assert_allclose(np.sin(s.theta_z), np.sum(up * s.left, axis=1), atol=_TOL)
    np.testing.assert_allclose(np.tan(s.theta_x), np.sum(up * s.forward, axis=1) / up[:, 2], rtol=1e-6)
    np.testing.assert_allclose(s.forward[:, 2], 0.0, atol=_TOL, err_msg="forward lies on the floor")


def test_angular_velocity_is_converted_to_world():
    rng = np.random.default_rng(2)
    q = quat.normalize(rng.normal(size=(50, 4)))
    w_local = rng.normal(size=(50, 3))
    qvel = np.concatenate([np.zeros((50, 3)), w_local], axis=1)
    s = rigid_state(np.concatenate([np.zeros((50, 3)), q], axis=1), qvel)
    np.testing.assert_allclose(s.omega, quat.mul_vec(q, w_local), atol=_TOL)


@pytest.mark.parametrize("tx,tz", [(0.0, 0.0), (0.4, 0.0), (np.pi / 2, 0.0), (-1.0, 0.3), (0.2, -1.2)])
def test_support_height_is_the_lowest_point_of_the_shape(tx, tz):
    cfg = BodyConfig()
    # brute force: sample the ellipsoid surface, rotate by the tilt, take the lowest point
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 721), np.linspace(0, np.pi, 361))
    pts = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], -1).reshape(-1, 3)
    pts = pts * cfg.semi_axes + cfg.shape_offset
    world = quat.mul_vec(tilt_quat(tx, tz), pts)
    assert support_height(cfg, tx, tz) == pytest.approx(-world[:, 2].min(), abs=2e-4)


def test_upright_body_rests_at_its_pendulum_length():
    cfg = BodyConfig()
    assert cfg.l == pytest.approx(0.55 * 1.5)
    assert support_height(cfg, 0.0, 0.0) == pytest.approx(cfg.l)


def test_paper_defaults_and_skeleton_scaling():
    from kinodyn.data.skeleton import humanoid

    cfg = BodyConfig()
    assert (cfg.height, cfg.mass, cfg.inertia) == (1.5, 40.0, 10.0)
    big = BodyConfig.from_skeleton(humanoid(), mass=70.0)
    assert big.height == pytest.approx(humanoid().height())
    s = big.height / 1.5
    assert big.inertia == pytest.approx(10.0 * 70.0 / 40.0 * s * s)
    assert big.depth == pytest.approx(0.13 * s)


def test_bad_body_config():
    with pytest.raises(ParameterError, match="BodyConfig.mass must be a positive number"):
        BodyConfig(mass=0.0)
    with pytest.raises(ParameterError, match="depth and width must be under half the height"):
        BodyConfig(depth=0.8)
    with pytest.raises(ParameterError, match="com_height must lie in"):
        BodyConfig(com_height=2.0)


def test_compiled_state_equals_the_numpy_one():
    """The crowd's compiled pass against :func:`rigid_state` and :func:`support_height` on random
    states, upright, tilted and fallen."""
    from kinodyn.crowd.body import rigid_state_fast

    cfg = BodyConfig()
    rng = np.random.default_rng(3)
    n = 2000
    q = quat.normalize(rng.normal(size=(n, 4)) * [1.0, 0.4, 0.4, 1.0])
    q[: n // 4] = quat.normalize(rng.normal(size=(n // 4, 4)))  # any rotation, fallen ones too
    r = rng.uniform(-5, 5, (n, 3))
    r[:, 2] = rng.uniform(0.0, 1.0, n)
    qpos, qvel = np.concatenate([r, q], axis=1), rng.normal(size=(n, 6))
    ref = rigid_state(qpos, qvel)
    got, on_floor = rigid_state_fast(qpos, qvel, cfg, 0.04)
    for name in ("r", "quat", "heading", "theta_x", "theta_z", "vel", "omega", "forward", "left", "up"):
        np.testing.assert_allclose(getattr(got, name), getattr(ref, name), atol=1e-12, err_msg=name)
    expect = r[:, 2] < support_height(cfg, ref.theta_x, ref.theta_z) + 0.04
    assert 0.1 < expect.mean() < 0.9
    np.testing.assert_array_equal(on_floor, expect)
    qpos[0, 2] = 7.0
    assert rigid_state_fast(qpos, qvel, cfg, 0.04)[0].r[0, 2] == 7.0, "the state is read afresh"
