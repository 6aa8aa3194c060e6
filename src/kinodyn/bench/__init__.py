"""Benchmarks, one per capability, registered by name and run by ``kinodyn bench NAME --json FILE``.

A benchmark module defines ``run(quick: bool, progress) -> BenchResult`` and is registered in its
package's ``register.py`` (``BENCHMARKS``, see :mod:`kinodyn.registry`); it lives beside what it
measures (``kinodyn.physics.bench``). Results are written as JSON: ``{"name", "metrics": {key: number},
"units": {key: unit}, "baseline": {...}, "machine": {...}}``. Speed goals live there, never in unit tests.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import os
import platform
from dataclasses import dataclass, field

from kinodyn import registry
from kinodyn.errors import UnknownNameError

__all__ = ["BenchResult", "one_numba_thread", "get", "machine_info", "names", "run"]


def names() -> list[str]:
    """Names of the registered benchmarks."""
    return list(registry.benchmarks())


@dataclass
class BenchResult:
    name: str
    metrics: dict[str, float] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    baseline: dict[str, float] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)

    def add(self, key: str, value: float, unit: str) -> None:
        self.metrics[key] = float(value)
        self.units[key] = unit

    def to_json(self) -> dict:
        return {"name": self.name, "metrics": self.metrics, "units": self.units, "baseline": self.baseline,
                "notes": self.notes, "machine": machine_info()}


def machine_info() -> dict:
    import numpy

    return {"python": platform.python_version(), "platform": platform.platform(), "cpus": os.cpu_count(),
            "numpy": numpy.__version__, "processor": platform.processor() or platform.machine()}


def get(name: str):
    """The ``run`` function of benchmark ``name``."""
    table = registry.benchmarks()
    if name not in table:
        raise UnknownNameError(f"unknown benchmark {name!r}; available: {', '.join(sorted(table))}")
    try:
        mod = importlib.import_module(table[name])
    except ModuleNotFoundError as e:
        raise UnknownNameError(f"benchmark {name!r} is not available in this build ({e.name} missing)") from None
    return mod.run


@contextlib.contextmanager
def one_numba_thread():
    """Compiled kernels on one thread while a benchmark runs (figures are per core); restored after."""
    import numba

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(threads)


def run(name: str, quick: bool = False, json_path=None, progress=None) -> BenchResult:
    """Run one benchmark with numba pinned to one thread; write its JSON atomically when ``json_path``
    is given."""
    from kinodyn.io.atomic import atomic_write_bytes

    with one_numba_thread():
        result = get(name)(quick=quick, progress=progress)
    if json_path is not None:
        atomic_write_bytes(json_path, (json.dumps(result.to_json(), indent=2) + "\n").encode())
    return result
