"""Acclaim ASF skeletons: the bones, their axes, dofs and limits, and the hierarchy (CMU's format).

The format and the conventions used are described in :mod:`kinodyn.io.amc`; the AMC motions that play
on an ASF skeleton are read there. :func:`read_asf` gives the :class:`AsfSkeleton` as stored (file
units, Y up); ``.skeleton()`` the kinodyn skeleton in Z-up metres.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinodyn.errors import AMCParseError
from kinodyn.io._acclaim import (
    LIMIT_RE,
    MAX_ABS_VALUE,
    MAX_BONES,
    NUMBER_RE,
    ROT_DOFS,
    TRANS_DOFS,
    metres_per_unit,
    read_text,
    token_kind,
    up_turn,
)
from kinodyn.math import quat
from kinodyn.skeleton import Skeleton

__all__ = ["PASS_ASF", "AsfSkeleton", "find_asf", "parse_asf", "read_asf"]

#: how an error about a missing ASF says to name it (the CLI says its --asf option instead)
PASS_ASF = "pass asf= explicitly"


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
        s = metres_per_unit(scale, self.metres_per_unit)
        turn = up_turn(up)
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


# --------------------------------------------------------------------------- parsing


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
        if NUMBER_RE.match(tok) is None:
            raise self.err(f"expected a number for {what}, found {token_kind(tok)} {tok[:40]!r}", ln)
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
    r = _AsfReader(lines)
    r.read()
    for section in ("root", "bonedata", "hierarchy"):
        if section not in r.seen:
            raise AMCParseError(f"no :{section} section", path, items[-1][0])
    names, parents = _depth_first(r, path)
    return _asf_skeleton(r, names, parents, path)


class _AsfReader:
    """The sections of one ASF file, read line by line (units, root, bones, hierarchy)."""

    def __init__(self, lines: _AsfLines):
        self.lines = lines
        self.units = {"length": 1.0, "mass": 1.0, "angle": "deg"}
        self.root = {"order": None, "axis": "XYZ", "position": [0.0, 0.0, 0.0], "orientation": [0.0, 0.0, 0.0],
                     "line": 1}
        self.bones: dict[str, dict] = {}
        self.bone_order: list[str] = []
        self.hier: dict[str, list[str]] = {}
        self.child_parent: dict[str, str] = {}
        self.hier_lines: dict[str, int] = {}
        self.seen: set[str] = set()

    def read(self) -> None:
        items = self.lines.items
        section = None
        i = 0
        while i < len(items):
            ln, toks = items[i]
            if toks[0].startswith(":"):
                section = toks[0][1:].lower()
                self.seen.add(section)
                if section == "root":
                    self.root["line"] = ln
                i += 1
            elif section == "bonedata":
                i = self.bone(i)
            else:
                if section == "units":
                    self.unit_line(ln, toks)
                elif section == "root":
                    self.root_line(ln, toks)
                elif section == "hierarchy":
                    self.hierarchy_line(ln, toks)
                i += 1  # :version, :name, :documentation and unknown sections are skipped

    def unit_line(self, ln: int, toks: list[str]) -> None:
        if len(toks) < 2:
            return
        key = toks[0].lower()
        if key == "angle":
            unit = toks[1].lower()
            if unit in ("deg", "degree", "degrees"):
                self.units["angle"] = "deg"
            elif unit in ("rad", "radian", "radians"):
                self.units["angle"] = "rad"
            else:
                raise self.lines.err(f"angle unit must be 'deg' or 'rad', found {toks[1][:40]!r}", ln)
        elif key in ("length", "mass"):
            v = self.lines.number(toks[1], f"units {key}", ln)
            if not 1e-6 <= v <= 1e6:
                raise self.lines.err(f"units {key} must be between 1e-6 and 1e6, found {toks[1][:40]!r}", ln)
            self.units[key] = v

    def root_line(self, ln: int, toks: list[str]) -> None:
        key = toks[0].lower()
        if key == "order":
            self.root["order"] = ([t.lower() for t in toks[1:]], ln)
        elif key == "axis":
            if len(toks) != 2:
                raise self.lines.err("root axis must be one order string such as XYZ", ln)
            self.root["axis"] = toks[1]
            self.root["axis_line"] = ln
        elif key in ("position", "orientation"):
            if len(toks) != 4:
                raise self.lines.err(f"root {key} needs 3 numbers, found {len(toks) - 1}", ln)
            self.root[key] = [self.lines.number(t, f"root {key}", ln) for t in toks[1:]]

    def bone(self, i: int) -> int:
        """Read the bone ``begin ... end`` starting at line item ``i``; returns the item after its end."""
        lines, items = self.lines, self.lines.items
        ln, toks = items[i]
        if toks[0].lower() != "begin":
            raise lines.err(f"expected 'begin' of a bone in :bonedata, found {toks[0][:40]!r}", ln)
        begin_line = ln
        bone = {"line": ln, "dof": (), "limits": [], "axis": None, "direction": None, "length": None}
        i += 1
        while True:
            if i >= len(items):
                raise lines.err(f"bone starting at line {begin_line} has no 'end'", items[-1][0])
            ln, toks = items[i]
            key = toks[0].lower()
            if key == "end":
                break
            if key.startswith(":") or key == "begin":
                raise lines.err(f"bone starting at line {begin_line} has no 'end'", ln)
            i = self.bone_key(bone, key, toks, ln, i) + 1
        self.add_bone(bone, begin_line)
        return i + 1

    def bone_key(self, bone: dict, key: str, toks: list[str], ln: int, i: int) -> int:
        """Store one ``key value...`` line of a bone; returns the last line item it used."""
        lines = self.lines
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
            bone["dof"] = self.dofs(toks, ln)
            bone["dof_line"] = ln
        elif key == "limits":
            i = self.limits(bone, toks, ln, i)
        # id, bodymass, cofmass and unknown keys are ignored
        return i

    def dofs(self, toks: list[str], ln: int) -> tuple[str, ...]:
        dofs = tuple(t.lower() for t in toks[1:])
        bad = [d for d in dofs if d not in ROT_DOFS + TRANS_DOFS + ("l",)]
        if bad:
            raise self.lines.err(f"unknown dof {bad[0][:40]!r} (expected rx, ry, rz)", ln)
        if len(set(dofs)) != len(dofs):
            raise self.lines.err(f"repeated dof in {' '.join(dofs)}", ln)
        if any(d not in ROT_DOFS for d in dofs):
            raise self.lines.err("translation and length dofs (tx, ty, tz, l) on bones are not supported", ln)
        return dofs

    def limits(self, bone: dict, toks: list[str], ln: int, i: int) -> int:
        """``limits (lo hi)`` pairs, one per dof, possibly continued on the following lines."""
        items = self.lines.items
        chunk = " ".join(toks[1:])
        while i + 1 < len(items) and items[i + 1][1][0].startswith("("):
            i += 1
            chunk += " " + " ".join(items[i][1])
        pairs = []
        for lo, hi in LIMIT_RE.findall(chunk):
            try:
                pairs.append((float(lo), float(hi)))
            except ValueError:
                raise self.lines.err(f"bad limits ({lo[:20]} {hi[:20]})", ln) from None
        bone["limits"] = pairs
        return i

    def add_bone(self, bone: dict, begin_line: int) -> None:
        lines = self.lines
        name = bone.get("name")
        if name is None:
            raise lines.err("bone has no name", begin_line)
        if name in self.bones or name.lower() == "root":
            raise lines.err(f"bone name {name[:40]!r} is used twice", bone["line"])
        for key in ("direction", "length"):
            if bone[key] is None:
                raise lines.err(f"bone {name!r} has no {key}", begin_line)
        if len(self.bones) >= MAX_BONES:
            raise lines.err(f"more than {MAX_BONES} bones", begin_line)
        self.bones[name] = bone
        self.bone_order.append(name)

    def hierarchy_line(self, ln: int, toks: list[str]) -> None:
        lines = self.lines
        parent = toks[0]
        if parent.lower() in ("begin", "end"):
            return
        if parent != "root" and parent not in self.bones:
            raise lines.err(f"hierarchy names unknown bone {parent[:40]!r}", ln)
        for child in toks[1:]:
            if child not in self.bones:
                raise lines.err(f"hierarchy names unknown bone {child[:40]!r}", ln)
            if child in self.child_parent:
                raise lines.err(f"bone {child!r} has two parents ({self.child_parent[child]!r} and {parent!r})",
                                ln)
            self.child_parent[child] = parent
            self.hier.setdefault(parent, []).append(child)
            self.hier_lines[child] = ln


def _depth_first(r: _AsfReader, path) -> tuple[list[str], list[int]]:
    """Joint names and parents in depth-first order from the root, children in the hierarchy's order."""
    names = ["root"]
    parents = [-1]
    stack = [(c, 0) for c in reversed(r.hier.get("root", []))]
    index = {"root": 0}
    while stack:
        b, p = stack.pop()
        if b in index:  # a cycle through the root cannot happen (root has no parent); guard anyway
            raise AMCParseError(f"bone {b!r} appears twice in the hierarchy", path, r.hier_lines.get(b))
        index[b] = len(names)
        names.append(b)
        parents.append(p)
        stack.extend((c, index[b]) for c in reversed(r.hier.get(b, [])))
    missing = [b for b in r.bone_order if b not in index]
    if missing:
        b = missing[0]
        where = "is not connected to the root" if b in r.child_parent else "is not in the hierarchy"
        raise AMCParseError(f"bone {b!r} {where}", path, r.hier_lines.get(b, r.bones[b]["line"]))
    return names, parents


def _asf_skeleton(r: _AsfReader, names: list[str], parents: list[int], path) -> AsfSkeleton:
    """The :class:`AsfSkeleton` arrays of the bones read, in the order of ``names``."""
    root, units, lines = r.root, r.units, r.lines
    unit = units["angle"]
    j = len(names)
    directions = np.zeros((j, 3))
    lengths = np.zeros(j)
    frames = np.zeros((j, 4))
    dofs: list[tuple[str, ...]] = []
    limits: list[tuple[tuple[float, float], ...]] = []
    order, order_line = root["order"] if root["order"] is not None else (list(TRANS_DOFS + ROT_DOFS), root["line"])
    bad = [d for d in order if d not in ROT_DOFS + TRANS_DOFS]
    if bad or len(set(order)) != len(order):
        raise AMCParseError(f"root order must list distinct TX TY TZ RX RY RZ, found {' '.join(order).upper()}",
                            path, order_line)
    frames[0] = _axis_frame(root["orientation"], root["axis"], unit, "root axis", root.get("axis_line", root["line"]),
                            lines)
    dofs.append(tuple(order))
    limits.append(())
    for k in range(1, j):
        b = r.bones[names[k]]
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
    return parse_asf(read_text(p, AMCParseError), p)


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
