"""kinodyn.parallel: same results for any worker count and backend, resumable chunks, clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn import parallel
from kinodyn.errors import ParameterError


def seeded_chunk(tasks):
    """A chunk function: each task (seed, i) draws its own numbers."""
    rows = [np.random.default_rng([s, i]).normal(size=3) for s, i in tasks]
    return {"x": np.array(rows), "i": np.array([i for _, i in tasks])}


def counting_chunk(tasks):
    """Fails on tasks marked 'stop' (to interrupt a run)."""
    if any(t[1] == "stop" for t in tasks):
        raise RuntimeError("interrupted")
    return {"i": np.array([t[0] for t in tasks])}


def test_chunks_cover_the_tasks():
    assert parallel.chunks(10, 4) == [(0, 4), (4, 8), (8, 10)]
    assert parallel.chunks(0, 4) == []
    with pytest.raises(ParameterError):
        parallel.chunks(3, 0)


def test_same_results_for_one_and_two_workers():
    tasks = [(7, i) for i in range(23)]
    one = parallel.run(seeded_chunk, tasks, chunk_size=5, workers=1)
    two = parallel.run(seeded_chunk, tasks, chunk_size=5, workers=2)
    np.testing.assert_array_equal(one["x"], two["x"])
    np.testing.assert_array_equal(one["i"], np.arange(23)), "task order kept"


def test_an_interrupted_run_resumes_from_its_chunks(tmp_path):
    tasks = [(i, "go") for i in range(10)]
    bad = tasks[:6] + [(6, "stop")] + tasks[7:]
    with pytest.raises(RuntimeError):
        parallel.run(counting_chunk, bad, chunk_size=3, workers=1, resume_dir=tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chunk-00000.npz", "chunk-00001.npz"]
    # The finished chunks are read back, not recomputed: they would fail if they were.
    resumed = [(i, "stop") for i in range(6)] + tasks[6:]
    out = parallel.run(counting_chunk, resumed, chunk_size=3, workers=1, resume_dir=tmp_path)
    np.testing.assert_array_equal(out["i"], np.arange(10))


def test_bad_arguments():
    with pytest.raises(ParameterError, match="backend"):
        parallel.run(seeded_chunk, [(0, 1)], backend="dask")
    with pytest.raises(ParameterError, match="workers"):
        parallel.run(seeded_chunk, [(0, 1)], workers=0)
    with pytest.raises(ParameterError, match="rows"):
        parallel.run(lambda t: {"x": np.zeros(len(t) + 1)}, [(0, 1)], workers=1)
    assert parallel.run(seeded_chunk, [], workers=1) == {}


# The Ray backend is checked on the real job, in tests/test_response_classifier.py.
