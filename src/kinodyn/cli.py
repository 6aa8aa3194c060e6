"""The ``kinodyn`` command.

Core commands live here (``info``, ``convert``, ``library``, ``bench``, ``demo``); each capability adds
its own commands in its package's ``register.py`` (:mod:`kinodyn.registry`), each a module defining
``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``. Motion inputs are read by
:mod:`kinodyn.commands.inputs`, the same way for every command. Bad input prints one line and exits 2;
no tracebacks reach the user.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from kinodyn import registry
from kinodyn.commands.inputs import add_motion_options, load_motion, parse_scale
from kinodyn.errors import KinodynError

__all__ = ["build_parser", "main"]


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line and exit 2, like every other bad input
        self.exit(2, f"{self.prog}: error: {message}\n")


# --------------------------------------------------------------------------- info


def _summary(motion, drop_tpose: bool = False) -> dict:
    """What ``kinodyn info`` reports. Contacts are found on the captured frames (an added T-pose frame,
    see :mod:`kinodyn.io.tpose`, is left out) and given in the file's time."""
    from kinodyn import contacts
    from kinodyn.io import drop_added_tpose

    sk = motion.skeleton
    out = {
        "name": motion.name,
        "joints": sk.num_joints,
        "end_sites": int(len(sk.end_parents)),
        "root": sk.names[0],
        "frames": motion.num_frames,
        "fps": round(motion.fps, 6),
        "duration_s": round(motion.duration, 4),
        "height_m": None,
        "added_tpose": False,
    }
    if motion.num_frames == 0:
        out["contacts"] = "unavailable: the motion has no frames"
        return out
    out["height_m"] = round(float(np.ptp(motion[:1].global_positions()[0, :, 2])), 4)
    captured, out["added_tpose"] = drop_added_tpose(motion)
    shift = 1 if out["added_tpose"] else 0
    try:
        c = contacts.detect(captured)
        s = contacts.sliding(captured, c)
        out["contacts"] = {side: [[round((a + shift) / motion.fps, 3), round((b + shift) / motion.fps, 3)]
                                  for a, b in iv] for side, iv in c.intervals().items()}
        out["sliding_cm_s"] = round(s.cm_per_s, 3)
    except KinodynError as e:
        out["contacts"] = f"unavailable: {e}"
    return out


def _cmd_info(args) -> int:
    from kinodyn.io.tpose import ADDED_TPOSE_NOTE

    motion = load_motion(args.file, args)
    if motion.num_frames == 0:
        raise KinodynError(f"{args.file}: the motion has no frames")
    info = _summary(motion)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    height = "" if info["height_m"] is None else f", height {info['height_m']:.2f} m"
    print(f"{args.file}")
    print(f"  skeleton   {info['joints']} joints ({info['end_sites']} end sites), root {info['root']!r}{height}")
    print(f"  motion     {info['frames']} frames at {info['fps']:g} fps = {info['duration_s']:.2f} s")
    if info["added_tpose"]:
        print(f"  T-pose     {ADDED_TPOSE_NOTE}")
    if isinstance(info["contacts"], dict):
        for side, iv in info["contacts"].items():
            spans = ", ".join(f"{a:.2f}-{b:.2f}" for a, b in iv[:8]) + (" ..." if len(iv) > 8 else "")
            print(f"  {side:<5} foot {len(iv)} contacts (s): {spans}")
        print(f"  sliding    {info['sliding_cm_s']:.2f} cm/s (horizontal foot speed in contact)")
    else:
        print(f"  contacts   {info['contacts']}")
    if args.verbose:
        sk = motion.skeleton
        for j, n in enumerate(sk.names):
            p = sk.parents[j]
            print(f"    {j:3d} {n:<24} parent {sk.names[p] if p >= 0 else '-'}")
    return 0


# --------------------------------------------------------------------------- convert


def _cmd_convert(args) -> int:
    from kinodyn.io import drop_added_tpose, save

    if args.drop_first < 0:
        raise KinodynError(f"--drop-first must be a number of frames >= 0, got {args.drop_first}")
    if args.fps is not None and not (np.isfinite(args.fps) and args.fps > 0):
        raise KinodynError(f"--fps must be a positive frame rate, got {args.fps:g}")
    kw = {}
    if args.output.lower().endswith(".bvh"):
        try:
            kw = {"scale": parse_scale(args.out_unit), "up": args.out_up, "order": args.order}
        except KinodynError:
            raise KinodynError(f"--out-unit must be a unit (m, cm, mm, inch, cmu) or metres per unit, "
                               f"got {args.out_unit!r}") from None
    motion = load_motion(args.input, args)
    if args.drop_tpose:
        motion, _ = drop_added_tpose(motion)
    if args.drop_first:
        if args.drop_first >= motion.num_frames:
            raise KinodynError(f"--drop-first {args.drop_first} leaves no frames of {args.input} "
                               f"({motion.num_frames} frames)")
        motion = motion[args.drop_first:]
    if args.fps:
        try:
            motion = motion.resample(args.fps)
        except KinodynError as e:
            raise KinodynError(f"--fps {args.fps:g}: {e}") from None
    if args.mirror:
        motion = motion.mirrored()
    save(args.output, motion, **kw)
    print(f"wrote {args.output}: {motion.num_frames} frames at {motion.fps:g} fps, {motion.num_joints} joints")
    return 0


# --------------------------------------------------------------------------- library


def _cmd_library(args) -> int:
    from kinodyn.data import library

    if args.action == "list":
        for name in library.names():
            info = library.describe(name)
            print(f"{name:<28} {info}")
        return 0
    if args.action == "export":
        if not args.name or not args.output:
            raise KinodynError("usage: kinodyn library export NAME OUT.bvh")
        from kinodyn.io import save

        motion = library.load(args.name)
        save(args.output, motion)
        print(f"wrote {args.output}: {motion.num_frames} frames at {motion.fps:g} fps")
        return 0
    raise KinodynError(f"unknown library action {args.action!r} (list, export)")


# --------------------------------------------------------------------------- bench / demo


def _cmd_bench(args) -> int:
    from kinodyn import bench
    from kinodyn.progress import progress

    result = bench.run(args.name, quick=args.quick, json_path=args.json, progress=progress)
    width = max(len(k) for k in result.metrics) if result.metrics else 0
    for k, v in result.metrics.items():
        print(f"{k:<{width}}  {v:,.6g} {result.units.get(k, '')}")
    for k, v in result.baseline.items():
        print(f"baseline {k}: {v:,.6g}")
    if args.json:
        print(f"wrote {args.json}")
    return 0


def _cmd_demo(args) -> int:
    from kinodyn.demo import run_demo

    run_demo(Path(args.out), only=args.only)
    return 0


# --------------------------------------------------------------------------- main


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The ``kinodyn`` parser for the command line ``argv`` (default: every capability command loaded).

    Of the capability commands only the one ``argv`` names (its first word that is not an option) is
    imported; with ``argv=None`` all are.
    """
    command = next((a for a in argv if not a.startswith("-")), None) if argv is not None else None
    p = _Parser(prog="kinodyn", description="Physically interactive character animation.")
    p.add_argument("--version", action="version", version=f"kinodyn {_version()}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    q = sub.add_parser("info", help="skeleton, frames, fps, contacts and sliding of a motion file",
                       description="Print what a motion file holds: its skeleton (joints, end sites, height), "
                       "frames, frame rate and duration, whether frame 0 is a T-pose added by the converter "
                       "(cgspeed CMU files), the foot contacts and how much the feet slide in contact.")
    q.add_argument("file", help="motion file: .bvh, .amc (with its .asf) or .npz written by kinodyn")
    q.add_argument("--json", action="store_true", help="print the summary as JSON")
    q.add_argument("-v", "--verbose", action="store_true", help="also list the joints and their parents")
    add_motion_options(q)
    q.set_defaults(func=_cmd_info)

    q = sub.add_parser("convert", help="convert BVH/AMC/NPZ to BVH or NPZ (units, fps, mirror)",
                       description="Read a motion file and write it as BVH or kinodyn .npz (chosen by the "
                       "output's ending), optionally dropping frames, resampling, mirroring, and choosing the "
                       "BVH unit, up axis and rotation order. Every frame is kept unless asked; the output "
                       "is written atomically.")
    q.add_argument("input", help="motion file to read: .bvh, .amc or .npz")
    q.add_argument("output", help="file to write: .bvh or .npz")
    add_motion_options(q)
    q.add_argument("--fps", type=float, help="resample to this frame rate (frames per second, > 0)")
    q.add_argument("--mirror", action="store_true", help="swap left and right")
    q.add_argument("--drop-tpose", action="store_true",
                   help="drop frame 0 when it is a T-pose added by the converter (cgspeed CMU files)")
    q.add_argument("--drop-first", type=int, default=0, metavar="N",
                   help="drop the first N frames (N >= 0, fewer than the frames; applied after --drop-tpose)")
    q.add_argument("--out-unit", default="cm",
                   help="BVH output length unit (m, cm, mm, inch, cmu) or metres per unit (default cm)")
    q.add_argument("--out-up", default="y", choices=["y", "z"], help="BVH output up axis (default y)")
    q.add_argument("--order", default="zyx", help="BVH output rotation channel order (default zyx)")
    q.set_defaults(func=_cmd_convert)

    q = sub.add_parser("library", help="the built-in clips: list, export NAME OUT.bvh")
    q.add_argument("action", choices=["list", "export"])
    q.add_argument("name", nargs="?")
    q.add_argument("output", nargs="?")
    q.set_defaults(func=_cmd_library)

    q = sub.add_parser("bench", help="run a registered benchmark")
    q.add_argument("name")
    q.add_argument("--json", help="write results to this JSON file")
    q.add_argument("--quick", action="store_true", help="finish within a minute")
    q.set_defaults(func=_cmd_bench)

    q = sub.add_parser("demo", help="run the demo on the built-in data, writing to --out")
    q.add_argument("--out", default="out")
    q.add_argument("--only", action="append", help="run only this demo part (repeatable)")
    q.set_defaults(func=_cmd_demo)

    _add_capability_commands(sub, command, load_all=argv is None)
    return p


def _add_capability_commands(sub, command: str | None, load_all: bool) -> None:
    """The registered commands: only ``command`` (or, with ``load_all``, every one) is imported, for its
    arguments; the others are listed with the help text read from their module's source, so
    ``kinodyn --help`` loads no capability."""
    root = Path(__file__).resolve().parent
    for name, modname in registry.commands().items():
        if not load_all and name != command:
            text = registry.module_constants(modname, ("HELP", "DESCRIPTION"), root)
            if text is None:
                continue  # the capability is not part of this build yet
            if "HELP" in text:
                sub.add_parser(name, help=text["HELP"], description=text.get("DESCRIPTION", text["HELP"]))
                continue
        mod = registry.load(modname)
        if mod is None:
            continue  # the capability is not part of this build yet
        q = sub.add_parser(name, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP))
        mod.add_arguments(q)
        q.set_defaults(func=mod.run)


def _version() -> str:
    from kinodyn.version import __version__

    return __version__


def main(argv: list[str] | None = None) -> int:
    parser = build_parser(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("kinodyn: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output cut short by a pager or `head`: not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (KinodynError, OSError) as e:  # bad input or an unusable path: one line, exit 2
        msg = str(e) if not isinstance(e, OSError) or not e.filename else f"{e.filename}: {e.strerror}"
        from kinodyn.io.amc import PASS_ASF

        msg = msg.replace(PASS_ASF, "give it with --asf FILE.asf")
        print(f"kinodyn: error: {' '.join(msg.split())}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
