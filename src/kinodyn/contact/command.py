"""``kinodyn contact``: run the paper's scenarios, clean motion data against a scene.

``kinodyn contact run SCENARIO -o out/ [--html] [--png N]`` simulates a shipped scenario (or a scene
file) and writes the avatar's resolved motion (BVH), the objects' trajectories (NPZ + JSON names), a
per-frame timing report (CSV) and a summary (JSON); ``--html`` adds the viewer page (the scene's
objects on their trajectories, the resolved avatar, the tracked one as a reference with its segments
inside obstacles in red, contact normals as arrows: :func:`write_page`), ``--png N`` N rendered frames. ``kinodyn contact fix MOTION --scene S.yaml -o
fixed.bvh`` resolves every frame of a clip against a scene's fixed objects and the avatar itself and
reports what changed per frame. ``kinodyn contact list`` names the scenarios.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from kinodyn.errors import KinodynError

HELP = "avatar-environment contact: run SCENARIO -o out/, fix MOTION --scene S.yaml -o fixed.bvh, list"
DESCRIPTION = ("Global penetration depth from convex pieces, overlap removal, CCD IK with joint limits and "
               "reach cones, impulses with Coulomb friction (Schmidl and Lin).")


def add_arguments(p) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", parser_class=type(p))
    sub.required = True
    q = sub.add_parser("run", help="simulate a scenario (a shipped name or a scene file)")
    q.add_argument("scenario")
    q.add_argument("-o", "--out", required=True, help="output folder")
    q.add_argument("--frames", type=int, help="frames to run (default: the whole scenario)")
    q.add_argument("--html", action="store_true", help="also write the viewer page")
    q.add_argument("--png", type=int, default=0, metavar="N", help="also render N frames as PNG")
    q.add_argument("--motion", help="the avatar's motion file (BVH, AMC, NPZ) instead of the scene's own; a "
                   "scene that plays motion capture (walk_into_wall: CMU 02_01) needs it unless --mocap or "
                   "KINODYN_MOCAP names the folder holding the file")
    q.add_argument("--mocap", metavar="DIR", help="the motion-capture folder a scene's mocap: motion is "
                   "found in (default: $KINODYN_MOCAP)")
    q.set_defaults(contact=_run)
    q = sub.add_parser("fix", help="resolve a clip against a scene's objects, floor and itself")
    q.add_argument("motion", help="motion file (BVH, AMC, NPZ) or a built-in clip name")
    q.add_argument("--scene", required=True, help="scene file (YAML) or a shipped scenario name")
    q.add_argument("-o", "--output", required=True, help="BVH (or NPZ) file to write")
    q.add_argument("--place", type=float, nargs=3, metavar=("X", "Y", "HEADING"),
                   help="move the clip's first frame here (m, m, deg) before resolving")
    q.add_argument("--report", help="write the per-frame report (CSV) here")
    q.set_defaults(contact=_fix)
    q = sub.add_parser("list", help="the shipped scenarios")
    q.set_defaults(contact=_list)


def run(args) -> int:
    return int(args.contact(args) or 0)


def _list(args) -> int:
    from kinodyn.contact.scenefile import load_scene, scenario_names, scenario_path

    for name in scenario_names():
        print(f"{name:<16} {load_scene(scenario_path(name)).description}")
    return 0


def _write_report(path, frames: dict) -> None:
    from kinodyn.io.atomic import atomic_write_bytes

    keys = list(frames)
    n = len(frames[keys[0]]) if keys else 0
    lines = ["frame," + ",".join(keys)]
    lines += [f"{f}," + ",".join(f"{frames[k][f]:.6g}" for k in keys) for f in range(n)]
    atomic_write_bytes(path, ("\n".join(lines) + "\n").encode())


def summary(result) -> dict:
    """Table 2's columns of one run."""
    fr = result.frames
    return {"scene": result.scene, "frames": len(fr["frame_ms"]), "frame_ms_mean": float(fr["frame_ms"].mean()),
            "frame_ms_max": float(fr["frame_ms"].max()), "joints_per_frame": float(fr["joints"].mean()),
            "iterations_per_frame": float(fr["iterations"].mean()),
            "ik_share": float(fr["ik_ms"].sum() / max(fr["wall_ms"].sum(), 1e-12)),
            "pairs_per_frame": float(fr["pairs"].mean()),
            "query_share": float(fr["query_ms"].sum() / max(fr["wall_ms"].sum(), 1e-12)),
            "max_penetration_mm": float(fr["penetration_mm"].max()), "fallback_frames": int(fr["fallback"].sum()),
            "collisions": int(fr["collisions"].sum())}


def with_motion(scene, motion=None, mocap=None):
    """``scene`` with its avatar playing ``motion`` (a file or clip name) when given, and its ``mocap:``
    motion resolved in the folder ``mocap`` (:func:`kinodyn.contact.scenefile.resolve_motion`)."""
    from dataclasses import replace

    from kinodyn.contact.scenefile import resolve_motion

    if scene.avatar is None:
        if motion is not None:
            raise KinodynError(f"scene {scene.name!r} has no avatar to play --motion {motion}")
        return scene
    if motion is not None:
        if not Path(motion).is_file() and Path(motion).suffix.lower() in (".bvh", ".amc", ".npz"):
            raise KinodynError(f"--motion {motion}: no such motion file")
        return replace(scene, avatar=replace(scene.avatar, motion=str(motion)))
    return replace(scene, avatar=replace(scene.avatar, motion=resolve_motion(scene.avatar.motion, mocap)))


def _run(args) -> int:
    from kinodyn.contact.scenefile import load_scene, scenario_path
    from kinodyn.contact.simulate import run_scene
    from kinodyn.io import save
    from kinodyn.io.atomic import atomic_path, atomic_write_bytes
    from kinodyn.progress import progress

    scene = with_motion(load_scene(scenario_path(args.scenario)), args.motion, args.mocap)
    if args.frames is not None and args.frames <= 0:
        raise KinodynError(f"--frames must be a positive number of frames, got {args.frames}")
    result = run_scene(scene, args.frames, progress=progress)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    if result.motion is not None:
        save(out / f"{scene.name}.bvh", result.motion)
        written.append(f"{scene.name}.bvh")
    with atomic_path(out / f"{scene.name}_objects.npz", suffix=".npz") as tmp:
        np.savez(tmp, pos=result.pos, quat=result.quat, fps=result.fps)
    atomic_write_bytes(out / f"{scene.name}_objects.json", json.dumps({"names": list(result.names)}).encode())
    _write_report(out / f"{scene.name}_frames.csv", result.frames)
    info = summary(result)
    atomic_write_bytes(out / f"{scene.name}_summary.json", (json.dumps(info, indent=2) + "\n").encode())
    written += [f"{scene.name}_objects.npz", f"{scene.name}_frames.csv", f"{scene.name}_summary.json"]
    if args.png:
        from kinodyn.contact.plots import render_frames

        written += [p.name for p in render_frames(scene, result, out, count=args.png)]
    if args.html:
        write_page(out / f"{scene.name}.html", scene, result)
        written.append(f"{scene.name}.html")
    print(f"{scene.name}: {info['frames']} frames, {info['frame_ms_mean']:.2f} ms/frame mean "
          f"({info['frame_ms_max']:.2f} max), {info['iterations_per_frame']:.2f} CCD iterations/frame, "
          f"deepest penetration left {info['max_penetration_mm']:.3f} mm")
    print(f"wrote {', '.join(written)} in {out}/")
    return 0


_KIND_COLOURS = {"fixed": "#b8b4ab", "simulated": "#f28c28", "driven": "#5b8ce6"}


def scene_props(scene, result, unlabelled=()) -> list:
    """The run's objects as viewer props (:class:`kinodyn.viz.objects.Prop`): fixed ones grey and
    translucent (walls do not hide the avatar), simulated ones orange (with the path of their centre),
    the hand blue. Objects named in ``unlabelled`` are left out of the legend."""
    from kinodyn.contact.display import shape_tracks
    from kinodyn.viz.objects import Prop

    props, labelled = [], set(unlabelled)
    for t in shape_tracks(scene, result):
        size = {"box": t.size, "sphere": t.size[:1], "capsule": t.size[:2]}.get(t.shape, (0.1,))
        owner = t.name.split("/")[0]
        label = "" if owner in labelled else owner
        labelled.add(owner)
        moving = len(t.positions) > 1
        props.append(Prop(t.shape, t.positions, size, t.quats, fps=result.fps, color=_KIND_COLOURS[t.kind],
                          label=label if t.kind != "fixed" else "", vertices=t.vertices, faces=t.faces,
                          trail=moving and t.kind == "simulated", opacity=0.35 if t.kind == "fixed" else 1.0))
    return props


def _focus(scene, result):
    """A scene without an avatar: a one-point character on the first moving object (the hand, else a
    simulated object), which names it and which the follow camera frames."""
    from kinodyn.motion import Motion
    from kinodyn.skeleton import Skeleton

    names = list(result.names)
    moving = [k for k, o in enumerate(names) if o == "hand"] or [
        k for k in range(len(names)) if np.ptp(result.pos[:, k], axis=0).max() > 1e-6] or [0]
    k = moving[0]
    point = Skeleton((names[k],), np.array([-1]), np.zeros((1, 3)))
    rot = np.tile([1.0, 0.0, 0.0, 0.0], (len(result.pos), 1, 1))
    return Motion(point, result.pos[:, k], rot, result.fps, name=names[k])


def write_page(path, scene, result, margin: float = 0.01):
    """The viewer page of a run: the scene's objects on their trajectories, the resolved avatar, the
    tracked (unresolved) motion as a ghost with its segments inside a fixed object in red, and the
    resolved avatar's contact normals (within ``margin`` m of a fixed object) as arrows."""
    from kinodyn.contact.display import contact_normals, penetrating_joints
    from kinodyn.viz import html

    if result.motion is None:
        focus = _focus(scene, result)  # it names its object in the legend
        return html.write(path, focus, scene_props(scene, result, [focus.name]), title=scene.name)
    overlays = scene_props(scene, result)
    frames, points, normals = contact_normals(result.motion, scene, margin)
    if len(frames):
        # each arrow ends at the contact point, coming from the avatar's side: the push the
        # obstacle takes; its normal is the reverse
        overlays.append(html.Forces(frames / result.fps, points, -normals * 0.15, scale=1.0,
                                    hold=1.0 / result.fps, label="contact normals"))
    hot = penetrating_joints(result.tracked, scene)
    actors = [html.Actor(result.motion, "resolved"),
              html.Actor(result.tracked, "tracked", ghost=True, highlight=hot)]
    return html.write(path, actors, overlays, title=scene.name)


def _fix(args) -> int:
    from kinodyn.contact.fix import fix_motion
    from kinodyn.contact.motions import scenario_motion
    from kinodyn.contact.scenefile import load_scene, scenario_path
    from kinodyn.io import save

    scene = load_scene(scenario_path(args.scene))
    motion = scenario_motion(args.motion)
    if args.place:
        x, y, h = args.place
        motion = motion.aligned_to(np.array([x, y, np.deg2rad(h)]), 0)
    fixed, report = fix_motion(motion, scene)
    save(args.output, fixed)
    if args.report:
        _write_report(args.report, report)
    changed = report["changed_deg"] > 1e-3
    print(f"wrote {args.output}: {fixed.num_frames} frames; {int(changed.sum())} frames changed "
          f"(largest joint change {report['changed_deg'].max():.1f} deg, root moved up to "
          f"{report['root_moved_mm'].max():.1f} mm); deepest penetration before "
          f"{report['before_mm'].max():.1f} mm, after {report['penetration_mm'].max():.3f} mm")
    for f in np.nonzero(changed)[0][:20]:
        print(f"  frame {f}: {report['changed_deg'][f]:.1f} deg, {report['before_mm'][f]:.1f} -> "
              f"{report['penetration_mm'][f]:.2f} mm, {int(report['iterations'][f])} CCD iterations")
    return 0
