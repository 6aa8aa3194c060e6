"""The batched crowd: contacts between characters, balls, pushes at a point, behaviours, posing."""

import numpy as np
import pytest

from kinodyn.crowd import behaviours as b
from kinodyn.crowd.crowd import Crowd, CrowdConfig, Prop, grid
from kinodyn.errors import ParameterError


def test_characters_collide_with_each_other():
    c = Crowd([[0.0, 0.0], [1.5, 0.0]], [0.0, np.pi], pose=False)
    c.ai.kind[:] = b.GOTO
    c.ai.target[:] = [[3.0, 0.0], [-1.5, 0.0]]  # walk through each other
    gap = []
    for _ in range(180):
        c.step()
        gap.append(np.linalg.norm(c.state.r[0, :2] - c.state.r[1, :2]))
    assert min(gap) > 0.2, "the bodies may not pass through each other"


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
