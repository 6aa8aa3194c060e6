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


CALLS: list = []


def counting_chunk(tasks):
    """Records the tasks it is called on (in this process: ``workers=1``); fails on tasks marked 'stop'
    (to interrupt a run)."""
    CALLS.append([t[0] for t in tasks])
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
    CALLS.clear()
    with pytest.raises(RuntimeError):
        parallel.run(counting_chunk, bad, chunk_size=3, workers=1, resume_dir=tmp_path)
    names = sorted(p.name for p in tmp_path.iterdir())
    assert [n[:12] for n in names] == ["chunk-00000-", "chunk-00001-"]
    assert all(n.endswith(".npz") for n in names)
    # The finished chunks are read back, not recomputed: only the last two chunks run again.
    CALLS.clear()
    out = parallel.run(counting_chunk, tasks, chunk_size=3, workers=1, resume_dir=tmp_path)
    np.testing.assert_array_equal(out["i"], np.arange(10))
    assert CALLS == [[6, 7, 8], [9]]


def test_a_resumed_run_reads_back_only_chunks_of_its_own_tasks(tmp_path):
    """Chunks of another run in the same folder (another seed, chunk size or function) are not taken for
    this run's; a longer run reuses the chunks it shares with a shorter one."""
    seven, eight = [(7, i) for i in range(6)], [(8, i) for i in range(6)]
    six = parallel.run(seeded_chunk, seven, chunk_size=3, workers=1, resume_dir=tmp_path)
    other = parallel.run(seeded_chunk, eight, chunk_size=3, workers=1, resume_dir=tmp_path)
    assert not np.allclose(six["x"], other["x"]), "seed 8 computed, not read back from seed 7's chunks"
    np.testing.assert_array_equal(other["x"], parallel.run(seeded_chunk, eight, chunk_size=3, workers=1)["x"])
    resized = parallel.run(seeded_chunk, seven, chunk_size=2, workers=1, resume_dir=tmp_path)
    np.testing.assert_array_equal(resized["x"], six["x"])
    CALLS.clear()
    parallel.run(counting_chunk, [(i, "go") for i in range(6)], chunk_size=3, workers=1, resume_dir=tmp_path)
    assert CALLS == [[0, 1, 2], [3, 4, 5]], "another function's chunks are not read back"
    CALLS.clear()
    longer = parallel.run(counting_chunk, [(i, "go") for i in range(9)], chunk_size=3, workers=1,
                          resume_dir=tmp_path)
    np.testing.assert_array_equal(longer["i"], np.arange(9))
    assert CALLS == [[6, 7, 8]], "the chunks shared with the shorter run are read back"
    assert parallel.chunk_key(seeded_chunk, [(7, 0)]) == parallel.chunk_key(seeded_chunk, [(7, 0)])
    assert parallel.chunk_key(seeded_chunk, [(7, 0)]) != parallel.chunk_key(counting_chunk, [(7, 0)])


def test_a_resumed_run_reads_back_only_chunks_of_its_own_context(tmp_path):
    """Chunks computed in another context (what the tasks read besides themselves: input files) are
    computed again; the same context reads them back; no context keeps the keys it had."""
    tasks = [(i, "go") for i in range(4)]
    CALLS.clear()
    parallel.run(counting_chunk, tasks, chunk_size=2, workers=1, resume_dir=tmp_path, context="clips v1")
    parallel.run(counting_chunk, tasks, chunk_size=2, workers=1, resume_dir=tmp_path, context="clips v1")
    assert CALLS == [[0, 1], [2, 3]], "the same context reads its chunks back"
    parallel.run(counting_chunk, tasks, chunk_size=2, workers=1, resume_dir=tmp_path, context="clips v2")
    assert CALLS == [[0, 1], [2, 3]] * 2, "another context computes its own chunks"
    assert parallel.chunk_key(counting_chunk, tasks[:2], "") == parallel.chunk_key(counting_chunk, tasks[:2])


def test_bad_arguments():
    with pytest.raises(ParameterError, match="backend"):
        parallel.run(seeded_chunk, [(0, 1)], backend="dask")
    with pytest.raises(ParameterError, match="workers"):
        parallel.run(seeded_chunk, [(0, 1)], workers=0)
    with pytest.raises(ParameterError, match="rows"):
        parallel.run(lambda t: {"x": np.zeros(len(t) + 1)}, [(0, 1)], workers=1)
    assert parallel.run(seeded_chunk, [], workers=1) == {}


# The Ray backend is checked on the real job, in tests/test_response_classifier.py.
