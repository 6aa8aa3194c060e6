"""``kinodyn demo``: the main job on the built-in data, one part per capability.

Each part is a module listed in :data:`DEMO_PARTS` defining ``demo(out: Path) -> list[str]``; it
writes its files under ``out`` and returns summary lines. Parts run in order; a part may use files an
earlier one wrote. Everything written is atomic, so an interrupted demo leaves no half-written file.
"""

from __future__ import annotations

import importlib
import time
from pathlib import Path

from kinodyn.errors import UnknownNameError

__all__ = ["DEMO_PARTS", "run_demo"]

#: part name -> module with ``demo(out) -> list[str]``.
DEMO_PARTS: dict[str, str] = {
    "clips": "kinodyn.data.demo",
    "physics": "kinodyn.physics.demo",
    "blend": "kinodyn.blend.demo",
    "viewer": "kinodyn.viz.demo",
    "response": "kinodyn.response.demo",
}


def run_demo(out: Path, only: list[str] | None = None) -> None:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    parts = list(DEMO_PARTS)
    if only:
        unknown = [p for p in only if p not in DEMO_PARTS]
        if unknown:
            raise UnknownNameError(f"unknown demo part {unknown[0]!r}; parts: {', '.join(DEMO_PARTS)}")
        parts = [p for p in parts if p in only]
    for name in parts:
        modname = DEMO_PARTS[name]
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as e:
            if e.name and modname.startswith(e.name):
                print(f"[{name}] not part of this build yet; skipped")
                continue
            raise
        t0 = time.perf_counter()
        print(f"[{name}] ...", flush=True)
        for line in mod.demo(out):
            print(f"  {line}", flush=True)
        print(f"[{name}] done in {time.perf_counter() - t0:.1f} s", flush=True)
    print(f"demo output in {out}/")
