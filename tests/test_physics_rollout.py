"""Batched rollouts on two threads: the same physics as World.step, impact batches for training data."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from kinodyn.data import library
from kinodyn.data.skeleton import humanoid
from kinodyn.errors import ParameterError, SimulationDivergedError
from kinodyn.physics import rollout as R
from kinodyn.physics.body import build_body
from kinodyn.physics.world import World


@pytest.fixture(scope="module")
def body():
    return build_body(humanoid())


def _walking_world(body):
    w = World()
    c = w.add_character(body)
    c.play(library.load("walk"), loop=True)
    w.run(0.4)
    w.switch_to_dynamic(c)
    return w, c


def test_rollout_equals_world_stepping(body):
    w, _c = _walking_world(body)
    s0 = w.get_state()
    ctrl = R.clip_controls(w, 120)
    res = R.rollout(w, s0, ctrl, nthread=2)
    assert res.state.shape == (1, 120, s0.size)
    w.step(30)  # 30 frames x 4 substeps
    np.testing.assert_allclose(res.qpos[0, -1], w.data.qpos, atol=1e-10)
    np.testing.assert_allclose(res.qvel[0, -1], w.data.qvel, atol=1e-8)
    assert not res.diverged.any()
    # plain threads give the same
    th = R.threaded_rollout(w, s0, ctrl[None], nthread=2)
    np.testing.assert_allclose(th.qpos, res.qpos, atol=1e-12)


def test_many_rollouts_on_two_threads(body):
    w, c = _walking_world(body)
    s0 = w.get_state()
    states = np.repeat(s0[None], 8, axis=0)
    states[:, 1 + c.qadr] += np.linspace(0.0, 0.1, 8)  # shift the root along x
    res = R.rollout(w, states, R.clip_controls(w, 60)[None], nthread=2)
    one = R.rollout(w, states[3], R.clip_controls(w, 60)[None], nthread=1)
    np.testing.assert_allclose(res.state[3], one.state[0], atol=1e-12)
    assert res.time[0, -1] == pytest.approx(w.time + 60 * w.dt)


def test_impact_batch_for_training_data(body):
    w = World()
    c = w.add_character(body)
    c.play(library.load("walk"), loop=True)
    throws = [{"landmark": lm, "speed": sp, "direction": dr, "height": h, "time": 0.8}
              for lm, sp, dr, h in [("chest", 8.0, 0.0, 1.4), ("head", 10.0, np.pi / 2, 1.7),
                                    ("pelvis", 6.0, -np.pi / 2, 1.0), ("stomach", 9.0, np.pi, 1.2)]]
    res, info = R.impact_batch(w, c, throws, duration=0.3)
    assert res.state.shape[:2] == (4, 72)
    assert not res.diverged.any()
    # every ball hit the character: it lost speed
    for i, inf in enumerate(info):
        v0 = np.linalg.norm(inf["launch"][1])
        v1 = np.linalg.norm(res.qvel[i, -1, inf["ball_vadr"]:inf["ball_vadr"] + 3])
        assert v1 < 0.8 * v0, f"throw {i} missed"
    with pytest.raises(ParameterError):
        R.impact_batch(w, c, [])


def test_diverged_rollouts_are_flagged(body, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo logs warnings to a file in the working directory
    w, c = _walking_world(body)
    s = np.repeat(w.get_state()[None], 2, axis=0)
    s[1, 1 + w.model.nq + c.vadr + 10] = 1e12  # an absurd joint velocity
    res = R.rollout(w, s, R.clip_controls(w, 10)[None], nthread=2)
    assert res.diverged.tolist() == [False, True]
    with pytest.raises(SimulationDivergedError):
        res.check()
