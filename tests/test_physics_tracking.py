"""Inertia-scaled PD servos: gains table, run-time gain changes, tracking a walk from a fixed root."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from kinodyn.data import library
from kinodyn.data.skeleton import humanoid
from kinodyn.errors import ParameterError
from kinodyn.math import quat
from kinodyn.physics import tracking
from kinodyn.physics.body import BodyConfig, build_body
from kinodyn.physics.world import World

#: mean joint-angle error (deg) allowed while a hanging body tracks the walk; measured about 0.75
_TRACK_MEAN_DEG = 2.0
#: worst single joint-angle error (deg); measured about 8 (a toe at push-off)
_TRACK_MAX_DEG = 20.0


def test_gains_are_inertia_scaled(body):
    cfg = tracking.PDConfig()
    inertia = tracking.subtree_inertia(body.model(), body.map)[body.map.actuated]
    mult = np.array([cfg.gains[body.map.segments[b].cls] for b in body.map.actuated])
    w = tracking.natural_frequency(cfg)
    np.testing.assert_allclose(body.kp, mult * inertia * w * w, rtol=1e-12)
    np.testing.assert_allclose(body.kv, 2.0 * np.sqrt(mult) * inertia * w, rtol=1e-12)
    # a heavier subtree gets a stiffer servo: the lower spine carries the whole upper body
    names = [body.map.segments[b].name for b in body.map.actuated]
    assert body.kp[names.index("Spine")] > body.kp[names.index("Neck")] > 0
    # halflife: a critically damped servo halves its error in `halflife` seconds
    x = w * cfg.halflife
    assert (1 + x) * np.exp(-x) == pytest.approx(0.5)


def test_gains_table_and_overrides():
    b1 = build_body(humanoid(), pd=tracking.PDConfig(overrides={"LeftArm": 2.0}))
    b0 = build_body(humanoid())
    names = [b0.map.segments[b].name for b in b0.map.actuated]
    k = names.index("LeftArm")
    ref = tracking.DEFAULT_GAINS["upperarm"]
    assert b1.kp[k] == pytest.approx(b0.kp[k] * 2.0 / ref)
    assert b1.kp[names.index("RightArm")] == pytest.approx(b0.kp[names.index("RightArm")])
    with pytest.raises(ParameterError):
        tracking.PDConfig(halflife=0.0)
    with pytest.raises(ParameterError):
        tracking.PDConfig(overrides={"LeftArm": -1.0})


def test_gains_change_at_run_time(body):
    w = World()
    c = w.add_character(body)
    m = w.model
    acts = c.actuator_ids
    np.testing.assert_allclose(m.actuator_gainprm[acts, 0], body.kp)
    c.set_gains(0.0)  # limp
    assert np.all(m.actuator_gainprm[acts, 0] == 0) and np.all(m.actuator_biasprm[acts, 1:3] == 0)
    c.set_gains(2.0, damping=1.0, joints=["LeftArm", "left_hand"])
    names = [body.map.segments[b].name for b in body.map.actuated]
    k = names.index("LeftArm")
    assert m.actuator_gainprm[acts[k], 0] == pytest.approx(2.0 * body.kp[k])
    assert m.actuator_biasprm[acts[k], 2] == pytest.approx(-body.kv[k])
    assert m.actuator_gainprm[acts[names.index("RightArm")], 0] == 0.0
    with pytest.raises(ParameterError, match="no servo"):
        c.set_gains(1.0, joints=["Hips"])


def test_hanging_body_tracks_a_walk():
    """A body hanging from a fixed root tracks the built-in walk with a small joint error."""
    walk = library.load("walk")
    w = World()
    c = w.add_character(humanoid(), config=BodyConfig(root="fixed"))
    w.place_root(c, [0.0, 0.0, 2.0], [1.0, 0.0, 0.0, 0.0])
    c.play(walk, loop=True)
    w.switch_to_dynamic(c)
    w.run(3.0)
    sim = c.trajectory()
    k = np.round(sim.times() * walk.fps).astype(int) % (walk.num_frames - 1)
    err = np.degrees(quat.angle_between(sim.local_rot, walk.local_rot[k]))[60:, 1:]  # after 1 s, root aside
    print(f"hanging walk tracking: mean joint error {err.mean():.2f} deg, max {err.max():.1f} deg")
    assert err.mean() < _TRACK_MEAN_DEG
    assert err.max() < _TRACK_MAX_DEG


def test_stiffer_servos_track_better():
    walk = library.load("walk")
    errs = []
    for hl in (0.08, 0.03):
        w = World()
        c = w.add_character(humanoid(), config=BodyConfig(root="fixed"), pd=tracking.PDConfig(halflife=hl))
        w.place_root(c, [0.0, 0.0, 2.0], [1.0, 0.0, 0.0, 0.0])
        c.play(walk, loop=True)
        w.switch_to_dynamic(c)
        w.run(1.5)
        sim = c.trajectory()
        k = np.round(sim.times() * walk.fps).astype(int) % (walk.num_frames - 1)
        errs.append(np.degrees(quat.angle_between(sim.local_rot, walk.local_rot[k]))[30:, 1:].mean())
    assert errs[1] < errs[0]


def test_gravity_feedforward_holds_a_pose(body):
    """Without feedforward a servo sags under gravity until its error pays for the load."""
    errs = {}
    for ff in ("none", "static"):
        w = World()
        c = w.add_character(humanoid(), config=BodyConfig(root="fixed"),
                            pd=tracking.PDConfig(feedforward=ff))
        w.place_root(c, [0.0, 0.0, 2.0], [1.0, 0.0, 0.0, 0.0])
        pose = quat.identity((humanoid().num_joints,))
        j = humanoid().index("LeftArm")
        pose[j] = quat.from_axis_angle([1.0, 0.0, 0.0], np.pi / 2)  # left arm raised sideways
        from kinodyn.motion import Motion

        clip = Motion(humanoid(), np.zeros((2, 3)), np.stack([pose, pose]), 1.0)
        c.play(clip)
        w.switch_to_dynamic(c)
        w.run(1.0)
        sim = c.trajectory()
        errs[ff] = np.degrees(quat.angle_between(sim.local_rot[-1, j], pose[j]))
    assert errs["static"] < 0.25 * errs["none"]
