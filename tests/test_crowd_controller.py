"""The inverted-pendulum controller and the state machine of figure 3, simulated in MuJoCo."""

import numpy as np
import pytest

from kinodyn.crowd.body import BodyConfig
from kinodyn.crowd.controller import (
    BALANCE,
    BRAKING,
    FALLING,
    LYING,
    STANDING_UP,
    ControllerConfig,
    lqr_gains,
)
from kinodyn.crowd.crowd import Crowd, CrowdConfig
from kinodyn.errors import ParameterError

WEAK, STRONG = 35.0, 160.0  # N s, applied over 0.1 s at 0.2 m above the centre of mass


def _pushed(directions, impulse, seconds, seed=0, pose=False):
    d = np.asarray(directions, float)
    n = len(d)
    c = Crowd(np.stack([np.arange(n) * 4.0, np.zeros(n)], axis=1), seed=seed, pose=pose,
              config=CrowdConfig(balls=0))
    c.step(15)
    c.start_recording()
    force = np.concatenate([d, np.zeros((n, 1))], axis=1) * (impulse / 0.1)
    c.push(np.arange(n), force, point=c.state.r + [0.0, 0.0, 0.2], duration=0.1)
    c.step(int(seconds * 60))
    return c


def _tilt(c):
    return np.arccos(np.clip(c.state.up[:, 2], -1, 1))


def _directions(k):
    a = np.arange(k) * 2 * np.pi / k
    return np.stack([np.cos(a), np.sin(a)], axis=1)


def test_gains_stabilize_the_linear_model():
    body, cfg = BodyConfig(), ControllerConfig()
    k = lqr_gains(body, cfg)
    m, l, i, g = body.mass, body.l, body.inertia, 9.81
    a = np.array([[0, 1, 0], [m * g * l / i, 0, 0], [0, 0, 0]])
    b = np.array([[0, 0], [-l / i, 1 / i], [1 / m, 0]])
    assert np.all(np.linalg.eigvals(a - b @ k).real < 0)


def test_weak_push_returns_upright():
    c = _pushed(_directions(4), WEAK, 4.0)
    modes = c.recording()["mode"]
    assert np.all(modes == BALANCE), "a weak push must not make it fall"
    assert np.max(_tilt(c)) < 0.03
    assert np.all(np.hypot(c.state.v_forward, c.state.v_side) < 0.05)


def test_weak_push_makes_it_step_in_the_push_direction():
    c = _pushed([[1.0, 0.0]], WEAK, 2.0)
    assert c.state.r[0, 0] > 0.15, "the body walks in the direction of the push to recover"


def _sequence(col):
    """The states in order, a settling body's returns from lying to braking merged."""
    out = [int(col[0])]
    for m in col[1:]:
        if m != out[-1]:
            out.append(int(m))
    while True:
        for k in range(len(out) - 2):
            if out[k:k + 3] == [BRAKING, LYING, BRAKING]:
                del out[k + 1:k + 3]
                break
        else:
            return out


def test_strong_push_falls_brakes_lies_still_and_stands_up():
    c = _pushed([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]], STRONG, 8.0)
    rec = c.recording()
    for i in range(3):
        assert _sequence(rec["mode"][:, i]) == [BALANCE, FALLING, BRAKING, LYING, STANDING_UP, BALANCE], i
        mode = rec["mode"][:, i]
        up = np.flatnonzero(mode == STANDING_UP)[0]
        last = np.flatnonzero(mode[:up] != LYING)[-1] + 1  # the last lying spell before standing up
        body = rec["body"][last:up, i, :3].astype(float)
        assert up - last >= 60, "it lies for at least a second"
        assert np.ptp(body[:, 0]) < 0.05 and np.ptp(body[:, 1]) < 0.05, "it lies still"
    assert np.all(_tilt(c) < 0.05), "standing again at the end"


def test_lands_face_up_or_face_down_never_on_its_side():
    c = _pushed(_directions(12), STRONG, 3.0)
    rec = c.recording()
    from kinodyn.crowd.body import rigid_state

    for i in range(12):
        lying = np.flatnonzero(rec["mode"][:, i] == LYING)
        assert len(lying), f"push direction {i} did not lay the body down"
        q = rec["body"][lying[0], i].astype(float)[None]
        s = rigid_state(q, np.zeros((1, 6)))
        assert abs(abs(s.theta_x[0]) - np.pi / 2) < 0.3, f"direction {i}: theta_x {s.theta_x[0]:.2f}"
        assert abs(s.theta_z[0]) < 0.3, f"direction {i} lies on its side: theta_z {s.theta_z[0]:.2f}"


def test_forward_fall_lands_face_down_backward_face_up():
    c = _pushed([[1.0, 0.0], [-1.0, 0.0]], STRONG, 3.0)
    rec = c.recording()
    from kinodyn.crowd.body import rigid_state

    first = [np.flatnonzero(rec["mode"][:, i] == LYING)[0] for i in range(2)]
    s = rigid_state(np.stack([rec["body"][f, i] for i, f in enumerate(first)]).astype(float), np.zeros((2, 6)))
    assert s.theta_x[0] > 1.2 and s.theta_x[1] < -1.2


def test_same_seed_same_crowd():
    from kinodyn.crowd.behaviours import WANDER

    def run(seed):
        c = Crowd(np.random.default_rng(5).uniform(-4, 4, (12, 2)), seed=seed)
        c.ai.kind[:] = WANDER
        c.push([0, 3], [[300.0, 0, 0], [0, -900.0, 0]], duration=0.1)
        c.step(90)
        return c.data.qpos.copy(), c.local_rot.copy(), c.root_pos.copy()

    a, b, other = run(7), run(7), run(8)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    assert not np.allclose(a[0], other[0])


def test_bad_controller_config():
    with pytest.raises(ParameterError, match="ControllerConfig.q_tilt must be a positive number"):
        ControllerConfig(q_tilt=-1.0)
    with pytest.raises(ParameterError, match="upright_angle < fall_angle"):
        ControllerConfig(fall_angle=1.3)


def test_compiled_controller_equals_the_numpy_one():
    """The crowd's compiled control pass against :func:`control` on random states and modes."""
    from kinodyn.crowd.body import rigid_state
    from kinodyn.crowd.controller import ControlState, control, control_kernel, pack_config
    from kinodyn.math import quat

    body, cfg = BodyConfig(), ControllerConfig()
    rng = np.random.default_rng(0)
    n = 3000
    q = quat.normalize(rng.normal(size=(n, 4)) * [1.0, 0.3, 0.3, 1.0])
    qpos = np.concatenate([rng.normal(size=(n, 3)), q], axis=1)
    qvel = rng.normal(size=(n, 6)) * 0.3
    on_floor = rng.random(n) < 0.8
    v, h = rng.normal(size=(n, 2)), rng.uniform(-3, 3, n)
    mode, timer, sf = rng.integers(0, 5, n), rng.uniform(0, 3, n), rng.uniform(-1.6, 1.6, n)
    cs = ControlState(mode.copy(), timer.copy(), sf.copy())
    f, t = control(rigid_state(qpos, qvel), cs, v, h, body, cfg, 1 / 60, on_floor)
    out = np.zeros((n, 6))
    control_kernel(qpos, qvel, on_floor, v, h, mode, timer, sf, pack_config(body, cfg), 1 / 60, out)
    np.testing.assert_array_equal(cs.mode, mode)
    np.testing.assert_allclose(cs.timer, timer, atol=1e-12)
    np.testing.assert_allclose(cs.stand_from, sf, atol=1e-12)
    np.testing.assert_allclose(out[:, :3], f, atol=1e-9)
    np.testing.assert_allclose(out[:, 3:], t, atol=1e-9)
