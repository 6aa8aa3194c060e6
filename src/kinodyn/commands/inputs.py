"""Reading motions from the command line: the input options and their loading, shared by every command.

``kinodyn info``, ``convert``, ``view``, ``render``, ``body`` and any capability command take motion
files the same way: ``--scale`` (a unit name or metres per unit), ``--up`` (the file's up axis) and, for
ASF/AMC, ``--asf``; a name that is not a file may be a built-in clip (``kinodyn library list``).
"""

from __future__ import annotations

from pathlib import Path

from kinodyn.errors import KinodynError

__all__ = ["add_motion_options", "library_clip", "load_motion", "load_motion_or_clip", "motion_kwargs",
           "parse_scale"]

HELP_SCALE = ("input length unit (m, cm, mm, inch, cmu) or metres per unit; default: detected from the "
              "body's size")
HELP_UP = "input up axis (default y for BVH and AMC)"
HELP_ASF = "ASF skeleton of an AMC file (default: the matching .asf beside it)"


def add_motion_options(parser, asf: bool = True) -> None:
    """Add ``--scale``, ``--up`` and (with ``asf``) ``--asf`` to an argparse parser."""
    parser.add_argument("--scale", help=HELP_SCALE)
    parser.add_argument("--up", choices=["y", "z"], help=HELP_UP)
    if asf:
        parser.add_argument("--asf", metavar="FILE.asf", help=HELP_ASF)


def parse_scale(s: str):
    """A ``--scale`` value: a unit name of :data:`kinodyn.io.bvh.UNIT_SCALES` or metres per file unit."""
    from kinodyn.io.bvh import UNIT_SCALES

    if s in UNIT_SCALES:
        return s
    try:
        v = float(s)
    except ValueError:
        raise KinodynError(f"--scale must be a unit ({', '.join(UNIT_SCALES)}) or metres per unit, got {s!r}") \
            from None
    return v


def motion_kwargs(path, scale=None, up=None, asf=None) -> dict:
    """Keyword arguments of :func:`kinodyn.io.load` for ``path`` from the option values (``None``: unset).

    ``--up`` does not apply to ``.npz`` (stored Z up), ``--asf`` only to ``.amc``.
    """
    name = str(path).lower()
    kw = {}
    if scale is not None:
        kw["scale"] = parse_scale(scale)
    if asf and name.endswith(".amc"):
        kw["asf"] = asf
    if up and not name.endswith(".npz"):
        kw["up"] = up
    return kw


def load_motion(path, args):
    """The motion in file ``path``, read with the options in ``args`` (those it lacks count as unset)."""
    from kinodyn.io import load

    return load(path, **motion_kwargs(path, getattr(args, "scale", None), getattr(args, "up", None),
                                      getattr(args, "asf", None)))


def library_clip(name: str):
    """The built-in clip ``name``.

    Raises:
        FileNotFoundError: ``name`` is neither a file nor a built-in clip.
    """
    try:
        from kinodyn.data import library
    except ImportError:
        library = None
    if library is not None and name in library.names():
        return library.load(name)
    raise FileNotFoundError(f"{name}: no such file, and not a built-in clip (kinodyn library list)")


def load_motion_or_clip(item: str, args):
    """A motion file when ``item`` exists, else the built-in clip of that name."""
    p = Path(item)
    return load_motion(p, args) if p.exists() else library_clip(item)
