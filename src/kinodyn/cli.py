"""The ``kinodyn`` command.

Core commands live here (``info``, ``convert``, ``library``, ``bench``, ``demo``); each capability adds
its own command as a module in :mod:`kinodyn.commands` listed in :data:`COMMANDS` (a module defines
``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``). Bad input prints one line and exits 2;
no tracebacks reach the user.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path

import numpy as np

from kinodyn.errors import KinodynError

__all__ = ["main", "COMMANDS"]

#: command name -> module in kinodyn.commands (capability commands).
COMMANDS: dict[str, str] = {
    "body": "kinodyn.commands.body",
    "blend": "kinodyn.commands.blend",
    "view": "kinodyn.commands.view",
    "render": "kinodyn.commands.render",
    "response": "kinodyn.response.command",
}


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line and exit 2, like every other bad input
        self.exit(2, f"{self.prog}: error: {message}\n")


def _load_motion(path: str, args) -> "object":
    from kinodyn.io import load

    kw = {}
    if getattr(args, "scale", None) is not None:
        kw["scale"] = _parse_scale(args.scale)
    if getattr(args, "asf", None) and path.lower().endswith(".amc"):
        kw["asf"] = args.asf
    if getattr(args, "up", None) and not path.lower().endswith(".npz"):
        kw["up"] = args.up
    return load(path, **kw)


def _parse_scale(s: str):
    from kinodyn.io.bvh import UNIT_SCALES

    if s in UNIT_SCALES:
        return s
    try:
        v = float(s)
    except ValueError:
        raise KinodynError(f"--scale must be a unit ({', '.join(UNIT_SCALES)}) or metres per unit, got {s!r}") \
            from None
    return v


# --------------------------------------------------------------------------- info


def _summary(motion, drop_tpose: bool = False) -> dict:
    from kinodyn import contacts

    sk = motion.skeleton
    out = {
        "name": motion.name,
        "joints": sk.num_joints,
        "end_sites": int(len(sk.end_parents)),
        "root": sk.names[0],
        "frames": motion.num_frames,
        "fps": round(motion.fps, 6),
        "duration_s": round(motion.duration, 4),
        "height_m": round(float(np.ptp(motion.global_positions()[0, :, 2])), 4),
    }
    try:
        c = contacts.detect(motion)
        s = contacts.sliding(motion, c)
        out["contacts"] = {side: [[round(a / motion.fps, 3), round(b / motion.fps, 3)] for a, b in iv]
                           for side, iv in c.intervals().items()}
        out["sliding_cm_s"] = round(s.cm_per_s, 3)
    except KinodynError as e:
        out["contacts"] = f"unavailable: {e}"
    return out


def _cmd_info(args) -> int:
    motion = _load_motion(args.file, args)
    info = _summary(motion)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{args.file}")
    print(f"  skeleton   {info['joints']} joints ({info['end_sites']} end sites), root {info['root']!r}, "
          f"height {info['height_m']:.2f} m")
    print(f"  motion     {info['frames']} frames at {info['fps']:g} fps = {info['duration_s']:.2f} s")
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
    from kinodyn.io import save

    motion = _load_motion(args.input, args)
    if args.drop_first:
        motion = motion[args.drop_first:]
    if args.fps:
        motion = motion.resample(args.fps)
    if args.mirror:
        motion = motion.mirrored()
    kw = {}
    if args.output.lower().endswith(".bvh"):
        kw = {"scale": _parse_scale(args.out_unit), "up": args.out_up, "order": args.order}
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


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="kinodyn", description="Physically interactive character animation.")
    p.add_argument("--version", action="version", version=f"kinodyn {_version()}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    def motion_opts(q):
        q.add_argument("--scale", help="input unit (m, cm, mm, inch, cmu) or metres per unit; default: detect")
        q.add_argument("--up", choices=["y", "z"], help="input up axis (BVH default y)")
        q.add_argument("--asf", help="ASF skeleton for an AMC file (default: the .asf beside it)")

    q = sub.add_parser("info", help="skeleton, frames, fps, contacts and sliding of a motion file")
    q.add_argument("file")
    q.add_argument("--json", action="store_true", help="print JSON")
    q.add_argument("-v", "--verbose", action="store_true", help="list the joints")
    motion_opts(q)
    q.set_defaults(func=_cmd_info)

    q = sub.add_parser("convert", help="convert BVH/AMC/NPZ to BVH or NPZ (units, fps, mirror)")
    q.add_argument("input")
    q.add_argument("output")
    motion_opts(q)
    q.add_argument("--fps", type=float, help="resample to this frame rate")
    q.add_argument("--mirror", action="store_true", help="swap left and right")
    q.add_argument("--drop-first", type=int, default=0, metavar="N",
                   help="drop the first N frames (e.g. 1 for the T-pose frame of CMU BVH conversions)")
    q.add_argument("--out-unit", default="cm", help="BVH output unit (m, cm, mm, inch, cmu or metres per unit)")
    q.add_argument("--out-up", default="y", choices=["y", "z"], help="BVH output up axis")
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

    for name, modname in COMMANDS.items():
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as e:
            if e.name and modname.startswith(e.name):
                continue  # the capability is not part of this build yet
            raise
        q = sub.add_parser(name, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP))
        mod.add_arguments(q)
        q.set_defaults(func=mod.run)
    return p


def _version() -> str:
    from kinodyn import __version__

    return __version__


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (KinodynError, FileNotFoundError, IsADirectoryError, PermissionError) as e:
        msg = str(e) if not isinstance(e, OSError) or not e.filename else f"{e.filename}: {e.strerror}"
        print(f"kinodyn: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("kinodyn: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output cut short by a pager or `head`: not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
