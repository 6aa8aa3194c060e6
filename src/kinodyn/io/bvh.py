"""BVH (Biovision Hierarchy) reading and writing.

Reading accepts any rotation-channel order per joint, 3- and 6-channel joints, ``End Site`` blocks,
CRLF or LF line ends, and converts to kinodyn's frame (Z up, metres): a Y-up file is turned by the
proper rotation ``(x, y, z) -> (z, x, y)`` so a character facing +Z in the file faces +X here, with +Y
to its left. Root position channels are absolute positions (the root OFFSET is kept but not added, as
all common tools read them). Lengths are converted by ``scale`` metres per file unit, detected from
the body's size when not given (m, cm, mm, inch, or CMU's 1/0.45-inch unit).

Writing produces a standard BVH (Y up by default, centimetres by default, ``Zrotation Yrotation
Xrotation`` channels, six channels on the root), atomically. Write-then-read reproduces every global
joint position to within 1e-6 m.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinodyn.errors import BVHParseError, ParameterError
from kinodyn.io import _numparse
from kinodyn.io.atomic import atomic_write_bytes
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

__all__ = ["BVHData", "read_bvh", "parse_bvh", "write_bvh", "to_bvh_text", "detect_scale", "UNIT_SCALES",
           "Y_UP_TO_Z_UP"]

#: Metres per unit of the length units kinodyn recognizes.
UNIT_SCALES = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "cmu": 0.0254 / 0.45}
#: Quaternion turning a Y-up frame into kinodyn's Z-up frame: (x, y, z) -> (z, x, y).
Y_UP_TO_Z_UP = np.array([0.5, 0.5, 0.5, 0.5])
_TYPICAL_BODY_SIZE_M = 1.7
MAX_FRAMES = 50_000_000
_MAX_HEADER_BYTES = 16 << 20

_CHANNEL_RE = re.compile(r"^([XYZxyz])(position|rotation)$", re.IGNORECASE)


@dataclass(frozen=True)
class BVHData:
    """A BVH file as stored: hierarchy, channels and raw values in file units and file axes.

    Attributes:
        names: joint names in file order.
        parents: ``(J,)`` parent indices.
        offsets: ``(J, 3)`` OFFSET values in file units.
        channels: per joint, the channel names as written (``"Xposition"``, ``"Zrotation"``, ...).
        end_parents, end_offsets: End Site parents and OFFSETs.
        frame_time: seconds per frame.
        values: ``(F, C)`` channel values (file units, degrees).
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_parents: np.ndarray
    end_offsets: np.ndarray
    frame_time: float
    values: np.ndarray
    path: str | None = field(default=None, compare=False)


# --------------------------------------------------------------------------- reading


def _tokens(header: str):
    """Yield ``(token, line_number)`` over the header text."""
    for ln, line in enumerate(header.split("\n"), start=1):
        for tok in line.split():
            yield tok, ln


class _Header:
    def __init__(self, text: str, path):
        self.toks = list(_tokens(text))
        self.i = 0
        self.path = path
        self.last_line = text.count("\n") + 1

    def err(self, msg: str, line: int | None = None):
        if line is None:
            line = self.toks[self.i][1] if self.i < len(self.toks) else self.last_line
        return BVHParseError(msg, self.path, line)

    def next(self, what: str) -> tuple[str, int]:
        if self.i >= len(self.toks):
            raise self.err(f"unexpected end of file, expected {what}")
        t = self.toks[self.i]
        self.i += 1
        return t

    def expect(self, word: str) -> int:
        tok, ln = self.next(repr(word))
        if tok.upper() != word.upper():
            raise self.err(f"expected {word!r}, found {tok!r}", ln)
        return ln

    def number(self, what: str) -> float:
        tok, ln = self.next(what)
        try:
            v = float(tok)
        except ValueError:
            raise self.err(f"expected a number for {what}, found {tok!r}", ln) from None
        if not np.isfinite(v):
            raise self.err(f"{what} must be finite, found {tok!r}", ln)
        return v

    def peek(self) -> str | None:
        return self.toks[self.i][0] if self.i < len(self.toks) else None


def _parse_hierarchy(h: _Header):
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    end_parents: list[int] = []
    end_offsets: list[list[float]] = []

    def offset(what: str) -> list[float]:
        h.expect("OFFSET")
        return [h.number(f"{what} OFFSET x"), h.number(f"{what} OFFSET y"), h.number(f"{what} OFFSET z")]

    def joint(parent: int):
        name, ln = h.next("a joint name")
        if name == "{":
            raise h.err("joint has no name", ln)
        if name in names:
            raise h.err(f"joint name {name!r} is used twice", ln)
        h.expect("{")
        idx = len(names)
        names.append(name)
        parents.append(parent)
        offsets.append(offset(f"joint {name!r}"))
        tok, ln = h.next("CHANNELS")
        if tok.upper() != "CHANNELS":
            raise h.err(f"expected 'CHANNELS' for joint {name!r}, found {tok!r}", ln)
        cnt_tok, ln = h.next("a channel count")
        if not cnt_tok.isdigit():
            raise h.err(f"channel count of joint {name!r} must be an integer, found {cnt_tok!r}", ln)
        cnt = int(cnt_tok)
        if cnt not in (0, 1, 2, 3, 6) or (cnt > 6):
            raise h.err(f"joint {name!r} declares {cnt} channels; expected 3 or 6", ln)
        chans = []
        for _ in range(cnt):
            c, cl = h.next("a channel name")
            if not _CHANNEL_RE.match(c):
                raise h.err(f"unknown channel {c!r} on joint {name!r} (expected e.g. Xposition, Zrotation)", cl)
            chans.append(c[0].upper() + c[1:].lower())
        rot = [c for c in chans if c.endswith("rotation")]
        pos = [c for c in chans if c.endswith("position")]
        if len(set(chans)) != len(chans) or len(rot) not in (0, 3) or len(pos) not in (0, 3):
            raise h.err(f"joint {name!r} must have three distinct rotation channels (and optionally three "
                        f"position channels), found {' '.join(chans)}", ln)
        channels.append(tuple(chans))
        while True:
            tok, ln = h.next("'JOINT', 'End Site' or '}'")
            up = tok.upper()
            if up == "}":
                return
            if up == "JOINT":
                joint(idx)
            elif up == "END":
                h.expect("Site")
                h.expect("{")
                end_parents.append(idx)
                end_offsets.append(offset(f"end site of {name!r}"))
                h.expect("}")
            else:
                raise h.err(f"expected 'JOINT', 'End Site' or '}}' inside joint {name!r}, found {tok!r}", ln)

    h.expect("HIERARCHY")
    tok, ln = h.next("ROOT")
    if tok.upper() != "ROOT":
        raise h.err(f"expected 'ROOT', found {tok!r}", ln)
    joint(-1)
    if h.peek() is not None and h.peek().upper() == "ROOT":
        raise h.err("files with more than one ROOT are not supported")
    if not channels[0]:
        raise h.err(f"the root joint {names[0]!r} has no channels")
    return names, parents, offsets, channels, end_parents, end_offsets


def parse_bvh(data: bytes, path=None) -> BVHData:
    """Parse the bytes of a BVH file into :class:`BVHData` (file units and axes, no conversion).

    Raises:
        BVHParseError: naming the file and line of the first problem found.
    """
    m = re.search(rb"(?m)^[ \t]*MOTION[ \t]*\r?$", data[:_MAX_HEADER_BYTES])
    if m is None:
        if not data.strip():
            raise BVHParseError("file is empty", path, 1)
        if b"HIERARCHY" not in data[:4096]:
            raise BVHParseError("not a BVH file: no HIERARCHY section", path, 1)
        raise BVHParseError("no MOTION section", path, data.count(b"\n") + 1)
    try:
        header = data[: m.start()].decode("utf-8")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise BVHParseError("header is not valid text", path, line) from None
    h = _Header(header.replace("\r", ""), path)
    names, parents, offsets, channels, end_parents, end_offsets = _parse_hierarchy(h)
    if h.peek() is not None:
        raise h.err(f"unexpected {h.peek()!r} after the hierarchy")
    motion_line = data[: m.start()].count(b"\n") + 1

    # "Frames: N" and "Frame Time: t" lines
    pos = m.end()
    lines_seen = motion_line
    meta = {}
    for key in ("Frames:", "Frame Time:"):
        while True:
            nl = data.find(b"\n", pos)
            raw = data[pos: len(data) if nl < 0 else nl]
            pos = len(data) if nl < 0 else nl + 1
            lines_seen += 1
            if raw.strip() or nl < 0:
                break
        text = raw.decode("utf-8", "replace").strip()
        if not text.lower().startswith(key.lower()):
            raise BVHParseError(f"expected {key!r} line, found {text[:40]!r}", path, lines_seen)
        meta[key] = (text[len(key):].strip(), lines_seen)
    n_txt, n_line = meta["Frames:"]
    if not n_txt.isdigit():
        raise BVHParseError(f"frame count must be a non-negative integer, found {n_txt!r}", path, n_line)
    n_frames = int(n_txt)
    if n_frames > MAX_FRAMES:
        raise BVHParseError(f"frame count {n_frames} is absurd (limit {MAX_FRAMES})", path, n_line)
    ft_txt, ft_line = meta["Frame Time:"]
    try:
        frame_time = float(ft_txt)
    except ValueError:
        raise BVHParseError(f"frame time must be a number, found {ft_txt!r}", path, ft_line) from None
    if not np.isfinite(frame_time) or frame_time <= 0 or frame_time > 10:
        raise BVHParseError(f"frame time must be a positive number of seconds, found {ft_txt!r}", path, ft_line)

    n_chan = sum(len(c) for c in channels)
    first_data_line = lines_seen + 1
    body = np.frombuffer(data, dtype=np.uint8, offset=pos) if pos < len(data) else np.zeros(0, np.uint8)
    values, status, rows, bad_line, bad_pos, bad_count = _numparse.parse(body, n_chan, n_frames)
    line_no = first_data_line + bad_line
    if status == _numparse.BAD_TOKEN:
        end = bad_pos
        while end < len(body) and body[end] not in (32, 9, 13, 10):
            end += 1
        tok = bytes(body[bad_pos:end]).decode("utf-8", "replace")[:30]
        what = "a non-finite value" if tok.lower().lstrip("+-") in ("nan", "inf", "infinity") else "text"
        raise BVHParseError(f"expected a number, found {what} {tok!r}", path, line_no)
    if status == _numparse.BAD_COUNT:
        raise BVHParseError(f"frame line has {bad_count} values; the hierarchy declares {n_chan} channels",
                            path, line_no)
    if status == _numparse.TOO_MANY_LINES:
        raise BVHParseError(f"more frame lines than the {n_frames} declared in 'Frames:'", path, line_no)
    if rows < n_frames:
        raise BVHParseError(f"file is truncated: 'Frames: {n_frames}' but {rows} frame lines found", path,
                            first_data_line + bad_line)
    if n_frames == 0:
        raise BVHParseError("file has no frames ('Frames: 0')", path, n_line)
    return BVHData(tuple(names), np.array(parents), np.array(offsets, dtype=np.float64).reshape(-1, 3),
                   tuple(channels), np.array(end_parents, dtype=np.int64),
                   np.array(end_offsets, dtype=np.float64).reshape(-1, 3), frame_time, values,
                   None if path is None else str(path))


_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}
_Y_UP_AXIS = {0: 1, 1: 2, 2: 0}  # a Y-up file's x, y, z axes are kinodyn's y, z, x


def _decode_channels(d: BVHData, up: str):
    """Local rotations ``(F, J, 4)`` (in kinodyn's axes when ``up == "y"``), position channels
    ``(F, J, 3)`` in file axes and units (offsets where a joint has none), and the mask of joints with
    position channels.

    For a Y-up file the rotation axes are renamed to kinodyn's axes, which equals conjugating every
    rotation by :data:`Y_UP_TO_Z_UP` at no cost.
    """
    f, j = d.values.shape[0], len(d.names)
    cols = np.full((j, 3), -1, dtype=np.int64)
    axes = np.zeros((j, 3), dtype=np.int64)
    pos_cols = {}
    col = 0
    for k, chans in enumerate(d.channels):
        rot = [(_AXIS_INDEX[c[0].lower()], col + i) for i, c in enumerate(chans) if c.endswith("rotation")]
        if rot:
            axes[k] = [(_Y_UP_AXIS[a] if up == "y" else a) for a, _ in rot]
            cols[k] = [c for _, c in rot]
        pc = {c[0].lower(): col + i for i, c in enumerate(chans) if c.endswith("position")}
        if pc:
            pos_cols[k] = [pc["x"], pc["y"], pc["z"]]
        col += len(chans)
    q = np.empty((f, j, 4))
    _numparse.euler_columns_to_quat(np.ascontiguousarray(d.values), cols, axes, q)
    has_pos = np.zeros(j, dtype=bool)
    has_pos[list(pos_cols)] = True
    if has_pos[1:].any():
        pos = np.broadcast_to(d.offsets, (f, j, 3)).copy()
        for k, c in pos_cols.items():
            pos[:, k] = d.values[:, c]
    else:
        pos = np.broadcast_to(d.offsets, (f, j, 3))[:, :1].copy()
        if has_pos[0]:
            pos[:, 0] = d.values[:, pos_cols[0]]
    return q, pos, has_pos


def detect_scale(size_in_file_units: float) -> tuple[str, float]:
    """The unit (name, metres per unit) that makes a body of this size closest to 1.7 m."""
    if not np.isfinite(size_in_file_units) or size_in_file_units <= 0:
        return "m", 1.0
    best = min(UNIT_SCALES.items(), key=lambda kv: abs(np.log(size_in_file_units * kv[1] / _TYPICAL_BODY_SIZE_M)))
    return best


def _body_size(offsets, parents, rot_q, pos, has_pos, end_parents, end_offsets) -> float:
    from kinodyn.kinematics import fk_arrays

    n = rot_q.shape[0]
    idx = np.unique(np.linspace(0, n - 1, min(n, 16)).astype(int))
    trans = None
    if pos.shape[1] > 1:
        trans = np.where(has_pos[None, :, None], pos[idx], offsets[None])
    gr, gp = fk_arrays(pos[idx, 0], rot_q[idx], offsets, parents, trans)
    if len(end_parents):
        gp = np.concatenate([gp, gp[:, end_parents] + quat.mul_vec(gr[:, end_parents], end_offsets)], axis=1)
    return float(np.median(np.ptp(gp, axis=1).max(axis=1)))


def to_motion(d: BVHData, scale: float | str | None = None, up: str = "y", name: str = "") -> Motion:
    """Convert raw :class:`BVHData` to a :class:`Motion` in Z-up metres.

    Args:
        scale: metres per file unit, a unit name from :data:`UNIT_SCALES`, or None to detect it.
        up: the file's up axis, ``"y"`` (usual) or ``"z"``.
    """
    up = up.lower()
    if up not in ("y", "z"):
        raise ParameterError(f"up must be 'y' or 'z', got {up!r}")
    q, pos, has_pos = _decode_channels(d, up)
    offsets, end_offsets = d.offsets, d.end_offsets
    if up == "y":
        c = Y_UP_TO_Z_UP
        offsets = quat.mul_vec(c, offsets)
        end_offsets = quat.mul_vec(c, end_offsets) if len(end_offsets) else end_offsets
        pos = quat.mul_vec(c, pos)
    if scale is None:
        size = _body_size(offsets, d.parents, q, pos, has_pos, d.end_parents, end_offsets)
        scale = detect_scale(size)[1]
    elif isinstance(scale, str):
        if scale not in UNIT_SCALES:
            raise ParameterError(f"unknown unit {scale!r}; known units: {', '.join(UNIT_SCALES)}")
        scale = UNIT_SCALES[scale]
    scale = float(scale)
    if not np.isfinite(scale) or scale <= 0:
        raise ParameterError(f"scale must be a positive number of metres per file unit, got {scale}")
    offsets, end_offsets, pos = offsets * scale, end_offsets * scale, pos * scale
    sk = Skeleton(d.names, d.parents, offsets, d.end_parents, end_offsets)
    animated = has_pos.copy()
    animated[0] = False
    translations = None
    if animated.any():  # pos is (F, J, 3) here
        # Non-root position channels that merely repeat the offset carry no information.
        dev = np.abs(pos[:, animated] - offsets[animated]).max()
        if dev > 1e-9 * max(1.0, np.abs(offsets).max()):
            translations = pos
    root = pos[:, 0] if has_pos[0] else np.broadcast_to(offsets[0], (len(q), 3))
    return Motion(sk, root, q, 1.0 / d.frame_time, translations, name)


def read_bvh(path, scale: float | str | None = None, up: str = "y") -> Motion:
    """Read a BVH file as a :class:`Motion` (Z up, metres).

    Args:
        path: the file.
        scale: metres per file unit (or a unit name: m, cm, mm, inch, cmu); detected when None.
        up: the file's up axis (``"y"`` for nearly every BVH in the wild).

    Raises:
        BVHParseError: the file is malformed (the message names file and line).
        FileNotFoundError: the file does not exist.
    """
    p = Path(path)
    data = p.read_bytes()
    return to_motion(parse_bvh(data, p), scale=scale, up=up, name=p.stem)


# --------------------------------------------------------------------------- writing


def to_bvh_text(motion: Motion, scale: float | str = "cm", up: str = "y", order: str = "zyx",
                precision: int = 6) -> str:
    """BVH text of a motion.

    Args:
        scale: metres per written unit or a unit name (default centimetres).
        up: the written file's up axis, ``"y"`` or ``"z"``.
        order: intrinsic rotation order of every joint's channels (``"zyx"`` writes Zrotation Yrotation
            Xrotation).
        precision: decimals written for every value.
    """
    if isinstance(scale, str):
        if scale not in UNIT_SCALES:
            raise ParameterError(f"unknown unit {scale!r}; known units: {', '.join(UNIT_SCALES)}")
        scale = UNIT_SCALES[scale]
    if not np.isfinite(scale) or scale <= 0:
        raise ParameterError(f"scale must be positive, got {scale}")
    order = order.lower()
    if order not in quat.EULER_ORDERS:
        raise ParameterError(f"order must be one of {', '.join(quat.EULER_ORDERS)}, got {order!r}")
    up = up.lower()
    if up not in ("y", "z"):
        raise ParameterError(f"up must be 'y' or 'z', got {up!r}")
    sk = motion.skeleton
    inv = 1.0 / scale
    offsets = sk.offsets * inv
    end_offsets = sk.end_offsets * inv
    root = motion.root_pos * inv
    q = motion.local_rot
    trans = None if motion.translations is None else motion.translations * inv
    if up == "y":
        c = quat.conj(Y_UP_TO_Z_UP)
        offsets = quat.mul_vec(c, offsets)
        end_offsets = quat.mul_vec(c, end_offsets) if len(end_offsets) else end_offsets
        root = quat.mul_vec(c, root)
        q = quat.mul(quat.mul(c, q), quat.conj(c))
        if trans is not None:
            trans = quat.mul_vec(c, trans)
    euler = np.rad2deg(quat.to_euler(q, order))  # (F, J, 3)
    rot_names = " ".join(f"{a.upper()}rotation" for a in order)
    six = trans is not None
    lines = ["HIERARCHY"]
    children = [[] for _ in sk.names]
    for j in range(1, sk.num_joints):
        children[sk.parents[j]].append(j)
    ends = [[] for _ in sk.names]
    for e, p in enumerate(sk.end_parents):
        ends[p].append(e)
    fmt = f"{{:.{precision}f}}"
    dfs, stack = [], [0]
    while stack:
        j = stack.pop()
        dfs.append(j)
        stack.extend(reversed(children[j]))
    if dfs != list(range(sk.num_joints)):
        raise ParameterError("skeleton joints are not in depth-first order; BVH needs parents listed before "
                             "their children and each subtree contiguous")

    def off(v) -> str:
        return " ".join(fmt.format(x) for x in v)

    def emit(j: int, depth: int):
        ind = "\t" * depth
        kw = "ROOT" if j == 0 else "JOINT"
        lines.append(f"{ind}{kw} {sk.names[j]}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}\tOFFSET {off(offsets[j])}")
        if j == 0 or six:
            lines.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition {rot_names}")
        else:
            lines.append(f"{ind}\tCHANNELS 3 {rot_names}")
        for k in children[j]:
            emit(k, depth + 1)
        for e in ends[j]:
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET {off(end_offsets[e])}")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    emit(0, 0)
    lines.append("MOTION")
    lines.append(f"Frames: {motion.num_frames}")
    lines.append(f"Frame Time: {1.0 / motion.fps:.7f}")
    f = motion.num_frames
    cols = []
    for j in range(sk.num_joints):
        if j == 0:
            cols.append(root)
        elif six:
            cols.append(trans[:, j])
        cols.append(euler[:, j])
    table = np.concatenate(cols, axis=1) if f else np.zeros((0, 1))
    table = np.where(np.abs(table) < 0.5 * 10.0 ** -precision, 0.0, table)  # no "-0.000000"
    row = " ".join([f"%.{precision}f"] * table.shape[1])
    body = "\n".join(row % tuple(r) for r in table.tolist())
    return "\n".join(lines) + "\n" + body + "\n"


def write_bvh(path, motion: Motion, scale: float | str = "cm", up: str = "y", order: str = "zyx",
              precision: int = 6) -> None:
    """Write ``motion`` as a BVH file, atomically (see :func:`to_bvh_text` for the options)."""
    text = to_bvh_text(motion, scale=scale, up=up, order=order, precision=precision)
    atomic_write_bytes(path, text.encode("utf-8"))
