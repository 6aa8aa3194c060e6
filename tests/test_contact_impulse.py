"""Impulses (equations 6-10): restitution, Coulomb friction that never reverses, virtual coupling."""

import numpy as np

from kinodyn.contact import setting as S
from kinodyn.contact.collide import CollisionWorld
from kinodyn.contact.impulse import Bodies, ImpulseConfig, ImpulseStats, couple, step

REL = 0.05  # the 5 %
G = 9.81
TABLE = S.SceneObject("table", "fixed", "wood", (S.box([1.0, 1.0, 0.05]),), pos=[0, 0, 0.7])


def _run(objects, seconds, fps=60.0):
    cfg = ImpulseConfig()
    w = CollisionWorld(objects)
    b = Bodies(w)
    st = ImpulseStats()
    dt = 1.0 / (fps * cfg.substeps)
    pos, vel = [], []
    for _ in range(int(seconds * fps * cfg.substeps)):
        step(b, dt, cfg, st)
        pos.append(w.pos[-1].copy())
        vel.append(b.vel[-1].copy())
    return np.array(pos), np.array(vel), st, dt


def test_ball_dropped_on_the_table_rebounds_to_e_squared_times_its_height():
    h, r = 1.0, 0.05
    e, _ = S.coefficients("metal", "wood")
    ball = S.SceneObject("ball", "simulated", "metal", (S.sphere(r),), pos=[0, 0, 0.75 + r + h], mass=0.3)
    pos, vel, st, _ = _run([TABLE, ball], 1.2)
    z = pos[:, 2] - (0.75 + r)
    hit = int(np.argmax(vel[:, 2] > 0))  # first step moving up: just after the impact
    rebound = z[hit:].max()
    assert st.collisions >= 1
    assert abs(rebound - e * e * h) <= REL * e * e * h, rebound


def test_sliding_block_decelerates_at_mu_g_and_never_reverses():
    _, mu = S.coefficients("wood", "wood")
    block = S.SceneObject("block", "simulated", "wood", (S.box([0.1, 0.1, 0.05]),), pos=[-0.8, 0, 0.8],
                          mass=1.0, velocity=[2.0, 0.0, 0.0])
    pos, vel, _, dt = _run([TABLE, block], 1.0)
    moving = np.nonzero(vel[:, 0] > 0.2)[0]
    a = -np.polyfit(np.arange(len(moving)) * dt, vel[moving, 0], 1)[0]
    assert abs(a - mu * G) <= REL * mu * G, a
    assert vel[:, 0].min() >= -1e-3  # friction stops the sliding, never pushes it backwards
    stop = 2.0 ** 2 / (2 * mu * G)
    assert abs((pos[-1, 0] + 0.8) - stop) <= REL * stop
    assert abs(pos[:, 2] - 0.8).max() < 1e-3  # it stays on the table


def test_virtual_coupling_settles_on_the_tracker():
    hand = S.SceneObject("hand", "driven", "human", (S.sphere(0.05),), pos=[0, 0, 1.0], mass=0.5)
    w = CollisionWorld([hand])
    b = Bodies(w)
    cfg = ImpulseConfig()
    target = np.array([0.2, 0.0, 1.0])
    xs = []
    for _ in range(120):
        couple(b, 0, target, np.zeros(3), 1.0 / 60.0, 0.5, cfg)
        xs.append(w.pos[0, 0])
    xs = np.array(xs)
    assert abs(xs[-1] - 0.2) < 1e-3
    # K = 1000, R = 40, m = 0.5: damping ratio 0.89, so almost no overshoot
    assert xs.max() < 0.2 * 1.05


def test_a_ball_lying_on_the_table_rests_at_the_default_steps():
    """One step of gravity at 2 substeps of 60 Hz (0.08 m/s) is above the fixed resting speed: the
    resting threshold follows the step, so the ball gets resting impulses only and does not hop."""
    r = 0.04
    ball = S.SceneObject("ball", "simulated", "metal", (S.sphere(r),), pos=[0, 0, 0.75 + r + 1e-4], mass=0.2)
    pos, _, st, _ = _run([TABLE, ball], 1.0)
    assert st.collisions == 0 and st.resting > 0
    assert np.abs(pos[:, 2] - (0.75 + r)).max() < 1e-3
