"""``kinodyn blend SCRIPT.yaml -o out.bvh``: play a blend script through the synchronized mixer.

The script lists actions (clips), their start and stop times and priorities (see
:mod:`kinodyn.blend.script`). The blended motion is written as BVH (or NPZ by the file ending);
``--html`` writes a viewer page beside it (support phases on, on the timeline under the scene),
``--plots DIR`` the support-phase bars, time warps and foot heights and speeds,
``--no-sync`` blends without synchronization (the baseline) and ``--compare`` prints the foot sliding
of both.
"""

from __future__ import annotations

from pathlib import Path

HELP = "blend actions from a YAML script with support-phase synchronization: kinodyn blend SCRIPT.yaml -o out.bvh"
DESCRIPTION = ("Play a script of actions (clips with start/stop times and priorities) through the real-time mixer: "
               "support phases are synchronized and time-warped before blending, so feet do not slide.")


def add_arguments(p) -> None:
    p.add_argument("script", help="YAML blend script (see examples/blend_fig12.yaml)")
    p.add_argument("-o", "--output", required=True, help="motion file to write (.bvh or .npz)")
    p.add_argument("--html", help="also write a viewer page (.html)")
    p.add_argument("--plots", metavar="DIR",
                   help="write support-phase, time-warp and foot height/speed figures (PNG) to DIR")
    p.add_argument("--no-sync", action="store_true", help="blend without synchronization (the baseline)")
    p.add_argument("--compare", action="store_true",
                   help="also blend without synchronization and print the foot sliding of both")
    p.add_argument("--fps", type=float, help="override the script's frame rate")


def _sliding_line(label, result) -> str:
    from kinodyn.blend.evaluate import measure

    f = measure(result)
    return (f"  {label:<22} sliding {f['sliding_cm_s']:6.2f} cm/s over {f['planted_frames']} frames the source "
            f"clips plant a foot, {f['transition_sliding_cm_s']:6.2f} cm/s in transitions; {f['err_frames']} frames "
            "mixing RS with LS")


def _plot_feet(result, other, sync: bool, path):
    """Foot heights and speeds of the blend (and of the other one with ``--compare``), with the frames the
    source clips plant a foot shaded and the transitions marked."""
    from kinodyn.blend import plots
    from kinodyn.blend.evaluate import source_contacts
    from kinodyn.contacts import intervals

    label = "synchronized" if sync else "not synchronized"
    runs = {label: result}
    if other is not None:
        runs["not synchronized" if sync else "synchronized"] = other
    fps = result.motion.fps
    spans = [(a / fps, b / fps) for a, b in intervals(result.transition_mask())]
    return plots.plot_feet({k: r.motion for k, r in runs.items()}, path,
                           labels={k: source_contacts(r) for k, r in runs.items()}, spans=spans)


def run(args) -> int:
    from dataclasses import replace

    from kinodyn.blend.script import load_script, run_script
    from kinodyn.errors import ParameterError
    from kinodyn.io import save

    script = load_script(args.script)
    if args.fps is not None:
        if not args.fps > 0:
            raise ParameterError(f"--fps must be positive, got {args.fps}")
        script = replace(script, fps=float(args.fps))
    sync = script.synchronize and not args.no_sync
    result = run_script(script, synchronize=sync)
    out = Path(args.output)
    save(out, result.motion)
    m = result.motion
    print(f"wrote {out}: {m.num_frames} frames at {m.fps:g} fps = {m.duration:.2f} s, "
          f"{len(result.starts)} actions, {'synchronized' if sync else 'not synchronized'}")
    waits = {}
    for e in result.sync_events:
        if e.kind == "wait":
            waits[e.key] = waits.get(e.key, 0) + 1
    for key, (asked, started) in result.starts.items():
        if started is None:
            print(f"  {key:<22} asked at {asked:6.2f} s, never started (no compatible support phase)")
            continue
        note = ""
        if waits.get(key):
            note = f" (waited {waits[key]} element(s) for a compatible support phase)"
        elif started - asked > 1e-6:
            note = " (at the next support-phase boundary)"
        print(f"  {key:<22} asked at {asked:6.2f} s, started at {started:6.2f} s{note}")
    lines = [_sliding_line("synchronized" if sync else "not synchronized", result)]
    other = None
    if args.compare:
        other = run_script(script, synchronize=not sync, library=result.library)
        lines.append(_sliding_line("not synchronized" if sync else "synchronized", other))
    print("\n".join(lines))
    if args.plots:
        from kinodyn.blend import plots

        d = Path(args.plots)
        stem = out.stem
        written = [plots.plot_phases(result, d / f"{stem}_phases.png",
                                     compare=other if (other is not None and sync) else None)]
        if sync:
            written.append(plots.plot_timewarp(result, d / f"{stem}_timewarp.png"))
        written.append(_plot_feet(result, other, sync, d / f"{stem}_feet.png"))
        for p in written:
            print(f"wrote {p}")
    if args.html:
        try:
            from kinodyn.viz import html
        except ImportError:
            print("viewer not available in this build; --html skipped")
        else:
            motions = {"synchronized" if sync else "blend": m}
            if other is not None:
                motions["not synchronized" if sync else "synchronized"] = other.motion
            # support phases on: the phase bars of every character fill the timeline under the scene;
            # a comparison side by side, in lanes across the direction of travel
            page = html.write(args.html, motions, ["contacts", "phases"], layout="lanes" if other else "world",
                              title=f"kinodyn blend: {script.name or Path(args.script).stem}")
            print(f"wrote {page.path} ({page.bytes / 1e6:.1f} MB)")
    return 0
