"""Demo part "clips": export every built-in clip to ``out/clips/NAME.bvh`` and summarize it.

Each summary line gives the clip's frames and duration, its foot sliding (mean horizontal speed of
the planted feet, :func:`kinodyn.contacts.sliding`) and the lowest height any foot point reaches.
"""

from __future__ import annotations

from pathlib import Path

from kinodyn.contacts import foot_points, sliding
from kinodyn.data import library
from kinodyn.io.bvh import write_bvh

__all__ = ["clip_summary", "demo"]


def clip_summary(name: str) -> str:
    """One line: ``name frames duration sliding min-foot-height`` of library clip ``name``."""
    m = library.load(name)
    slide = sliding(m)
    low = min(float(p[..., 2].min()) for p in foot_points(m).values())
    return (f"{name:<26} {m.num_frames:4d} frames {m.duration:5.2f} s  sliding {slide.cm_per_s:4.2f} cm/s  "
            f"min foot height {100.0 * low:5.2f} cm")


def demo(out: Path) -> list[str]:
    """Write ``out/clips/NAME.bvh`` for every library clip; return one summary line per clip."""
    folder = Path(out) / "clips"
    folder.mkdir(parents=True, exist_ok=True)
    lines = []
    for name in library.names():
        write_bvh(folder / f"{name}.bvh", library.load(name))
        lines.append(clip_summary(name))
    lines.append(f"{len(lines)} clips written to {folder}/ (BVH, Y up, centimetres, 60 fps)")
    return lines

