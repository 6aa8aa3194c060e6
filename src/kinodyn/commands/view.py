"""``kinodyn view FILE... -o out.html``: a self-contained viewer page (or a glTF export) of motions.

Inputs are motion files (``.bvh``, ``.amc``, ``.npz``) or names of built-in clips (``kinodyn library
list``). The page plays every input in one world; ``--layout row`` puts clips side by side.
``-o out.glb`` / ``out.gltf`` writes a glTF 2.0 skeleton animation of one input instead.
"""

from __future__ import annotations

from pathlib import Path

from kinodyn.commands.inputs import add_motion_options, load_motion_or_clip
from kinodyn.errors import ParameterError

HELP = "write a self-contained HTML viewer (or .glb/.gltf) of motion files or built-in clips"

_OVERLAYS = ("contacts", "phases", "trajectories")


def add_input_arguments(p) -> None:
    """Arguments shared by ``view`` and ``render``: inputs and how to read them."""
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
    p.add_argument("--layout", choices=["world", "row", "grid"], default="world",
                   help="world: as recorded; row/grid: side by side (default: world)")


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


def run(args) -> int:
    motions = load_inputs(args)
    out = Path(args.output or f"{Path(args.inputs[0]).stem}.html")
    names = split_list(args.names)
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

    page = html.write(out, motions, overlays_arg(args.overlays), names=names, colors=colors, title=args.title,
                      layout=args.layout, body=args.body, camera=args.camera, autoplay=not args.paused)
    frames = max(f for _, _, f in page.scenes)
    print(f"wrote {out}: {len(motions)} character{'s' * (len(motions) != 1)}, {frames} frames, "
          f"{page.bytes / 1e6:.2f} MB")
    return 0
