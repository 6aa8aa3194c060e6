"""Demo part ``contact``: the paper's scenarios on the shipped scene files.

Runs the four avatar scenarios of Table 2 and the hand of figure 7 in the two-room gallery (and the
CMU walk into the wall when its motion-capture file is found: ``$KINODYN_MOCAP``), and writes under
``out/contact``: each scenario's resolved motion (BVH), object trajectories, per-frame
report (CSV) and summary (JSON), its viewer page (HTML), four rendered frames per scenario (PNG), the frame-time plot
(figures 7 and 8) and ``table2.json`` with the columns of Table 2.
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["demo"]

SCENARIOS = ("two_arms", "self_collision", "two_arms_leg", "arm_in_corner", "hand")


def demo(out: Path) -> list[str]:
    import numpy as np

    from kinodyn.contact.command import summary, with_motion, write_page
    from kinodyn.contact.plots import frame_time_plot, render_frames
    from kinodyn.contact.scenefile import load_scene, scenario_path
    from kinodyn.contact.simulate import run_scene
    from kinodyn.io import save
    from kinodyn.io.atomic import atomic_path, atomic_write_bytes

    folder = Path(out) / "contact"
    folder.mkdir(parents=True, exist_ok=True)
    lines, table, results = [], {}, []
    run_scene(load_scene(scenario_path("two_arms")), frames=40)  # compile the kernels outside the timings
    from kinodyn.errors import KinodynError

    for name in SCENARIOS + ("walk_into_wall",):
        try:
            scene = with_motion(load_scene(scenario_path(name)))
        except KinodynError as e:  # motion capture that is not there
            lines.append(f"{name}: skipped ({e})")
            continue
        r = run_scene(scene)
        results.append(r)
        if r.motion is not None:
            save(folder / f"{name}.bvh", r.motion)
        with atomic_path(folder / f"{name}_objects.npz", suffix=".npz") as tmp:
            np.savez(tmp, pos=r.pos, quat=r.quat, fps=r.fps)
        render_frames(scene, r, folder, count=4)
        write_page(folder / f"{name}.html", scene, r)
        s = summary(r)
        table[name] = s
        lines.append(f"{name}: {s['frames']} frames, {s['frame_ms_mean']:.2f} ms/frame, "
                     f"{s['iterations_per_frame']:.2f} CCD iterations/frame, "
                     f"deepest overlap left {s['max_penetration_mm']:.3f} mm")
    frame_time_plot(results, folder / "frame_times.png")
    atomic_write_bytes(folder / "table2.json", (json.dumps(table, indent=2) + "\n").encode())
    lines.append(f"wrote {folder}/ (BVH, trajectories, viewer pages, PNG frames, frame_times.png, table2.json)")
    return lines
