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
