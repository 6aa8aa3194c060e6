"""The batched crowd: contacts between characters, balls, pushes at a point, behaviours, posing."""

import numpy as np
import pytest

from kinodyn.crowd import behaviours as b
from kinodyn.crowd.crowd import Crowd, CrowdConfig, Prop, grid
from kinodyn.errors import ParameterError


@pytest.mark.parametrize("shape", ["capsule", "ellipsoid"])
def test_characters_collide_with_each_other(shape):
    c = Crowd([[0.0, 0.0], [1.5, 0.0]], [0.0, np.pi], pose=False, config=CrowdConfig(body_contact=shape))
    c.ai.kind[:] = b.GOTO
    c.ai.target[:] = [[3.0, 0.0], [-1.5, 0.0]]  # walk through each other
    gap = []
    for _ in range(180):
        c.step()
        gap.append(np.linalg.norm(c.state.r[0, :2] - c.state.r[1, :2]))
    assert min(gap) > 0.2, "the bodies may not pass through each other"


@pytest.mark.parametrize("shape", ["capsule", "ellipsoid"])
def test_each_pair_touches_through_its_contact_shape(shape):
    """Characters touch each other through the configured shape only; the floor and balls touch the
    ellipsoids (the capsule is as tall as the body, with the cross-section area of the ellipsoid)."""
    import mujoco

    c = Crowd([[0.0, 0.0], [0.22, 0.0]], pose=False, config=CrowdConfig(balls=1, body_contact=shape))
    c.throw([-0.6, 0.0, 0.8], [3.0, 0.0, 0.0])
    m = c.model
    kinds = set()
    for _ in range(30):
        c.step()
        con = c.data.contact[: c.data.ncon]
        kinds |= {tuple(sorted((int(m.geom_type[a]), int(m.geom_type[b])))) for a, b in zip(con.geom1, con.geom2)}
    g = mujoco.mjtGeom
    plane, sphere, ell, cap = (int(t) for t in (g.mjGEOM_PLANE, g.mjGEOM_SPHERE, g.mjGEOM_ELLIPSOID, g.mjGEOM_CAPSULE))
    between = (cap, cap) if shape == "capsule" else (ell, ell)
    assert kinds == {(plane, ell), between, (sphere, ell), (plane, sphere)}, kinds
    if shape == "capsule":
        capsule = m.geom_type == cap
        radius, half = c.body.contact_capsule
        np.testing.assert_allclose(m.geom_size[capsule][:, :2], [[radius, half]] * 2)
        np.testing.assert_allclose(np.pi * radius ** 2, np.pi * c.body.depth * c.body.width)
        np.testing.assert_allclose(radius + half, c.body.height / 2)


def test_controller_forces_enter_as_mujocos_generalized_forces():
    """:func:`generalized_forces` against MuJoCo's own mapping of a force and torque at the centre of
    mass (``mj_applyFT``, what ``xfrc_applied`` does) for tilted, turned bodies."""
    import mujoco

    from kinodyn.crowd.crowd import generalized_forces

    c = Crowd(grid(6, spacing=2.0), np.linspace(-3, 3, 6), pose=False)
    c.push(np.arange(6), np.random.default_rng(2).normal(0, 300, (6, 3)), point=c.state.r + [0, 0, 0.5])
    c.step(25)
    assert np.abs(c.state.theta_x).max() > 0.05 and np.ptp(c.state.heading) > 1.0
    m, d = c.model, c.data
    mujoco.mj_forward(m, d)  # the bodies' frames and Jacobians at the current state, as mj_step sees them
    f = np.random.default_rng(3).normal(0, 100, (6, 6))
    want = np.zeros(m.nv)
    for i in range(6):
        mujoco.mj_applyFT(m, d, f[i, :3], f[i, 3:], d.xipos[i + 1], i + 1, want)
    got = np.zeros((6, 6))
    generalized_forces(d.qpos[:42].reshape(6, 7), f, got)
    np.testing.assert_allclose(got, want[:36].reshape(6, 6), atol=1e-9)


def test_a_ball_knocks_a_character():
    c = Crowd([[0.0, 0.0]], pose=False, config=CrowdConfig(balls=1))
    c.step(10)
    x0 = c.state.r[0, 0]
    c.throw([-3.0, 0.0, 0.9], [14.0, 0.0, 1.5])
    c.step(60)
    assert c.state.r[0, 0] - x0 > 0.05, "the ball's momentum moves the body"
    assert c.ball_positions()[0, 0] < 0.5, "the ball bounces off"


def test_push_above_the_centre_tilts_toward_the_push_below_tilts_away():
    c = Crowd([[0.0, 0.0], [5.0, 0.0]], pose=False)
    c.step(5)
    r = c.state.r
    c.push([0, 1], [[500.0, 0, 0], [500.0, 0, 0]], point=r + [[0, 0, 0.5], [0, 0, -0.7]], duration=0.1)
    c.step(6)
    assert c.state.theta_x[0] > 0.02 and c.state.theta_x[1] < -0.02


def test_props_stop_characters():
    c = Crowd([[0.0, 0.0]], pose=False, props=[Prop("box", (1.5, 0.0, 0.5), (0.2, 2.0, 0.5))])
    c.ai.kind[:] = b.GOTO
    c.ai.target[:] = [[4.0, 0.0]]
    c.step(300)
    assert c.state.r[0, 0] < 1.3


def test_behaviours_move_where_they_say():
    c = Crowd(np.array([[0.0, 0.0], [0.0, 5.0], [10.0, 0.0], [10.0, 4.0], [-10.0, 0.0]]), pose=False)
    c.ai.kind[:] = [b.GOTO, b.FLEE, b.IDLE, b.FOLLOW, b.WANDER]
    c.ai.target[0] = [4.0, 0.0]
    c.ai.target[1] = [0.0, 3.0]
    c.ai.leader[3] = 0
    start = c.state.r[:, :2].copy()
    c.step(480)
    p = c.state.r[:, :2]
    assert np.linalg.norm(p[0] - [4.0, 0.0]) < 0.6, "go to"
    assert np.linalg.norm(p[1] - [0.0, 3.0]) > 5.0, "flee"
    assert np.linalg.norm(p[2] - start[2]) < 0.05, "idle"
    assert np.linalg.norm(p[3] - p[0]) < 2.5, "follow"
    assert np.linalg.norm(p[4] - start[4]) > 3.0, "wander"


def test_walking_advances_the_phase_and_moves_the_feet():
    c = Crowd([[0.0, 0.0]])
    c.ai.kind[:] = b.GOTO
    c.ai.target[:] = [[20.0, 0.0]]
    c.step(60)
    c.start_recording()
    c.step(120)
    m = c.motions()[0]
    feet = m.global_positions()[:, [m.skeleton.index("LeftFoot"), m.skeleton.index("RightFoot")]]
    assert np.ptp(feet[:, 0, 0] - feet[:, 1, 0]) > 0.3, "the feet swing past each other"
    assert m.global_positions()[:, :, 2].min() > -0.05, "nothing goes deep into the floor"


def test_pose_is_shown_in_the_body_frame():
    from kinodyn.crowd.interpolate import interpolate
    from kinodyn.math import quat

    c = Crowd(grid(5, spacing=3.0), np.linspace(-2, 2, 5))
    c.push(np.arange(5), [[300.0, 100.0, 0.0]] * 5)
    c.step(20)
    rot, root = interpolate(c.keyframes, c.points, c.behaviour_weights, c.side_weight)
    s = c.state
    np.testing.assert_allclose(c.root_pos, s.r + quat.mul_vec(s.quat, root), atol=1e-9)
    want = rot.copy()
    want[:, 0] = quat.mul(s.quat, rot[:, 0])
    # the crowd sums its rotations in float32 (shown and recorded poses need no more)
    assert c.local_rot.dtype == np.float32
    np.testing.assert_allclose(quat.angle_between(c.local_rot.astype(np.float64), want), 0, atol=2e-6)


def test_bad_crowd_input():
    with pytest.raises(ParameterError, match=r"positions must be a finite \(N, 2\) array"):
        Crowd(np.zeros((3, 3)))
    with pytest.raises(ParameterError, match="who must index characters"):
        Crowd([[0.0, 0.0]], pose=False).push(3, [1.0, 0, 0])
    with pytest.raises(ParameterError, match="no ball slots"):
        Crowd([[0.0, 0.0]], pose=False, config=CrowdConfig(balls=0)).throw([0, 0, 1], [1, 0, 0])
    with pytest.raises(ParameterError, match="CrowdConfig.substeps must be an int >= 1"):
        CrowdConfig(substeps=0)
    with pytest.raises(ParameterError, match=r"CrowdConfig.body_contact must be one of \('capsule', 'ellipsoid'\)"):
        CrowdConfig(body_contact="box")


def test_compiled_behaviours_equal_the_numpy_ones():
    """The crowd's compiled :func:`decide_fast` against :func:`decide`, every behaviour, same draws."""
    from kinodyn.crowd.body import rigid_state

    n = 500
    rng = np.random.default_rng(4)
    qpos = np.concatenate([rng.uniform(-8, 8, (n, 2)), np.full((n, 1), 0.8),
                           np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))], axis=1)
    qpos[:, 3:] = [[np.cos(a / 2), 0, 0, np.sin(a / 2)] for a in rng.uniform(-3, 3, n)]
    s = rigid_state(qpos, np.zeros((n, 6)))
    states = []
    for seed in (7, 7):
        ai = b.new_ai(n, s.heading, b.AIConfig(), np.random.default_rng(seed))
        ai.kind[:] = rng.integers(0, 5, n) if not states else states[0][0].kind
        ai.target[:] = rng.uniform(-6, 6, (n, 2)) if not states else states[0][0].target
        ai.leader[:] = rng.integers(0, n, n) if not states else states[0][0].leader
        states.append((ai, (b.decide if not states else b.decide_fast)(ai, s, b.AIConfig(), 1 / 60)))
    (ai0, (v0, h0)), (ai1, (v1, h1)) = states
    assert len(set(ai0.kind.tolist())) == 5
    np.testing.assert_allclose(v1, v0, atol=1e-12)
    np.testing.assert_allclose(h1, h0, atol=1e-12)
    np.testing.assert_allclose(ai1.wander, ai0.wander, atol=1e-12)
