"""``kinodyn body FILE.bvh -o body.xml``: the MuJoCo body (MJCF) of a skeleton.

The skeleton comes from a motion file (BVH, ASF/AMC, NPZ) or a built-in name (``humanoid``, or any
clip of the built-in library, whose skeleton is the humanoid). The MJCF is checked by compiling it with
MuJoCo's own XML loader before it is written (atomically), so a file that exists always loads.
"""

from __future__ import annotations

from pathlib import Path

from kinodyn.commands.inputs import add_motion_options, motion_kwargs
from kinodyn.errors import KinodynError, UnknownNameError

HELP = "write the MuJoCo body (MJCF) of a skeleton: kinodyn body FILE.bvh -o body.xml"
DESCRIPTION = ("Build the simulated body of a skeleton (one rigid body per bone, capsules and box feet, "
               "masses scaled to --mass, joint limits from kinodyn.limits, PD servos) and write it as MJCF.")


def add_arguments(p) -> None:
    p.add_argument("source", help="motion file (.bvh, .amc, .npz) or a built-in name (humanoid, walk, ...)")
    p.add_argument("-o", "--output", required=True, help="MJCF file to write")
    p.add_argument("--mass", type=float, default=70.0, help="total body mass in kg (default 70)")
    p.add_argument("--root", choices=["free", "fixed"], default="free", help="free root joint or fixed root")
    p.add_argument("--merge-toes", action="store_true", help="one box per foot, toes merged into it")
    p.add_argument("--no-self-collision", action="store_true", help="segments of the body do not collide")
    add_motion_options(p, asf=False)
    p.add_argument("-v", "--verbose", action="store_true", help="print the segment table")


def load_skeleton(source: str, scale=None, up=None):
    """A skeleton from a motion file or a built-in name."""
    path = Path(source)
    if path.exists():
        from kinodyn.io import load

        return load(path, **motion_kwargs(path, scale, up)).skeleton
    from kinodyn.data import library
    from kinodyn.data.skeleton import humanoid

    if source == "humanoid":
        return humanoid()
    if source in library.names():
        return library.load(source).skeleton
    if path.suffix:
        raise FileNotFoundError(f"{source}: no such file")
    raise UnknownNameError(f"{source!r} is neither a file nor a built-in name; built-in: humanoid, "
                           f"{', '.join(library.names())}")


def run(args) -> int:
    from kinodyn.io.atomic import atomic_write_bytes
    from kinodyn.physics.body import BodyConfig, build_body, model_from_xml

    sk = load_skeleton(args.source, args.scale, args.up)
    cfg = BodyConfig(mass=args.mass, root=args.root, merge_toes=args.merge_toes,
                     self_collision=not args.no_self_collision)
    body = build_body(sk, cfg)
    xml = body.to_xml()
    try:
        model = model_from_xml(xml)
    except ValueError as e:  # pragma: no cover - a bug, not bad input
        raise KinodynError(f"internal: the MJCF does not compile in MuJoCo: {e}") from None
    atomic_write_bytes(args.output, xml.encode())
    merged = [f"{n} ({why})" for s in body.map.segments for n, why in zip(s.merged, s.merged_why)]
    print(f"wrote {args.output}: {body.map.num_bodies} bodies from {sk.num_joints} joints, "
          f"{model.njnt} joints, {model.nu} controls, {body.total_mass:.1f} kg")
    if merged:
        print(f"  merged into their parents: {', '.join(merged)}")
    if args.verbose:
        for s, m in zip(body.map.segments, model.body_mass[1:]):
            print(f"  {s.name:<16} {s.cls:<9} {s.kind:<5} {m:6.2f} kg  r={s.radius:.3f} m  L={s.length:.3f} m")
    return 0
