"""``kinodyn render FILE... -o out.mp4``: a video (MP4, GIF) or still (PNG) rendered offscreen.

Same inputs, overlays, layouts and ``--loop`` / ``--hold`` as ``kinodyn view``; MuJoCo's renderer draws offscreen with the first backend
that works here (EGL, then OSMesa, then GLFW with a display; ``MUJOCO_GL`` to choose).
"""

from __future__ import annotations

from pathlib import Path

from kinodyn.commands.view import add_input_arguments, load_inputs, overlays_arg, split_list
from kinodyn.errors import ParameterError

HELP = "render motion files or built-in clips to MP4, GIF or PNG offscreen"


def add_arguments(p) -> None:
    add_input_arguments(p)
    p.add_argument("-o", "--output", help="output .mp4, .gif or .png (default: FIRST_INPUT.mp4)")
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=360)
    p.add_argument("--fps", type=float, help="output frame rate (default: the motion's, at most 30)")
    p.add_argument("--start", type=float, default=0.0, help="start time in seconds (PNG: the frame shown)")
    p.add_argument("--end", type=float, help="end time in seconds")
    p.add_argument("--camera", choices=["follow", "orbit", "fixed"], default="follow")
    p.add_argument("--azimuth", type=float, help="camera azimuth in degrees (default: side view)")
    p.add_argument("--elevation", type=float, help="camera elevation in degrees (default: -21)")
    p.add_argument("--distance", type=float, help="camera distance in metres (default: fit)")
    p.add_argument("--body", choices=["capsules", "bones"], default="capsules")
    p.add_argument("--fast", action="store_true", help="no shadows, no antialiasing (about 4x faster)")
    p.add_argument("--no-hud", action="store_true", help="no frame counter, names or phase bars")


def run(args) -> int:
    from kinodyn.progress import progress
    from kinodyn.viz.render import VIDEO_FORMATS, RenderConfig, render

    motions = load_inputs(args)
    out = Path(args.output or f"{Path(args.inputs[0]).stem}.mp4")
    if out.suffix.lower() not in VIDEO_FORMATS:
        raise ParameterError(f"output must end in {', '.join(VIDEO_FORMATS)}, got {out.name!r} "
                             "(viewer pages: kinodyn view FILE -o out.html)")
    cfg = RenderConfig(width=args.width, height=args.height, fps=args.fps, start=args.start, end=args.end,
                       camera=args.camera, azimuth=args.azimuth, elevation=args.elevation, distance=args.distance,
                       shadows=not args.fast, samples=0 if args.fast else RenderConfig.samples, body=args.body,
                       hud=not args.no_hud)
    res = render(out, motions, overlays_arg(args.overlays), names=split_list(args.names),
                 colors=split_list(args.colors), layout=args.layout, loop_clips=args.loop_clips, config=cfg,
                 progress=progress)
    print(f"wrote {out}: {res.frames} frame{'s' * (res.frames != 1)} at {res.fps:g} fps, {res.width}x{res.height}, "
          f"{res.seconds:.1f} s ({res.frames / max(res.seconds, 1e-9):.1f} frames/s)")
    return 0
