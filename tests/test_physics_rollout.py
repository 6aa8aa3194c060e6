"""Batched rollouts on two threads: the same physics as World.step, impact batches for training data."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from kinodyn.data import library
from kinodyn.errors import ParameterError, SimulationDivergedError, SimulationError
from kinodyn.physics import rollout as R
from kinodyn.physics.world import World


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
    assert res.bad_body[0] == "" and res.bad_body[1] == w.model.body(w.model.dof_bodyid[c.vadr + 10]).name


def test_unchecked_rollouts_read_unknown_not_fine(body, tmp_path, monkeypatch):
    """Regression: rollout(check=False) reported every rollout as not diverged."""
    monkeypatch.chdir(tmp_path)
    w, c = _walking_world(body)
    s = np.repeat(w.get_state()[None], 2, axis=0)
    s[1, 1 + w.model.nq + c.vadr + 10] = 1e12
    res = R.rollout(w, s, R.clip_controls(w, 10)[None], nthread=2, check=False)
    assert not res.checked and res.diverged is None and res.first_bad is None
    with pytest.raises(SimulationError, match="not checked") as e:
        res.check()
    assert not isinstance(e.value, SimulationDivergedError)
    assert R.rollout(w, s, R.clip_controls(w, 10)[None], nthread=2).checked


def test_a_diverging_impact_batch_raises_naming_the_throw_step_and_body(body, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    w = World()
    c = w.add_character(body)
    c.play(library.load("walk"), loop=True)
    throws = [{"landmark": "chest", "speed": 8.0, "direction": 0.0, "height": 1.4, "time": 0.3},
              {"landmark": "head", "speed": 400.0, "direction": 1.0, "height": 1.6, "time": 0.3,
               "distance": 40.0}]
    with pytest.raises(SimulationDivergedError, match=r"1 of 2 impact rollouts diverged; the first is throw 1") as e:
        R.impact_batch(w, c, throws, duration=0.2)
    assert e.value.body and e.value.body in str(e.value)
    start = round(0.3 / w.dt) - max(1, round(0.05 / w.dt))
    assert e.value.step > start
    res, info = R.impact_batch(w, c, throws, duration=0.2, on_divergence="flag")
    assert res.diverged.tolist() == [False, True]
    assert e.value.step == info[1]["start_step"] + res.first_bad[1] + 1
    with pytest.raises(ParameterError, match="on_divergence"):
        R.impact_batch(w, c, throws, on_divergence="ignore")


def test_threaded_rollout_raises_what_a_worker_raised(body, monkeypatch):
    """Regression: an exception in a worker thread was lost and the rows it did not fill came back
    uninitialised."""
    w, _c = _walking_world(body)
    s0 = np.repeat(w.get_state()[None], 4, axis=0)
    ctrl = R.clip_controls(w, 5)[None]
    calls = []
    real = mujoco.mj_step

    def flaky(m, d):
        calls.append(1)
        if len(calls) == 7:
            raise RuntimeError("engine failure in a worker")
        real(m, d)

    monkeypatch.setattr(R.mujoco, "mj_step", flaky)
    with pytest.raises(RuntimeError, match="engine failure in a worker"):
        R.threaded_rollout(w, s0, ctrl, nthread=2)
    monkeypatch.setattr(R.mujoco, "mj_step", real)
    with pytest.raises(ParameterError, match="control must be"):
        R.threaded_rollout(w, s0, ctrl[..., :3], nthread=2)
    res = R.threaded_rollout(w, s0, ctrl, nthread=2)
    assert np.isfinite(res.state).all() and not res.diverged.any()
