"""One executor for embarrassingly parallel, seeded work: local processes by default, a Ray cluster when asked.

Training-set generation (:mod:`kinodyn.response.dataset`) and candidate-scene generation map a function
over many small tasks. :func:`run` cuts the task list into chunks of a fixed size (so the same tasks go
into the same chunks whatever the backend or worker count), runs each chunk as one job (Ray's guidance:
tasks under about 10 ms gain nothing, so a job should last seconds), and concatenates the results in
task order. Every task carries its own seed, so the same tasks give the same results on 1 or N local
workers and on Ray.

A chunk function takes a list of tasks and returns a dict of arrays with one leading row per task.
With ``resume_dir`` each finished chunk is written there (``chunk-00012-<key>.npz``, no pickles) and a
rerun skips the chunks already on disk, so an interrupted run resumes where it stopped. A chunk's file
name carries a key of the chunk function, the chunk's own tasks and the run's ``context`` (what the tasks
read besides themselves, such as a fingerprint of the input files; :func:`chunk_key`), so a chunk is read
back only by a run that would compute the same one: a run with another seed, chunk size, function or
context in the same folder computes its own chunks, and a run with more tasks reuses the chunks it
shares with a shorter one.

Ray is an optional dependency (``pip install kinodyn[ray]``), imported only when asked for.
"""

from __future__ import annotations

import hashlib
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.progress import progress

__all__ = ["BACKENDS", "chunk_key", "chunks", "default_workers", "run"]

BACKENDS = ("local", "ray")


def default_workers() -> int:
    """Worker processes used by default: every core this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def chunks(n: int, size: int) -> list[tuple[int, int]]:
    """``[start, stop)`` task ranges of ``size`` tasks (the last may be shorter)."""
    if size < 1:
        raise ParameterError(f"chunk size must be >= 1, got {size}")
    return [(a, min(a + size, n)) for a in range(0, n, size)]


def chunk_key(fn, tasks: list, context: str = "") -> str:
    """16 hex digits naming chunk function ``fn`` applied to ``tasks`` in ``context``: a hash of the
    function's module and qualified name, of the tasks' ``repr`` (tasks carry numbers and strings, whose
    ``repr`` is stable) and of ``context`` (the empty context keeps the keys of runs without one)."""
    text = f"{getattr(fn, '__module__', '')}.{getattr(fn, '__qualname__', repr(fn))}\n{tasks!r}"
    if context:
        text += f"\n{context}"
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _chunk_path(folder: Path, i: int, key: str) -> Path:
    return folder / f"chunk-{i:05d}-{key}.npz"


def _save(path: Path, result: dict) -> None:
    """Write a chunk atomically: a temporary file in the same folder, then renamed over ``path``."""
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
    try:
        np.savez(tmp, **{k: np.asarray(v) for k, v in result.items()})
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _load(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _check_result(result, n: int, i: int) -> dict:
    if not isinstance(result, dict) or not result:
        raise ParameterError(f"a chunk function must return a non-empty dict of arrays, chunk {i} returned "
                             f"{type(result).__name__}")
    for k, v in result.items():
        if len(np.asarray(v)) != n:
            raise ParameterError(f"chunk {i}: result {k!r} has {len(np.asarray(v))} rows for {n} tasks")
    return result


def _local(fn, parts, todo, workers, bar, done):
    if workers == 1:
        for i in todo:
            done(i, fn(parts[i]))
            bar.update(1)
        return
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        futures = {pool.submit(fn, parts[i]): i for i in todo}
        for f in as_completed(futures):
            done(futures[f], f.result())
            bar.update(1)


def _ray(fn, parts, todo, workers, address, bar, done):
    try:
        import ray
    except ImportError:
        raise ParameterError("the ray backend needs Ray: pip install 'kinodyn[ray]'") from None
    if not ray.is_initialized():
        if address:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    remote = ray.remote(fn)
    pending = {remote.remote(parts[i]): i for i in todo}
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        for ref in ready:
            done(pending.pop(ref), ray.get(ref))
            bar.update(1)


def run(fn, tasks: list, *, chunk_size: int = 16, workers: int | None = None, backend: str = "local",
        address: str | None = None, resume_dir=None, context: str = "", desc: str = "",
        show_progress: bool | None = None) -> dict:
    """``fn`` over ``tasks`` in chunks; the per-task rows of every chunk's dict of arrays, concatenated.

    Args:
        fn: a picklable top-level function ``fn(list_of_tasks) -> {name: array with one row per task}``.
        tasks: the tasks (each carrying what it needs, its seed included).
        chunk_size: tasks per job.
        workers: local processes (default every core; 1 runs in this process) or Ray CPUs for a local
            Ray started here.
        backend: ``"local"`` or ``"ray"``.
        address: Ray cluster address (default: start Ray locally).
        resume_dir: folder keeping finished chunks; a chunk of the same function, tasks and context found
            there is read back, not recomputed.
        context: text naming what the tasks' results depend on besides the tasks (a fingerprint of the
            files they read): a chunk computed in another context is not read back.
        desc: progress-bar label; show_progress: force the bar on or off (default: on a terminal).
    """
    if backend not in BACKENDS:
        raise ParameterError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise ParameterError(f"workers must be >= 1, got {workers}")
    ranges = chunks(len(tasks), chunk_size)
    parts = [tasks[a:b] for a, b in ranges]
    results: dict[int, dict] = {}
    folder = None if resume_dir is None else Path(resume_dir)
    paths = []
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        paths = [_chunk_path(folder, i, chunk_key(fn, part, context)) for i, part in enumerate(parts)]
        for i, path in enumerate(paths):
            if path.exists():
                results[i] = _check_result(_load(path), len(parts[i]), i)
    todo = [i for i in range(len(parts)) if i not in results]

    def done(i, result):
        results[i] = _check_result(result, len(parts[i]), i)
        if folder is not None:
            _save(paths[i], results[i])

    bar = progress(total=len(parts), desc=desc or "chunks", enabled=show_progress)
    bar.update(len(parts) - len(todo))
    try:
        if todo and backend == "local":
            _local(fn, parts, todo, workers, bar, done)
        elif todo:
            _ray(fn, parts, todo, workers, address, bar, done)
    finally:
        bar.close()
    if not parts:
        return {}
    keys = list(results[0])
    return {k: np.concatenate([results[i][k] for i in range(len(parts))]) for k in keys}
