"""Scene files: a documented YAML format for contact scenes, validated with errors that name the entry.

A scene file (see ``kinodyn/contact/scenes/*.yaml`` for the shipped ones) is a mapping::

    name: two_arms                      # defaults to the file name
    description: one line
    fps: 60                             # frame rate of the simulation (default: the avatar motion's)
    frames: 600                         # frames to run (default: the motion's length)
    include: [gallery.yaml]             # other scene files whose objects come first (relative paths)
    objects:
      - name: table                     # unique
        kind: fixed                     # fixed | simulated | driven
        material: wood                  # wood | human | metal (Table 1)
        pos: [0, 0, 0.7]                # metres (default origin)
        rot: [0, 0, 90]                 # degrees about x, y, z (extrinsic), or quat: [w, x, y, z]
        mass: 1.0                       # kg (simulated and driven objects)
        velocity: [0, 0, 0]             # m/s, simulated objects
        shape: {box: [0.8, 0.5, 0.02]}  # one convex piece: box half sizes | sphere r | capsule [r, half
                                        #   length] | ellipsoid [a, b, c]
        pieces:                         # or several convex pieces, each a shape with its own pos/rot
          - {box: [0.05, 0.05, 0.35], pos: [0.7, 0.4, -0.35]}
        mesh: sculpture.obj             # or a mesh file (OBJ, STL, PLY, GLB) decomposed by CoACD;
        mesh: {prism: [[0, 0], [1, 0], [1, 0.2]], depth: 1.0}   # or a prism of an x-z polygon
        mesh: {torus: [0.3, 0.08]}      # or a torus (major, minor radius)
        scale: 1.0                      # mesh scale
    avatar:                             # the driven avatar (optional)
      motion: push                      # a built-in clip, a scenario motion of kinodyn.contact.motions,
                                        #   or a motion file (BVH, AMC, NPZ) relative to the scene file,
                                        #   or mocap:REL, a file of the user's motion-capture folder
                                        #   (see mocap_folder; `contact run --motion PATH` overrides)
      place: [0, 0, 0]                  # x, y (m) and heading (deg) of the clip's first frame
      material: human
      self_collision: true
    hand:                               # the driven articulated hand (optional)
      path: flick                       # a hand path of kinodyn.contact.motions
      mass: 0.5                         # kg, for the virtual coupling (K = 1000, R = 40)

Errors are :class:`kinodyn.errors.FileFormatError` naming the file and the entry
(``objects[3] 'table': ...``). Motion-capture data is never shipped: a ``mocap:`` motion is looked up
when the scene is run (:func:`resolve_motion`), so listing and parsing scenes works without it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinodyn.contact import meshes
from kinodyn.contact.setting import KINDS, MATERIALS, SHAPES, Piece, SceneObject
from kinodyn.errors import FileFormatError, KinodynError
from kinodyn.io import mocapdir
from kinodyn.math import quat

__all__ = [
    "AvatarSpec",
    "HandSpec",
    "Scene",
    "load_scene",
    "mocap_folder",
    "parse_scene",
    "resolve_motion",
    "scenario_names",
    "scenario_path",
    "scenes_dir",
]

#: prefix of a scene's avatar motion that names a file of the user's motion-capture folder
MOCAP_PREFIX = "mocap:"
_TOP = {"name", "description", "fps", "frames", "include", "objects", "avatar", "hand"}
_OBJ = {"name", "kind", "material", "pos", "rot", "quat", "mass", "velocity", "shape", "pieces", "mesh", "scale"}


@dataclass(frozen=True)
class AvatarSpec:
    """The scene's avatar: ``motion`` (clip, scenario motion or resolved file path), ``place`` (x, y,
    heading in degrees), ``material``, ``self_collision``."""

    motion: str
    place: tuple[float, float, float] = (0.0, 0.0, 0.0)
    material: str = "human"
    self_collision: bool = True


@dataclass(frozen=True)
class HandSpec:
    """The scene's articulated hand: ``path`` (a hand path name) and ``mass`` (kg)."""

    path: str
    mass: float = 0.5


@dataclass(frozen=True)
class Scene:
    """A parsed scene file."""

    name: str
    description: str
    objects: tuple[SceneObject, ...]
    avatar: AvatarSpec | None = None
    hand: HandSpec | None = None
    fps: float | None = None
    frames: int | None = None
    path: str = ""


def scenes_dir() -> Path:
    """The folder of the shipped scenario files."""
    return Path(__file__).resolve().parent / "scenes"


def scenario_names() -> list[str]:
    """Names of the shipped scenarios (scene files that drive something)."""
    return sorted(p.stem for p in scenes_dir().glob("*.yaml") if p.stem != "gallery")


def scenario_path(name_or_path) -> Path:
    """A shipped scenario by name, or a scene file path."""
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml"):
        if not p.exists():
            raise FileNotFoundError(f"{p}: no such scene file")
        return p
    q = scenes_dir() / f"{name_or_path}.yaml"
    if not q.exists():
        from kinodyn.errors import UnknownNameError

        raise UnknownNameError(f"no scenario named {name_or_path!r}; scenarios: {', '.join(scenario_names())}")
    return q


def mocap_folder(folder=None) -> Path | None:
    """The motion-capture folder ``mocap:`` motions are found in (:func:`kinodyn.io.mocapdir.find`):
    ``folder`` when given, else ``$KINODYN_MOCAP``, else ``shared/mocap`` beside the checkout; None when
    there is none."""
    return mocapdir.find(folder)


def resolve_motion(motion: str, folder=None) -> str:
    """The motion name or file a scene's avatar plays: ``mocap:REL`` becomes the file ``REL`` of
    :func:`mocap_folder` (a clear error when the folder or the file is missing); anything else is
    returned as it is."""
    if not motion.startswith(MOCAP_PREFIX):
        return motion
    rel = motion[len(MOCAP_PREFIX):].strip()
    root = mocap_folder(folder)
    hint = "pass --motion PATH to the file, or set KINODYN_MOCAP to the folder that holds it"
    if root is None:
        asked = folder if folder is not None else os.environ.get("KINODYN_MOCAP")
        where = f"the folder {asked} is not there" if asked else "KINODYN_MOCAP is not set"
        raise KinodynError(f"this scene plays the motion-capture file {rel}, but {where}: {hint}")
    path = root / rel
    if not path.is_file():
        raise KinodynError(f"this scene plays the motion-capture file {rel}, not found in {root}: {hint}")
    return str(path)


def _err(path, where: str, msg: str) -> FileFormatError:
    return FileFormatError(f"{where}: {msg}", path)


def _vec(v, n: int, path, where: str, key: str) -> np.ndarray:
    a = np.asarray(v, dtype=object).reshape(-1)
    try:
        out = np.array([float(x) for x in a])
    except (TypeError, ValueError):
        raise _err(path, where, f"{key} must be {n} numbers, got {v!r}") from None
    if out.shape != (n,) or not np.all(np.isfinite(out)):
        raise _err(path, where, f"{key} must be {n} finite numbers, got {v!r}")
    return out


def _rotation(entry: dict, path, where: str) -> np.ndarray:
    if "quat" in entry:
        q = _vec(entry["quat"], 4, path, where, "quat")
        if np.linalg.norm(q) < 1e-9:
            raise _err(path, where, "quat must not be zero")
        return q / np.linalg.norm(q)
    if "rot" in entry:
        e = np.deg2rad(_vec(entry["rot"], 3, path, where, "rot"))
        return quat.from_euler(e[::-1], "zyx")
    return np.array([1.0, 0.0, 0.0, 0.0])


def _shape(spec, path, where: str) -> Piece:
    if not isinstance(spec, dict):
        raise _err(path, where, f"a shape must be a mapping like {{box: [x, y, z]}}, got {spec!r}")
    kinds = [k for k in spec if k in SHAPES and k != "hull"]
    if len(kinds) != 1:
        raise _err(path, where, f"a shape needs exactly one of box, sphere, capsule, ellipsoid, got {sorted(spec)}")
    k = kinds[0]
    size = _vec(spec[k], SHAPES[k], path, where, k)
    if np.any(size <= 0):
        raise _err(path, where, f"{k} sizes must be positive, got {size.tolist()}")
    pos = _vec(spec.get("pos", (0, 0, 0)), 3, path, where, "pos")
    return Piece(k, tuple(size), pos, _rotation(spec, path, where))


def _mesh(spec, entry: dict, base: Path, path, where: str) -> tuple[Piece, ...]:
    scale = float(entry.get("scale", 1.0))
    try:
        if isinstance(spec, str):
            v, f = meshes.load_mesh(base / spec, scale)
        elif isinstance(spec, dict) and "prism" in spec:
            v, f = meshes.prism(spec["prism"], float(spec.get("depth", 1.0)))
            v = v * scale
        elif isinstance(spec, dict) and "torus" in spec:
            import trimesh

            r = _vec(spec["torus"], 2, path, where, "torus")
            t = trimesh.creation.torus(r[0], r[1], major_sections=int(spec.get("sections", 24)),
                                       minor_sections=int(spec.get("minor_sections", 10)))
            v, f = np.asarray(t.vertices) * scale, np.asarray(t.faces)
        else:
            raise _err(path, where, f"mesh must be a file name, {{prism: ...}} or {{torus: ...}}, got {spec!r}")
        return tuple(meshes.mesh_pieces(v, f, name=where))
    except FileNotFoundError as e:
        raise _err(path, where, str(e)) from None
    except FileFormatError as e:
        raise _err(path, where, e.reason) from None


def _object(entry, k: int, base: Path, path) -> SceneObject:
    where = f"objects[{k}]"
    if not isinstance(entry, dict):
        raise _err(path, where, f"must be a mapping, got {type(entry).__name__}")
    name = entry.get("name")
    if not isinstance(name, str) or not name:
        raise _err(path, where, "needs a name (a non-empty string)")
    where = f"objects[{k}] {name!r}"
    unknown = sorted(set(entry) - _OBJ)
    if unknown:
        raise _err(path, where, f"unknown keys {unknown}; allowed: {sorted(_OBJ)}")
    kind = entry.get("kind", "fixed")
    if kind not in KINDS:
        raise _err(path, where, f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    material = entry.get("material", "wood")
    if material not in MATERIALS:
        raise _err(path, where, f"material must be one of {', '.join(MATERIALS)}, got {material!r}")
    given = [g for g in ("shape", "pieces", "mesh") if g in entry]
    if len(given) != 1:
        raise _err(path, where, f"needs exactly one of shape, pieces, mesh; got {given or 'none'}")
    if "shape" in entry:
        pieces = (_shape(entry["shape"], path, where),)
    elif "pieces" in entry:
        if not isinstance(entry["pieces"], list) or not entry["pieces"]:
            raise _err(path, where, "pieces must be a non-empty list of shapes")
        pieces = tuple(_shape(p, path, f"{where} pieces[{i}]") for i, p in enumerate(entry["pieces"]))
    else:
        pieces = _mesh(entry["mesh"], entry, base, path, where)
    try:
        mass = float(entry.get("mass", 1.0))
    except (TypeError, ValueError):
        raise _err(path, where, f"mass must be a number of kg, got {entry.get('mass')!r}") from None
    if not (np.isfinite(mass) and mass > 0):
        raise _err(path, where, f"mass must be a positive number of kg, got {mass}")
    return SceneObject(name, kind, material, pieces, _vec(entry.get("pos", (0, 0, 0)), 3, path, where, "pos"),
                       _rotation(entry, path, where), mass,
                       _vec(entry.get("velocity", (0, 0, 0)), 3, path, where, "velocity"))


def _avatar(spec, base: Path, path) -> AvatarSpec:
    where = "avatar"
    if not isinstance(spec, dict) or "motion" not in spec:
        raise _err(path, where, "must be a mapping with a motion (a clip name or a motion file)")
    motion = str(spec["motion"])
    if Path(motion).suffix.lower() in (".bvh", ".amc", ".npz") and not motion.startswith(MOCAP_PREFIX):
        full = Path(motion).expanduser()
        full = full if full.is_absolute() else base / full
        motion = str(full)
    place = tuple(_vec(spec.get("place", (0, 0, 0)), 3, path, where, "place"))
    material = spec.get("material", "human")
    if material not in MATERIALS:
        raise _err(path, where, f"material must be one of {', '.join(MATERIALS)}, got {material!r}")
    return AvatarSpec(motion, place, material, bool(spec.get("self_collision", True)))


def parse_scene(data, path="<scene>", base: Path | None = None, _seen=()) -> Scene:
    """A :class:`Scene` from the mapping ``data`` of a scene file (see the module docstring)."""
    base = Path(base) if base is not None else Path(".")
    if not isinstance(data, dict):
        raise FileFormatError(f"a scene file must hold a mapping, got {type(data).__name__}", path)
    unknown = sorted(set(data) - _TOP)
    if unknown:
        raise FileFormatError(f"unknown top-level keys {unknown}; allowed: {sorted(_TOP)}", path)
    objects = []
    inc = data.get("include", [])
    for name in [inc] if isinstance(inc, str) else list(inc):
        objects += list(load_scene(base / name, _seen=_seen + (str(path),)).objects)
    raw = data.get("objects", [])
    if not isinstance(raw, list):
        raise FileFormatError("objects must be a list of mappings", path)
    objects += [_object(e, k, base, path) for k, e in enumerate(raw)]
    names = [o.name for o in objects]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise FileFormatError(f"object names must be unique, repeated: {', '.join(dup)}", path)
    avatar = _avatar(data["avatar"], base, path) if data.get("avatar") is not None else None
    hand = None
    if data.get("hand") is not None:
        h = data["hand"]
        if not isinstance(h, dict) or "path" not in h:
            raise _err(path, "hand", "must be a mapping with a path (a hand path name)")
        hand = HandSpec(str(h["path"]), float(h.get("mass", 0.5)))
    fps = data.get("fps")
    frames = data.get("frames")
    for key, val in (("fps", fps), ("frames", frames)):
        if val is not None and (not isinstance(val, (int, float)) or val <= 0):
            raise FileFormatError(f"{key} must be a positive number, got {val!r}", path)
    return Scene(str(data.get("name") or Path(str(path)).stem), str(data.get("description", "")), tuple(objects),
                 avatar, hand, None if fps is None else float(fps), None if frames is None else int(frames), str(path))


def load_scene(path, _seen=()) -> Scene:
    """Read and check a scene file (YAML)."""
    import yaml

    path = Path(path)
    if str(path) in _seen:
        raise FileFormatError(f"include loop: {' -> '.join(list(_seen) + [str(path)])}", path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such scene file")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as e:
        line = getattr(getattr(e, "problem_mark", None), "line", None)
        raise FileFormatError(f"not valid YAML: {getattr(e, 'problem', e)}", path,
                              None if line is None else line + 1) from None
    try:
        return parse_scene(data, path, path.parent, _seen)
    except FileFormatError:
        raise
    except KinodynError as e:
        raise FileFormatError(str(e), path) from None
