"""``kinodyn view FILE... -o out.html``: a self-contained viewer page (or a glTF export) of motions.

Inputs are motion files (``.bvh``, ``.amc``, ``.npz``) or names of built-in clips (``kinodyn library
list``). The page plays every input in one world; ``--layout row`` puts clips side by side, ``--layout
lanes`` side by side across their direction of travel (comparisons); ``--ghost FILE`` adds a
translucent reference; ``--loop`` / ``--hold`` say what clips shorter than the page do after their last
frame; ``--curves`` opens the curves panel. ``-o out.glb`` / ``out.gltf`` writes a glTF 2.0 skeleton
animation of one input instead.
"""

from __future__ import annotations

from pathlib import Path

from kinodyn.commands.inputs import add_motion_options, load_motion_or_clip
from kinodyn.errors import ParameterError

HELP = "write a self-contained HTML viewer (or .glb/.gltf) of motion files or built-in clips"

_OVERLAYS = ("contacts", "phases", "trajectories")


def add_input_arguments(p) -> None:
    """Arguments shared by ``view`` and ``render``: inputs, how to read them and how to lay them out."""
    from kinodyn.viz.world import LAYOUTS

    p.add_argument("inputs", nargs="+", metavar="FILE", help="motion files (.bvh .amc .npz) or built-in clip names")
    add_motion_options(p, asf=False)
    p.add_argument("--drop-first", type=int, default=0, metavar="N",
                   help="drop the first N frames of each file (1 for the T-pose frame of CMU BVH conversions)")
    p.add_argument("--keep-tpose", action="store_true",
                   help="keep frame 0 when it is a T-pose added by the converter (skipped by default)")
    p.add_argument("--names", help="comma-separated character names (default: file stems)")
    p.add_argument("--colors", help="comma-separated colours, #rrggbb or C0..C9")
    p.add_argument("--overlays", default="contacts",
                   help=f"comma-separated overlays from {', '.join(_OVERLAYS)}, or 'none' (default: contacts)")
    p.add_argument("--layout", choices=LAYOUTS, default="world",
                   help="world: as recorded; row/grid: side by side (galleries); lanes: side by side across the "
                        "direction of travel (comparisons) (default: world)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--loop", dest="loop_clips", action="store_true", default=False,
                   help="clips shorter than the longest start again after their last frame")
    g.add_argument("--hold", dest="loop_clips", action="store_false",
                   help="clips shorter than the longest hold their last pose (default)")


def load_inputs(args) -> list:
    """The motions named by ``args.inputs`` (files first, then built-in clip names)."""
    from kinodyn.io import skip_added_tpose

    out = []
    for item in args.inputs:
        m = load_motion_or_clip(item, args)
        if Path(item).exists() and not args.drop_first and not getattr(args, "keep_tpose", False):
            m = skip_added_tpose(m, item)
        if args.drop_first:
            if args.drop_first < 0:
                raise ParameterError(f"--drop-first {args.drop_first}: a number of frames >= 0 to drop from {item}")
            if args.drop_first >= m.num_frames:
                raise ParameterError(f"--drop-first {args.drop_first} leaves no frames of {item} "
                                     f"({m.num_frames} frames)")
            m = m[args.drop_first:]
        out.append(m)
    return out


def split_list(s: str | None) -> list[str] | None:
    return None if s is None else [x.strip() for x in s.split(",")]


def overlays_arg(s: str) -> list[str]:
    items = [x for x in split_list(s) if x]
    if items in (["none"], []):
        return []
    bad = [x for x in items if x not in _OVERLAYS]
    if bad:
        raise ParameterError(f"--overlays: unknown overlay {bad[0]!r}; choose from {', '.join(_OVERLAYS)} or none")
    return items


def add_arguments(p) -> None:
    add_input_arguments(p)
    p.add_argument("-o", "--output", help="output .html (default: FIRST_INPUT.html), or .glb / .gltf")
    p.add_argument("--title", help="page title")
    p.add_argument("--body", choices=["capsules", "bones"], default="capsules", help="how bodies are drawn")
    p.add_argument("--camera", choices=["follow", "orbit", "free"], default="follow", help="camera at start")
    p.add_argument("--paused", action="store_true", help="do not start playing when opened")
    p.add_argument("--curves", action="store_true",
                   help="open the curves panel (joint speeds, root and foot heights) at start")
    p.add_argument("--ghost", action="append", default=[], metavar="FILE",
                   help="a reference drawn translucent (motion file or built-in clip name; may be repeated)")


def actors(args, motions) -> list:
    """The inputs (with ``--names`` and ``--colors``) then the ``--ghost`` references, as viewer actors."""
    from kinodyn.viz.world import Actor

    names, colors = split_list(args.names), split_list(args.colors)
    for flag, given in (("--names", names), ("--colors", colors)):
        if given is not None and len(given) != len(motions):
            raise ParameterError(f"{flag}: one entry per input ({len(motions)}), got {len(given)}")
    out = [Actor(m, names[i] if names else None, colors[i] if colors else None) for i, m in enumerate(motions)]
    for item in args.ghost:
        g = load_motion_or_clip(item, args)
        out.append(Actor(g, Path(item).stem, ghost=True))
    return out


def run(args) -> int:
    motions = load_inputs(args)
    out = Path(args.output or f"{Path(args.inputs[0]).stem}.html")
    colors = split_list(args.colors)
    ext = out.suffix.lower()
    if ext in (".glb", ".gltf"):
        from kinodyn.viz.gltf import write_gltf

        if len(motions) != 1:
            raise ParameterError(f"a glTF export takes one motion, got {len(motions)} inputs")
        size = write_gltf(out, motions[0], color=colors[0] if colors else None)
        print(f"wrote {out}: {motions[0].num_frames} frames, {motions[0].num_joints} joints, {size / 1e6:.2f} MB")
        return 0
    if ext not in (".html", ".htm"):
        raise ParameterError(f"output must end in .html, .glb or .gltf, got {out.name!r} "
                             "(videos: kinodyn render FILE -o out.mp4)")
    from kinodyn.viz import html

    page = html.write(out, actors(args, motions), overlays_arg(args.overlays), title=args.title, layout=args.layout,
                      body=args.body, camera=args.camera, autoplay=not args.paused, curves=args.curves,
                      loop_clips=args.loop_clips)
    frames = max(f for _, _, f in page.scenes)
    n = len(motions) + len(args.ghost)
    print(f"wrote {out}: {n} character{'s' * (n != 1)}, {frames} frames, "
          f"{page.bytes / 1e6:.2f} MB")
    return 0
