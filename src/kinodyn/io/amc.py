"""Acclaim ASF skeletons and AMC motions (the CMU motion-capture database's original format).

Format (Acclaim, as written by Vicon for the CMU database): the ASF file gives each bone a unit
``direction`` and a ``length`` in the world frame of the rest pose, an ``axis`` (three angles and their
order, e.g. ``0 0 20 XYZ``) defining the bone's local frame ``C``, and the ``dof`` its AMC lines carry.
The AMC file lists, per frame, a frame number and one line per animated bone with its dof values.

Conventions used here (checked against the cgspeed BVH conversion of CMU trial 01_01, which agrees
within 1 cm on every frame):

* Angle orders are *extrinsic*, first listed first: ``axis a b c XYZ`` is ``C = Rz(c) Ry(b) Rx(a)``, and
  a bone with ``dof rx ry rz`` rotates by ``M = Rz(rz) Ry(ry) Rx(rx)`` (missing dofs are zero). The
  bone's rotation relative to its parent is ``C M C^-1``; the root's uses the ``:root`` ``orientation``
  (in the ``axis`` order) as ``C`` and the rotation dofs of ``order``.
* A bone starts at the end of its parent (the root's children start at the root) and ends at
  ``length * direction`` from its start, rotated with it. Each bone becomes a kinodyn joint at its
  start; bones without children get an end site at their tip.
* The AMC root translation is the root's absolute position (the ASF ``position`` is kept as the root
  offset but not added, as for BVH root channels).
* Units: ``:units length L`` means file lengths are inches times ``L`` (CMU: ``L = 0.45``), so a file
  unit is ``0.0254 / L`` metres. ``angle deg|rad`` sets the unit of ``axis``, ``orientation`` and,
  unless the AMC says ``:RADIANS``/``:DEGREES``, of the AMC values.
* Files are Y up; motions are converted to kinodyn's Z-up metres with the same turn as BVH files
  (:data:`kinodyn.io.bvh.Y_UP_TO_Z_UP`). The AMC format stores no frame rate; CMU captured at 120 Hz,
  the default (an AMC header line ``:SAMPLES-PER-SECOND n`` overrides it).

Parsing is vectorized: when every frame lists the same bones in the same order (all CMU files), the
whole body is split once and its numbers parsed by the compiled BVH number parser; otherwise, and to
locate the line of any error, a line-by-line reader groups the values by bone name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinodyn.errors import AMCParseError, MotionError, ParameterError, SkeletonError
from kinodyn.io import _numparse
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

__all__ = [
    "CMU_FPS",
    "MAX_ABS_VALUE",
    "PASS_ASF",
    "AsfSkeleton",
    "amc_from_text",
    "decode_text",
    "find_asf",
    "parse_amc",
    "parse_asf",
    "read_amc",
    "read_asf",
]

#: Frame rate of the CMU captures (AMC files do not store one).
CMU_FPS = 120.0
#: Largest magnitude accepted for any number (file units or angles).
MAX_ABS_VALUE = 1e9
#: how an error about a missing ASF says to name it (the CLI says its --asf option instead)
PASS_ASF = "pass asf= explicitly"
_MAX_BONES = 10_000
_ROT_DOFS = ("rx", "ry", "rz")
_TRANS_DOFS = ("tx", "ty", "tz")
_NUMBER_RE = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
_INT_RE = re.compile(r"[0-9]+\Z")
_LIMIT_RE = re.compile(r"\(\s*([^\s()]+)\s+([^\s()]+)\s*\)")


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """An ASF skeleton as stored: file units, file (Y-up) axes, bones in depth-first order.

    Attributes:
        names: ``J`` names, ``"root"`` first, then the bones in depth-first order of the hierarchy.
        parents: ``(J,)`` parent indices (``-1`` for the root).
        directions: ``(J, 3)`` unit bone directions in the rest pose's world frame (root: zero).
        lengths: ``(J,)`` bone lengths in file units (root: 0).
        frames: ``(J, 4)`` quaternion ``C`` of each bone's local frame (the root's from ``orientation``).
        dofs: per joint, the dof names in AMC order (``("rx", "ry", "rz")``; the root's include
            ``"tx", "ty", "tz"``).
        limits: per joint, the ``(lo, hi)`` of each dof (degrees or radians as in the file; may be inf).
        root_position: ``(3,)`` the ``:root`` ``position``.
        length_unit: the ``:units length`` value (file lengths are inches times this).
        angle_unit: ``"deg"`` or ``"rad"``.
        mass: the ``:units mass`` value.
        path: the file read, if any.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    directions: np.ndarray
    lengths: np.ndarray
    frames: np.ndarray
    dofs: tuple[tuple[str, ...], ...]
    limits: tuple[tuple[tuple[float, float], ...], ...]
    root_position: np.ndarray
    length_unit: float = 1.0
    angle_unit: str = "deg"
    mass: float = 1.0
    path: str | None = field(default=None, compare=False)

    @property
    def num_joints(self) -> int:
        return len(self.names)

    @property
    def metres_per_unit(self) -> float:
        """Metres per file length unit: ``0.0254 / length_unit`` (CMU: 0.0254 / 0.45)."""
        return 0.0254 / self.length_unit

    def children(self) -> list[list[int]]:
        out: list[list[int]] = [[] for _ in self.names]
        for j in range(1, self.num_joints):
            out[self.parents[j]].append(j)
        return out

    def skeleton(self, scale: float | str | None = None, up: str = "y") -> Skeleton:
        """The kinodyn :class:`~kinodyn.skeleton.Skeleton` (Z up, metres): one joint per bone at the
        bone's start, end sites at the tips of bones without children.

        Args:
            scale: metres per file unit or a unit name (see :data:`kinodyn.io.bvh.UNIT_SCALES`); by
                default :attr:`metres_per_unit`.
            up: the file's up axis, ``"y"`` (ASF files) or ``"z"``.
        """
        s = _resolve_scale(scale, self)
        turn = _up_turn(up)
        tips = self.directions * self.lengths[:, None]  # bone end relative to its start, file frame
        offsets = np.zeros((self.num_joints, 3))
        offsets[0] = self.root_position
        offsets[1:] = tips[self.parents[1:]]
        kids = self.children()
        leaves = np.array([j for j in range(1, self.num_joints) if not kids[j]], dtype=np.int64)
        end_offsets = tips[leaves] if len(leaves) else np.zeros((0, 3))
        if turn is not None:
            offsets = quat.mul_vec(turn, offsets)
            end_offsets = quat.mul_vec(turn, end_offsets) if len(leaves) else end_offsets
        return Skeleton(self.names, self.parents, offsets * s, leaves, end_offsets * s)


# --------------------------------------------------------------------------- helpers


def _up_turn(up: str):
    from kinodyn.io.bvh import Y_UP_TO_Z_UP

    up = str(up).lower()
    if up not in ("y", "z"):
        raise ParameterError(f"up must be 'y' or 'z', got {up!r}")
    return Y_UP_TO_Z_UP if up == "y" else None


def _resolve_scale(scale, asf: AsfSkeleton) -> float:
    from kinodyn.io.bvh import resolve_scale

    if scale is None:
        return asf.metres_per_unit
    return resolve_scale(scale)


def _order_euler(axes: list[str], angles: np.ndarray) -> tuple[str, np.ndarray]:
    """Pad an extrinsic rotation given by ``axes`` (e.g. ``["x", "z"]``) and ``angles (..., k)`` to three
    distinct axes with zero angles, for :func:`kinodyn.math.quat.from_euler`."""
    missing = [a for a in "xyz" if a not in axes]
    order = "".join(axes) + "".join(missing)
    pad = np.zeros(angles.shape[:-1] + (len(missing),))
    return order, np.concatenate([angles, pad], axis=-1)


def decode_text(data: bytes, path=None, err=AMCParseError) -> str:
    """Text of an ASF/AMC file's bytes: UTF-8 (BOM dropped), LF line ends; binary data is an error."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    if b"\x00" in data:
        raise err("not a text file (binary data)", path, data[: data.index(b"\x00")].count(b"\n") + 1)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise err("file is not valid UTF-8 text", path, data[: e.start].count(b"\n") + 1) from None
    if "\n" not in text and "\r" in text:
        text = text.replace("\r", "\n")
    return text.replace("\r", "")


def _kind(tok: str) -> str:
    return "a non-finite value" if tok.lower().lstrip("+-") in ("nan", "inf", "infinity") else "text"


def _read_text(path: Path, err) -> str:
    return decode_text(path.read_bytes(), path, err)


# --------------------------------------------------------------------------- ASF


class _AsfLines:
    """Lines of an ASF file without comments, as ``(line_number, tokens)``."""

    def __init__(self, text: str, path):
        self.path = path
        self.items = []
        for ln, line in enumerate(text.split("\n"), start=1):
            k = line.find("#")
            if k >= 0:
                line = line[:k]
            toks = line.split()
            if toks:
                self.items.append((ln, toks))
        self.i = 0

    def err(self, msg: str, line: int | None = None) -> AMCParseError:
        if line is None:
            line = self.items[min(self.i, len(self.items) - 1)][0] if self.items else 1
        return AMCParseError(msg, self.path, line)

    def number(self, tok: str, what: str, ln: int) -> float:
        if _NUMBER_RE.match(tok) is None:
            raise self.err(f"expected a number for {what}, found {_kind(tok)} {tok[:40]!r}", ln)
        v = float(tok)
        if abs(v) > MAX_ABS_VALUE:
            raise self.err(f"{what} is out of range: {tok[:40]!r} (limit {MAX_ABS_VALUE:g})", ln)
        return v


def _axis_frame(angles, order: str, unit: str, what: str, ln: int, lines: _AsfLines) -> np.ndarray:
    o = order.lower()
    if len(o) != 3 or sorted(o) != ["x", "y", "z"]:
        raise lines.err(f"{what} order must be a permutation of XYZ, found {order[:40]!r}", ln)
    a = np.asarray(angles, dtype=np.float64)
    if unit == "deg":
        a = np.deg2rad(a)
    return quat.from_euler(a, o, extrinsic=True)


def parse_asf(text: str, path=None) -> AsfSkeleton:
    """Parse the text of an ASF file (see :func:`read_asf`)."""
    lines = _AsfLines(text, path)
    items = lines.items
    if not items:
        raise AMCParseError("file is empty", path, 1)
    units = {"length": 1.0, "mass": 1.0, "angle": "deg"}
    root = {"order": None, "axis": "XYZ", "position": [0.0, 0.0, 0.0], "orientation": [0.0, 0.0, 0.0],
            "line": 1}
    bones: dict[str, dict] = {}
    bone_order: list[str] = []
    hier: dict[str, list[str]] = {}
    child_parent: dict[str, str] = {}
    hier_lines: dict[str, int] = {}
    section = None
    seen_root = seen_bones = seen_hier = False
    i = 0
    n = len(items)
    while i < n:
        ln, toks = items[i]
        head = toks[0]
        if head.startswith(":"):
            section = head[1:].lower()
            if section == "units":
                pass
            elif section == "root":
                seen_root = True
                root["line"] = ln
            elif section == "bonedata":
                seen_bones = True
            elif section == "hierarchy":
                seen_hier = True
            i += 1
            continue
        if section == "units":
            if len(toks) >= 2:
                key = head.lower()
                if key == "angle":
                    unit = toks[1].lower()
                    if unit in ("deg", "degree", "degrees"):
                        units["angle"] = "deg"
                    elif unit in ("rad", "radian", "radians"):
                        units["angle"] = "rad"
                    else:
                        raise lines.err(f"angle unit must be 'deg' or 'rad', found {toks[1][:40]!r}", ln)
                elif key in ("length", "mass"):
                    v = lines.number(toks[1], f"units {key}", ln)
                    if not 1e-6 <= v <= 1e6:
                        raise lines.err(f"units {key} must be between 1e-6 and 1e6, found {toks[1][:40]!r}", ln)
                    units[key] = v
            i += 1
        elif section == "root":
            key = head.lower()
            if key == "order":
                root["order"] = ([t.lower() for t in toks[1:]], ln)
            elif key == "axis":
                if len(toks) != 2:
                    raise lines.err("root axis must be one order string such as XYZ", ln)
                root["axis"] = toks[1]
                root["axis_line"] = ln
            elif key in ("position", "orientation"):
                if len(toks) != 4:
                    raise lines.err(f"root {key} needs 3 numbers, found {len(toks) - 1}", ln)
                root[key] = [lines.number(t, f"root {key}", ln) for t in toks[1:]]
            i += 1
        elif section == "bonedata":
            if head.lower() != "begin":
                raise lines.err(f"expected 'begin' of a bone in :bonedata, found {head[:40]!r}", ln)
            begin_line = ln
            bone = {"line": ln, "dof": (), "limits": [], "axis": None, "direction": None, "length": None}
            i += 1
            while True:
                if i >= n:
                    raise lines.err(f"bone starting at line {begin_line} has no 'end'", items[-1][0])
                ln, toks = items[i]
                key = toks[0].lower()
                if key == "end":
                    i += 1
                    break
                if key.startswith(":") or key == "begin":
                    raise lines.err(f"bone starting at line {begin_line} has no 'end'", ln)
                if key == "name":
                    if len(toks) != 2 or len(toks[1]) > 256:
                        raise lines.err("bone name must be one word of at most 256 characters", ln)
                    bone["name"] = toks[1]
                elif key == "direction":
                    if len(toks) != 4:
                        raise lines.err(f"bone direction needs 3 numbers, found {len(toks) - 1}", ln)
                    bone["direction"] = [lines.number(t, "bone direction", ln) for t in toks[1:]]
                elif key == "length":
                    if len(toks) != 2:
                        raise lines.err(f"bone length needs 1 number, found {len(toks) - 1}", ln)
                    v = lines.number(toks[1], "bone length", ln)
                    if v < 0:
                        raise lines.err(f"bone length must not be negative, found {toks[1][:40]!r}", ln)
                    bone["length"] = v
                elif key == "axis":
                    if len(toks) != 5:
                        raise lines.err("bone axis needs 3 angles and an order such as XYZ", ln)
                    bone["axis"] = ([lines.number(t, "bone axis", ln) for t in toks[1:4]], toks[4], ln)
                elif key == "dof":
                    dofs = tuple(t.lower() for t in toks[1:])
                    bad = [d for d in dofs if d not in _ROT_DOFS + _TRANS_DOFS + ("l",)]
                    if bad:
                        raise lines.err(f"unknown dof {bad[0][:40]!r} (expected rx, ry, rz)", ln)
                    if len(set(dofs)) != len(dofs):
                        raise lines.err(f"repeated dof in {' '.join(dofs)}", ln)
                    if any(d not in _ROT_DOFS for d in dofs):
                        raise lines.err("translation and length dofs (tx, ty, tz, l) on bones are not "
                                        "supported", ln)
                    bone["dof"] = dofs
                    bone["dof_line"] = ln
                elif key == "limits":
                    # limits (lo hi) pairs, one per dof, possibly on the following lines
                    chunk = " ".join(toks[1:])
                    while i + 1 < n and items[i + 1][1][0].startswith("("):
                        i += 1
                        chunk += " " + " ".join(items[i][1])
                    pairs = []
                    for lo, hi in _LIMIT_RE.findall(chunk):
                        try:
                            pairs.append((float(lo), float(hi)))
                        except ValueError:
                            raise lines.err(f"bad limits ({lo[:20]} {hi[:20]})", ln) from None
                    bone["limits"] = pairs
                # id, bodymass, cofmass and unknown keys are ignored
                i += 1
            name = bone.get("name")
            if name is None:
                raise lines.err("bone has no name", begin_line)
            if name in bones or name.lower() == "root":
                raise lines.err(f"bone name {name[:40]!r} is used twice", bone["line"])
            for key in ("direction", "length"):
                if bone[key] is None:
                    raise lines.err(f"bone {name!r} has no {key}", begin_line)
            if len(bones) >= _MAX_BONES:
                raise lines.err(f"more than {_MAX_BONES} bones", begin_line)
            bones[name] = bone
            bone_order.append(name)
        elif section == "hierarchy":
            key = head.lower()
            if key in ("begin", "end"):
                i += 1
                continue
            parent = head
            if parent != "root" and parent not in bones:
                raise lines.err(f"hierarchy names unknown bone {parent[:40]!r}", ln)
            for child in toks[1:]:
                if child not in bones:
                    raise lines.err(f"hierarchy names unknown bone {child[:40]!r}", ln)
                if child in child_parent:
                    raise lines.err(f"bone {child!r} has two parents ({child_parent[child]!r} and {parent!r})", ln)
                child_parent[child] = parent
                hier.setdefault(parent, []).append(child)
                hier_lines[child] = ln
            i += 1
        else:  # :version, :name, :documentation and unknown sections
            i += 1
    if not seen_root:
        raise AMCParseError("no :root section", path, items[-1][0])
    if not seen_bones:
        raise AMCParseError("no :bonedata section", path, items[-1][0])
    if not seen_hier:
        raise AMCParseError("no :hierarchy section", path, items[-1][0])

    # depth-first order from the root, children in the order the hierarchy lists them
    names = ["root"]
    parents = [-1]
    stack = [(c, 0) for c in reversed(hier.get("root", []))]
    index = {"root": 0}
    while stack:
        b, p = stack.pop()
        if b in index:  # a cycle through the root cannot happen (root has no parent); guard anyway
            raise AMCParseError(f"bone {b!r} appears twice in the hierarchy", path, hier_lines.get(b))
        index[b] = len(names)
        names.append(b)
        parents.append(p)
        stack.extend((c, index[b]) for c in reversed(hier.get(b, [])))
    missing = [b for b in bone_order if b not in index]
    if missing:
        b = missing[0]
        where = "is not connected to the root" if b in child_parent else "is not in the hierarchy"
        raise AMCParseError(f"bone {b!r} {where}", path, hier_lines.get(b, bones[b]["line"]))

    unit = units["angle"]
    j = len(names)
    directions = np.zeros((j, 3))
    lengths = np.zeros(j)
    frames = np.zeros((j, 4))
    dofs: list[tuple[str, ...]] = []
    limits: list[tuple[tuple[float, float], ...]] = []
    # root
    order, order_line = root["order"] if root["order"] is not None else (list(_TRANS_DOFS + _ROT_DOFS), root["line"])
    bad = [d for d in order if d not in _ROT_DOFS + _TRANS_DOFS]
    if bad or len(set(order)) != len(order):
        raise AMCParseError(f"root order must list distinct TX TY TZ RX RY RZ, found {' '.join(order).upper()}",
                            path, order_line)
    frames[0] = _axis_frame(root["orientation"], root["axis"], unit, "root axis", root.get("axis_line", root["line"]),
                            lines)
    dofs.append(tuple(order))
    limits.append(())
    for k in range(1, j):
        b = bones[names[k]]
        d = np.asarray(b["direction"], dtype=np.float64)
        norm = float(np.linalg.norm(d))
        if norm > 1e-12:
            d = d / norm
        elif b["length"] > 0:
            raise AMCParseError(f"bone {names[k]!r} has a zero direction but length {b['length']:g}", path,
                                b["line"])
        directions[k] = d
        lengths[k] = b["length"]
        if b["axis"] is not None:
            ang, order_s, aln = b["axis"]
            frames[k] = _axis_frame(ang, order_s, unit, f"bone {names[k]!r} axis", aln, lines)
        else:
            frames[k] = (1.0, 0.0, 0.0, 0.0)
        dofs.append(b["dof"])
        lim = tuple(b["limits"])
        if lim and len(lim) != len(b["dof"]):
            raise AMCParseError(f"bone {names[k]!r} has {len(b['dof'])} dofs but {len(lim)} limits", path,
                                b.get("dof_line", b["line"]))
        limits.append(lim)
    return AsfSkeleton(tuple(names), np.array(parents, dtype=np.int64), directions, lengths, frames, tuple(dofs),
                       tuple(limits), np.array(root["position"], dtype=np.float64), float(units["length"]), unit,
                       float(units["mass"]), None if path is None else str(path))


def read_asf(path) -> AsfSkeleton:
    """Read an ASF skeleton file.

    Returns:
        The :class:`AsfSkeleton` as stored; ``.skeleton()`` gives the kinodyn skeleton in Z-up metres.

    Raises:
        AMCParseError: the file is malformed (the message names the file and line).
        FileNotFoundError: the file does not exist.
    """
    p = Path(path)
    return parse_asf(_read_text(p, AMCParseError), p)


# --------------------------------------------------------------------------- finding the ASF

_TRIAL_RE = re.compile(r"^(.*?)(\d+)_(\d+)(.*)$")


def find_asf(amc_path) -> Path:
    """The ASF skeleton file beside an AMC file.

    Tried in turn, each accepted only when exactly one file matches (case-insensitively):
    the same stem (``walk.amc`` -> ``walk.asf``); the CMU subject with the trial's suffix
    (``cmu_07_05-walk.amc`` -> ``cmu_07-walk.asf``); the subject alone (``cmu_01_01.amc`` ->
    ``cmu_01.asf``, ``01_01.amc`` -> ``01.asf``); any ASF named for the subject
    (``cmu_07-run.asf``); finally the only ``.asf`` in the folder.

    Raises:
        AMCParseError: no ASF or several equally good ones (pass ``asf=`` explicitly).
    """
    amc = Path(amc_path)
    folder = amc.parent
    asfs = sorted(q for q in folder.iterdir() if q.suffix.lower() == ".asf" and q.is_file()) \
        if folder.is_dir() else []
    by_stem: dict[str, list[Path]] = {}
    for q in asfs:
        by_stem.setdefault(q.stem.lower(), []).append(q)
    stem = amc.stem.lower()
    tiers: list[list[Path]] = [by_stem.get(stem, [])]
    m = _TRIAL_RE.match(stem)
    if m:
        prefix, subject, _trial, suffix = m.groups()
        base = prefix + subject
        tiers.append(by_stem.get(base + suffix, []) if suffix else [])
        tiers.append(by_stem.get(base, []))
        tiers.append([q for q in asfs if q.stem.lower().startswith(base)
                      and not q.stem[len(base):len(base) + 1].isdigit()])
    tiers.append(asfs if len(asfs) == 1 else [])
    for cands in tiers:
        if len(cands) == 1:
            return cands[0]
        if len(cands) > 1:
            raise AMCParseError(f"several ASF skeletons could belong to this motion "
                                f"({', '.join(q.name for q in cands)}); {PASS_ASF}", amc)
    found = f" (found {', '.join(q.name for q in asfs)})" if asfs else ""
    raise AMCParseError(f"no ASF skeleton found beside the AMC file{found}; {PASS_ASF}", amc)


# --------------------------------------------------------------------------- AMC


def _split_header(text: str, path) -> tuple[int, float | None, str | None, int]:
    """Offset where the frames start, fps and angle unit from the header, and the first frame's line."""
    pos = 0
    line = 1
    fps = None
    unit = None
    n = len(text)
    while pos < n:
        nl = text.find("\n", pos)
        end = n if nl < 0 else nl
        s = text[pos:end].strip()
        if s and not s.startswith(("#", ":")):
            return pos, fps, unit, line
        up = s.upper()
        if up.startswith(":DEGREES"):
            unit = "deg"
        elif up.startswith(":RADIANS"):
            unit = "rad"
        elif up.startswith(":SAMPLES-PER-SECOND"):
            parts = s.split()
            v = float(parts[1]) if len(parts) == 2 and _NUMBER_RE.match(parts[1]) else -1.0
            if not 0 < v <= 1e6:
                raise AMCParseError(f"bad :SAMPLES-PER-SECOND value {s[:60]!r}", path, line)
            fps = v
        pos = end + 1
        line += 1
    raise AMCParseError("no frames (the file has only a header)", path, line)


def _fast_values(body: str, layout: list[tuple[str, int]]) -> tuple[np.ndarray, np.ndarray] | None:
    """Frame numbers ``(F,)`` and values ``(F, V)`` when every frame has exactly ``layout`` (bone names
    and value counts in the file's order); None otherwise, leaving errors to :func:`_slow_values`."""
    raw = np.frombuffer(body.encode("utf-8"), dtype=np.uint8)
    values, counts, name_start, name_len, status, _, _ = _numparse.parse_named(raw, MAX_ABS_VALUE)
    if status != _numparse.OK:
        return None
    keep = (counts > 0) | (name_start >= 0)
    counts, name_start, name_len = counts[keep], name_start[keep], name_len[keep]
    per = len(layout) + 1
    if len(counts) == 0 or len(counts) % per:
        return None
    f = len(counts) // per
    if not (counts.reshape(f, per) == np.array([1] + [c for _, c in layout])).all():
        return None
    name_start, name_len = name_start.reshape(f, per), name_len.reshape(f, per)
    if (name_start[:, 0] >= 0).any():
        return None
    for b, (nm, _) in enumerate(layout):  # every bone line names the bone the layout expects
        want = np.frombuffer(nm.encode("utf-8"), dtype=np.uint8)
        if not (name_len[:, b + 1] == len(want)).all():
            return None
        if not (raw[name_start[:, b + 1, None] + np.arange(len(want))] == want).all():
            return None
    vals = values.reshape(f, 1 + sum(c for _, c in layout))
    frame_no = vals[:, 0]
    if not (frame_no >= 0).all() or not (frame_no == np.round(frame_no)).all() or frame_no.max() > 1e11:
        return None
    frame_no = frame_no.astype(np.int64)
    if f > 1 and not (np.diff(frame_no) == 1).all():
        return None
    return frame_no, vals[:, 1:]


def _slow_values(body: str, first_line: int, layout_names: dict[str, int], path) -> tuple[np.ndarray, np.ndarray,
                                                                                           list[tuple[str, int]]]:
    """Line-by-line reading that groups values by bone name and reports the line of any problem.

    ``layout_names`` maps each animated bone to its number of values. Returns frame numbers ``(F,)``,
    values ``(F, V)`` in the order of ``layout`` (the bones in the ASF's order) and that layout.
    """
    layout = list(layout_names.items())
    start = {}
    col = 0
    for nm, c in layout:
        start[nm] = col
        col += c
    nv = col
    frames: list[np.ndarray] = []
    frame_no: list[int] = []
    cur: np.ndarray | None = None
    seen: set[str] = set()
    cur_line = first_line

    def close():
        if cur is not None:
            missing = [nm for nm, _ in layout if nm not in seen]
            if missing:
                raise AMCParseError(f"frame {frame_no[-1]} has no values for bone {missing[0]!r}", path, cur_line)

    for k, raw in enumerate(body.split("\n")):
        ln = first_line + k
        toks = raw.split()
        if not toks:
            continue
        t0 = toks[0]
        if len(toks) == 1 and _INT_RE.match(t0):
            close()
            num = int(t0) if len(t0) < 12 else -1
            if num < 0:
                raise AMCParseError(f"frame number {t0[:40]!r} is out of range", path, ln)
            if frame_no and num != frame_no[-1] + 1:
                raise AMCParseError(f"frame {num} follows frame {frame_no[-1]}; frames must be consecutive", path,
                                    ln)
            frame_no.append(num)
            cur = np.zeros(nv)
            frames.append(cur)
            seen = set()
            cur_line = ln
            continue
        if cur is None:
            raise AMCParseError(f"expected a frame number, found {raw.strip()[:40]!r}", path, ln)
        if t0 not in layout_names:
            if t0[:1].isdigit() or t0[:1] in "+-.":
                raise AMCParseError(f"expected a bone name or a frame number, found {raw.strip()[:40]!r}", path,
                                    ln)
            raise AMCParseError(f"bone {t0[:40]!r} is not animated by the skeleton (no such bone or no dof)", path,
                                ln)
        if t0 in seen:
            raise AMCParseError(f"bone {t0!r} appears twice in frame {frame_no[-1]}", path, ln)
        c = layout_names[t0]
        if len(toks) - 1 != c:
            raise AMCParseError(f"bone {t0!r} needs {c} values, found {len(toks) - 1}", path, ln)
        s = start[t0]
        for i, tok in enumerate(toks[1:]):
            if _NUMBER_RE.match(tok) is None:
                raise AMCParseError(f"expected a number, found {_kind(tok)} {tok[:40]!r}", path, ln)
            v = float(tok)
            if not abs(v) <= MAX_ABS_VALUE:
                raise AMCParseError(f"value {tok[:40]!r} is out of range (limit {MAX_ABS_VALUE:g})", path, ln)
            cur[s + i] = v
        seen.add(t0)
    close()
    if not frames:
        raise AMCParseError("no frames", path, first_line)
    return np.array(frame_no, dtype=np.int64), np.array(frames), layout


def parse_amc(text: str, asf: AsfSkeleton, path=None) -> tuple[np.ndarray, dict[str, np.ndarray], float | None,
                                                                str | None]:
    """Parse the text of an AMC file against its skeleton.

    Returns:
        Frame numbers ``(F,)``; per animated joint name, its values ``(F, n_dof)`` in ASF dof order;
        the frame rate from a ``:SAMPLES-PER-SECOND`` line (None when absent); the angle unit from a
        ``:DEGREES``/``:RADIANS`` line (None when absent).

    Raises:
        AMCParseError: naming the file and line of the first problem.
    """
    start, fps, unit, first_line = _split_header(text, path)
    body = text[start:]
    animated = {nm: len(d) for nm, d in zip(asf.names, asf.dofs) if len(d)}
    # The first frame's layout (bone order as the file writes it) drives the fast path.
    layout: list[tuple[str, int]] = []
    lines_iter = iter(body.split("\n", 4 * len(animated) + 8))
    next(lines_iter, None)
    for raw in lines_iter:
        toks = raw.split()
        if not toks:
            continue
        if len(toks) == 1 and _INT_RE.match(toks[0]):
            break
        if toks[0] not in animated or len(toks) - 1 != animated[toks[0]]:
            layout = []
            break
        layout.append((toks[0], len(toks) - 1))
    result = None
    if layout and sorted(nm for nm, _ in layout) == sorted(animated):
        result = _fast_values(body, layout)
    if result is None:
        frame_no, values, layout = _slow_values(body, first_line, animated, path)
    else:
        frame_no, values = result
    out: dict[str, np.ndarray] = {}
    col = 0
    for nm, c in layout:
        out[nm] = values[:, col:col + c]
        col += c
    return frame_no, out, fps, unit


def read_amc(path, asf=None, scale: float | str | None = None, up: str = "y", fps: float | None = None) -> Motion:
    """Read a CMU/Acclaim AMC motion as a :class:`~kinodyn.motion.Motion` (Z up, metres).

    Args:
        path: the ``.amc`` file.
        asf: the skeleton: an ``.asf`` path or an :class:`AsfSkeleton`; by default the ASF beside the
            AMC file (see :func:`find_asf`).
        scale: metres per file unit or a unit name; by default from the ASF's ``:units length``
            (CMU: 0.0254 / 0.45 m).
        up: the files' up axis, ``"y"`` (ASF/AMC) or ``"z"``.
        fps: frames per second; by default a ``:SAMPLES-PER-SECOND`` header line, else 120 (CMU).

    Raises:
        AMCParseError: the AMC or ASF file is malformed, or no ASF could be found (the message names
            the file and line).
        FileNotFoundError: a file does not exist.
    """
    p = Path(path)
    if asf is None:
        asf = read_asf(find_asf(p))
    elif not isinstance(asf, AsfSkeleton):
        asf = read_asf(asf)
    text = _read_text(p, AMCParseError)
    return amc_from_text(text, asf, p, scale=scale, up=up, fps=fps, name=p.stem)


def amc_from_text(text: str, asf: AsfSkeleton, path=None, scale: float | str | None = None, up: str = "y",
                  fps: float | None = None, name: str = "") -> Motion:
    """A :class:`~kinodyn.motion.Motion` from the text of an AMC file and its skeleton (what
    :func:`read_amc` does after reading the files; same options).

    Raises:
        AMCParseError: the text is malformed; the message names ``path`` and the line.
    """
    p = path
    turn = _up_turn(up)
    s = _resolve_scale(scale, asf)
    if fps is not None:
        fps = float(fps)
        if not np.isfinite(fps) or fps <= 0:
            raise ParameterError(f"fps must be a positive number, got {fps}")
    frame_no, values, file_fps, amc_unit = parse_amc(text, asf, p)
    f = len(frame_no)
    unit = amc_unit or asf.angle_unit
    to_rad = np.pi / 180.0 if unit == "deg" else 1.0
    local = np.empty((f, asf.num_joints, 4))
    local[:] = (1.0, 0.0, 0.0, 0.0)
    root_pos = np.zeros((f, 3))
    # Group the joints by their padded rotation order, so each group is one vectorized from_euler.
    groups: dict[str, tuple[list[int], list[np.ndarray]]] = {}
    for j, (nm, dofs) in enumerate(zip(asf.names, asf.dofs)):
        if not dofs:
            continue
        v = values[nm]
        if j == 0:
            for k, d in enumerate(dofs):
                if d in _TRANS_DOFS:
                    root_pos[:, "xyz".index(d[1])] = v[:, k]
        rot = [k for k, d in enumerate(dofs) if d in _ROT_DOFS]
        if not rot:
            continue
        order, ang = _order_euler([dofs[k][1] for k in rot], v[:, rot] * to_rad)
        js, angs = groups.setdefault(order, ([], []))
        js.append(j)
        angs.append(ang)
    frames = asf.frames if turn is None else quat.mul(turn, asf.frames)  # C, or turn * C for Y-up files
    for order, (js, angs) in groups.items():
        m = quat.from_euler(np.stack(angs, axis=1), order, extrinsic=True)  # (F, G, 4)
        c = frames[js]
        local[:, js] = quat.mul(quat.mul(c, m), quat.conj(c))
    if turn is not None:
        root_pos = quat.mul_vec(turn, root_pos)
    if not any(d in _TRANS_DOFS for d in asf.dofs[0]):
        root_pos[:] = asf.skeleton(scale=1.0, up=up).offsets[0]
    try:
        sk = asf.skeleton(scale=s, up=up)
        return Motion(sk, root_pos * s, local, fps or file_fps or CMU_FPS, None, name)
    except (SkeletonError, MotionError) as e:
        raise AMCParseError(str(e), p) from e
