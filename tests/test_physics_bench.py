"""The physics benchmark's pieces (the timings themselves live in ``kinodyn bench physics``)."""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("mujoco")

from kinodyn import bench, registry
from kinodyn.physics import bench as physics


def test_registered():
    assert registry.benchmarks()["physics"] == "kinodyn.physics.bench"
    assert bench.get("physics") is physics.run


def test_tracked_world_holds_n_characters_tracking_the_walk_3_m_apart():
    w = physics.tracked_world(4)
    assert len(w.characters) == 4
    assert all(c.mode == "dynamic" and c.clip is not None and c.ctrl_target is None for c in w.characters)
    assert w.time == pytest.approx(0.2)  # the kinematic warm-up
    # placed on a grid 3 m apart (the roots have moved a little since)
    roots = np.array([w.data.qpos[c.qadr:c.qadr + 2] for c in w.characters])
    gaps = np.linalg.norm(roots[:, None] - roots[None], axis=-1)[np.triu_indices(4, 1)]
    assert np.sort(gaps)[:4] == pytest.approx([physics.SPACING] * 4, abs=0.3)


def test_measure_world_simulates_the_asked_time_and_times_it():
    worlds = [physics.tracked_world(1), physics.tracked_world(1)]
    t0 = [w.time for w in worlds]
    frames0 = [len(w.frame_times()) for w in worlds]
    start = time.perf_counter()
    wall, cpu = physics.measure_world(worlds, 0.1)
    outer = time.perf_counter() - start
    assert [w.time - t for w, t in zip(worlds, t0)] == pytest.approx([0.1, 0.1])
    assert [len(w.frame_times()) for w in worlds] == frames0  # the timed steps record nothing
    assert 0 < wall <= outer and cpu > 0


def test_rtf_figures_are_one_measurement_in_three_units():
    sps, rtf, rtf_cpu = physics._rtf(2, 0.1, None, None, nworlds=2, repeats=1)
    substeps = physics.tracked_world(1).config.substeps
    # steps per wall second and simulated seconds per wall second come from the same best time
    assert sps / rtf == pytest.approx(physics.FPS * substeps, rel=1e-12)
    assert rtf > 0 and rtf_cpu > 0


def test_python_pd_baseline_runs_every_step_it_times():
    """Regression: the explicit Python PD diverged after 2 of 120 steps, the divergence was swallowed and
    the speedup divided by a 2-step timing. The stable one runs all its steps and keeps the body up."""
    w = physics.tracked_world(1)
    c = w.characters[0]
    pd = physics.PythonPD(w, c)
    assert np.all(w.model.actuator_gainprm[c.actuator_ids, 0] == 0)  # the engine servos are off
    from kinodyn.physics.rollout import clip_controls

    ctrl = clip_controls(w, 120)
    for i in range(120):
        pd.step(ctrl[i])
        assert np.isfinite(w.data.qvel).all() and np.abs(w.data.qvel).max() < w.config.max_speed, \
            f"diverged at step {i}"
    assert w.data.qpos[c.qadr + 2] > 0.5  # still tracking: the pelvis has not collapsed in 0.5 s
    assert physics._python_pd_rate(0.1, None, None) > 0


def test_python_pd_divergence_raises(monkeypatch):
    from kinodyn.errors import SimulationDivergedError

    def explode(self, target):
        self.world.data.qvel[:] = np.nan

    monkeypatch.setattr(physics.PythonPD, "step", explode)
    with pytest.raises(SimulationDivergedError, match="diverged at step 0"):
        physics._python_pd_rate(0.1, None, None)


def test_quick_run_measures_every_figure_at_its_count(monkeypatch):
    """--quick measures the real-time counts (no estimate under the same key) and pins numba's threads."""
    import numba

    seen = []

    def fake_rtf(n, seconds, body, walk, nworlds=1, repeats=2):  # real time up to 40 characters a world
        seen.append((n, nworlds, numba.get_num_threads()))
        r = 40.0 * nworlds / n
        return r * 240, r, r

    monkeypatch.setattr(physics, "_rtf", fake_rtf)
    monkeypatch.setattr(physics, "_rollout_rate", lambda *a: 1e5)
    monkeypatch.setattr(physics, "_python_pd_rate", lambda *a: 1e3)
    res = physics.run(quick=True)
    for key, nw in (("realtime_characters", 1), ("realtime_characters_2worlds", 2)):
        n = res.metrics[key]
        assert (n, nw, 1) in seen, f"{key} = {n} was not measured"
        assert n <= 40 * nw < max(m for m, w, _ in seen if w == nw), f"{key}: the count above was tried and failed"
    assert all(t == 1 for _, _, t in seen)
    assert not any("estimat" in v or "not measured" in v for v in res.notes.values())
