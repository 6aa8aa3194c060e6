"""``kinodyn demo``: the main job on the built-in data, one part per capability.

Each part is a module defining ``demo(out: Path) -> list[str]``, registered in its package's
``register.py`` (``DEMO_PARTS``, see :mod:`kinodyn.registry`) with an order number; it writes its files
under ``out`` and returns summary lines. Parts run in that order; a part may use files an earlier one
wrote. Everything written is atomic, so an interrupted demo leaves no half-written file.
"""

from __future__ import annotations

import time
from pathlib import Path

from kinodyn import registry
from kinodyn.errors import UnknownNameError

__all__ = ["run_demo"]


def run_demo(out: Path, only: list[str] | None = None) -> None:
    table = registry.demo_parts()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    parts = list(table)
    if only:
        unknown = [p for p in only if p not in table]
        if unknown:
            raise UnknownNameError(f"unknown demo part {unknown[0]!r}; parts: {', '.join(table)}")
        parts = [p for p in parts if p in only]
    for name in parts:
        modname = table[name]
        mod = registry.load(modname)
        if mod is None:
            print(f"[{name}] not part of this build yet; skipped")
            continue
        t0 = time.perf_counter()
        print(f"[{name}] ...", flush=True)
        for line in mod.demo(out):
            print(f"  {line}", flush=True)
        print(f"[{name}] done in {time.perf_counter() - t0:.1f} s", flush=True)
    print(f"demo output in {out}/")
