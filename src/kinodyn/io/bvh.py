"""BVH (Biovision Hierarchy) reading and writing.

Reading accepts any rotation-channel order per joint, 3- and 6-channel joints (0-channel joints too),
``End Site`` blocks, CRLF, LF or CR line ends, a UTF-8 byte-order mark, blank lines and trailing
whitespace, and converts to kinodyn's frame (Z up, metres): a Y-up file is turned by the proper
rotation ``(x, y, z) -> (z, x, y)`` so a character facing +Z in the file faces +X here, with +Y to its
left. Root position channels are absolute positions (the root OFFSET is kept but not added, as all
common tools read them). Lengths are converted by ``scale`` metres per file unit, detected from the
body's size when not given (m, cm, mm, inch, or CMU's 1/0.45-inch unit). A ``Frame Time`` that is a
whole frame rate's period rounded to the digits written (``.0083333``) is read as exactly that rate.

Malformed input raises :class:`~kinodyn.errors.BVHParseError` naming the file and line: truncated
files, ragged or extra frame lines, text, ``nan``/``inf`` or numbers beyond :data:`MAX_ABS_VALUE`
where numbers belong, unknown channels, absurd ``Frames:`` or ``CHANNELS`` claims, more than
:data:`MAX_JOINTS` joints, headers without ``MOTION`` in their first 16 MiB, binary data. Memory is
bounded by the file's size, never by what its header claims, and nothing recurses on the nesting
depth. The numbers are parsed by a compiled single-pass parser (:mod:`kinodyn.io._numparse`).

Writing produces a standard BVH (Y up by default, centimetres by default, ``Zrotation Yrotation
Xrotation`` channels, six channels on the root), atomically. Write-then-read reproduces every global
joint position to within 1e-6 m.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinodyn._arrays import median
from kinodyn.errors import BVHParseError, MotionError, ParameterError, SkeletonError
from kinodyn.io import _numparse
from kinodyn.io._bvhheader import MAX_ABS_VALUE, MAX_JOINTS, UINT_RE, Header, parse_hierarchy, parse_number
from kinodyn.io.atomic import atomic_write_bytes
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

__all__ = [
    "MAX_ABS_VALUE",
    "MAX_FRAMES",
    "MAX_JOINTS",
    "SCALE_RANGE",
    "UNIT_SCALES",
    "Y_UP_TO_Z_UP",
    "BVHData",
    "bvh_from_bytes",
    "detect_scale",
    "parse_bvh",
    "read_bvh",
    "resolve_scale",
    "to_bvh_text",
    "to_motion",
    "write_bvh",
]

#: Metres per unit of the length units kinodyn recognizes.
UNIT_SCALES = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "cmu": 0.0254 / 0.45}
#: Quaternion turning a Y-up frame into kinodyn's Z-up frame: (x, y, z) -> (z, x, y).
Y_UP_TO_Z_UP = np.array([0.5, 0.5, 0.5, 0.5])
#: Accepted range of ``scale`` (metres per file unit).
SCALE_RANGE = (1e-9, 1e3)
_TYPICAL_BODY_SIZE_M = 1.7
#: Largest frame count accepted in ``Frames:`` (a larger claim is reported as absurd).
MAX_FRAMES = 50_000_000
_MAX_HEADER_BYTES = 16 << 20
_SNIFF_BYTES = 64 << 10
_MAX_INDENT = 32

_MOTION_RE = re.compile(rb"(?m)^[ \t]*MOTION[ \t]*\r?$")


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


def _token_at(body: np.ndarray, pos: int) -> str:
    end = min(pos + 40, len(body))
    chunk = bytes(body[pos:end])
    for k, b in enumerate(chunk):
        if b in (32, 9, 13, 10):
            chunk = chunk[:k]
            break
    return chunk.decode("utf-8", "replace")


def _normalize_text(data: bytes) -> bytes:
    """Drop a UTF-8 byte-order mark; turn old Mac CR-only line ends into LF."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    if b"\n" not in data[:_SNIFF_BYTES] and b"\r" in data[:_SNIFF_BYTES]:
        data = data.replace(b"\r", b"\n")
    return data


def _check_start(data: bytes, path) -> None:
    head = data[:_SNIFF_BYTES].lstrip()
    if not head:
        raise BVHParseError("file is empty", path, 1)
    if not head[:9].upper().startswith(b"HIERARCHY"):
        line = data[: len(data[:_SNIFF_BYTES]) - len(head)].count(b"\n") + 1
        raise BVHParseError("not a BVH file: it does not start with 'HIERARCHY'", path, line)


def _snap_frame_time(frame_time: float, token: str) -> float:
    """``1 / n`` for the whole frame rate ``n`` whose period, rounded or truncated to the decimals
    written, is the token (``.0083333`` -> 1/120 s, ``0.016666`` -> 1/60 s); otherwise the value as
    written."""
    mant = token.lower().split("e")[0]
    if "e" in token.lower() or "." not in mant:
        return frame_time
    decimals = len(mant.split(".")[1])
    rate = round(1.0 / frame_time)
    err = abs(1.0 / rate - frame_time) if rate >= 1 else np.inf
    if err < 10.0 ** -decimals and err < 1e-4 * frame_time:
        return 1.0 / rate
    return frame_time


def _motion_header(data: bytes, pos: int, motion_line: int, path) -> tuple[int, float, int, int]:
    """The ``Frames: N`` and ``Frame Time: t`` lines after ``MOTION`` (ending at byte ``pos``): frame count,
    frame time, the byte where the frame lines start and the line number of the frame-time line."""
    if data[pos:pos + 1] == b"\n":  # the MOTION line's own end
        pos += 1
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
        text = raw[:200].decode("utf-8", "replace").strip()
        if not text.lower().startswith(key.lower()):
            raise BVHParseError(f"expected {key!r} line, found {text[:40]!r}", path, lines_seen)
        meta[key] = (text[len(key):].strip(), lines_seen)
    n_txt, n_line = meta["Frames:"]
    if not UINT_RE.match(n_txt):
        raise BVHParseError(f"frame count must be a non-negative integer, found {n_txt[:40]!r}", path, n_line)
    n_frames = int(n_txt) if len(n_txt) < 12 else MAX_FRAMES + 1
    if n_frames > MAX_FRAMES:
        raise BVHParseError(f"frame count {n_txt[:40]} is absurd (limit {MAX_FRAMES})", path, n_line)
    ft_txt, ft_line = meta["Frame Time:"]
    frame_time = parse_number(ft_txt)
    if frame_time is None:
        raise BVHParseError(f"frame time must be a number, found {ft_txt[:40]!r}", path, ft_line)
    if not 0 < frame_time <= 10:
        raise BVHParseError(f"frame time must be a positive number of seconds (at most 10), found {ft_txt!r}",
                            path, ft_line)
    frame_time = _snap_frame_time(frame_time, ft_txt)
    if n_frames == 0:
        raise BVHParseError("file has no frames ('Frames: 0')", path, n_line)
    return n_frames, frame_time, pos, lines_seen


def _frame_values(data: bytes, pos: int, n_chan: int, n_frames: int, first_data_line: int, path) -> np.ndarray:
    """``(n_frames, n_chan)`` values of the frame lines starting at byte ``pos`` (compiled parser)."""
    body = np.frombuffer(data, dtype=np.uint8, offset=pos) if pos < len(data) else np.zeros(0, np.uint8)
    values, status, rows, bad_line, bad_pos, bad_count = _numparse.parse(body, n_chan, n_frames, MAX_ABS_VALUE)
    line_no = first_data_line + bad_line
    if status == _numparse.BAD_TOKEN:
        tok = _token_at(body, bad_pos)
        what = "a non-finite value" if tok.lower().lstrip("+-") in ("nan", "inf", "infinity") else "text"
        raise BVHParseError(f"expected a number, found {what} {tok!r}", path, line_no)
    if status == _numparse.HUGE:
        raise BVHParseError(f"value {_token_at(body, bad_pos)!r} is out of range (limit {MAX_ABS_VALUE:g})", path,
                            line_no)
    if status == _numparse.BAD_COUNT:
        raise BVHParseError(f"frame line has {bad_count} values; the hierarchy declares {n_chan} channels",
                            path, line_no)
    if status == _numparse.TOO_MANY_LINES:
        raise BVHParseError(f"more frame lines than the {n_frames} declared in 'Frames:'", path, line_no)
    if rows < n_frames:
        raise BVHParseError(f"file is truncated: 'Frames: {n_frames}' but {rows} frame lines found", path,
                            line_no)
    return values


def parse_bvh(data: bytes, path=None) -> BVHData:
    """Parse the bytes of a BVH file into :class:`BVHData` (file units and axes, no conversion).

    Raises:
        BVHParseError: naming the file and line of the first problem found.
    """
    data = _normalize_text(bytes(data))
    _check_start(data, path)
    m = _MOTION_RE.search(data, 0, _MAX_HEADER_BYTES)
    if m is None:
        if len(data) > _MAX_HEADER_BYTES:
            raise BVHParseError(f"no MOTION section in the first {_MAX_HEADER_BYTES >> 20} MiB (header too large)",
                                path, data[:_MAX_HEADER_BYTES].count(b"\n") + 1)
        raise BVHParseError("no MOTION section", path, data.rstrip().count(b"\n") + 1)
    try:
        header = data[: m.start()].decode("utf-8")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise BVHParseError("header is not valid UTF-8 text", path, line) from None
    h = Header(header.replace("\r", ""), path)
    names, parents, offsets, channels, end_parents, end_offsets = parse_hierarchy(h)
    if h.peek() is not None:
        raise h.err(f"unexpected {h.peek()[:40]!r} after the hierarchy")
    motion_line = data[: m.start()].count(b"\n") + 1
    n_frames, frame_time, pos, lines_seen = _motion_header(data, m.end(), motion_line, path)
    values = _frame_values(data, pos, sum(len(c) for c in channels), n_frames, lines_seen + 1, path)
    return BVHData(tuple(names), np.array(parents, dtype=np.int64),
                   np.array(offsets, dtype=np.float64).reshape(-1, 3), tuple(channels),
                   np.array(end_parents, dtype=np.int64), np.array(end_offsets, dtype=np.float64).reshape(-1, 3),
                   frame_time, values, None if path is None else str(path))


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


def resolve_scale(scale: float | str) -> float:
    """Metres per file unit from a number or a unit name of :data:`UNIT_SCALES`.

    Raises:
        ParameterError: an unknown unit name, or a number outside ``SCALE_RANGE`` (1e-9 to 1e3 m).
    """
    if isinstance(scale, str):
        if scale not in UNIT_SCALES:
            raise ParameterError(f"unknown unit {scale!r}; known units: {', '.join(UNIT_SCALES)}")
        return UNIT_SCALES[scale]
    try:
        s = float(scale)
    except (TypeError, ValueError):
        raise ParameterError(f"scale must be a number of metres per file unit or a unit name, got {scale!r}") \
            from None
    lo, hi = SCALE_RANGE
    if not lo <= s <= hi:  # also rejects nan
        raise ParameterError(f"scale must be between {lo:g} and {hi:g} metres per file unit, got {scale!r}")
    return s


def detect_scale(size_in_file_units: float) -> tuple[str, float]:
    """The unit (name, metres per unit) that makes a body of this size closest to 1.7 m."""
    if not np.isfinite(size_in_file_units) or size_in_file_units <= 0:
        return "m", 1.0
    best = min(UNIT_SCALES.items(), key=lambda kv: abs(np.log(size_in_file_units * kv[1] / _TYPICAL_BODY_SIZE_M)))
    return best


def _body_size(offsets, parents, rot_q, pos, has_pos, end_parents, end_offsets) -> float:
    from kinodyn.kinematics import fk_arrays

    n = rot_q.shape[0]
    idx = np.linspace(0, n - 1, min(n, 16)).astype(int)
    idx = idx[np.r_[True, idx[1:] != idx[:-1]]]  # as np.unique (sorted already), without importing numpy.ma
    trans = None
    if pos.shape[1] > 1:
        trans = np.where(has_pos[None, :, None], pos[idx], offsets[None])
    gr, gp = fk_arrays(pos[idx, 0], rot_q[idx], offsets, parents, trans)
    if len(end_parents):
        gp = np.concatenate([gp, gp[:, end_parents] + quat.mul_vec(gr[:, end_parents], end_offsets)], axis=1)
    return float(median(np.ptp(gp, axis=1).max(axis=1)))


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
    else:
        scale = resolve_scale(scale)
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


def bvh_from_bytes(data: bytes, path=None, scale: float | str | None = None, up: str = "y",
                   name: str = "") -> Motion:
    """A :class:`Motion` from the bytes of a BVH file (what :func:`read_bvh` does after reading).

    Raises:
        BVHParseError: the data is malformed; the message names ``path`` and the line.
        ParameterError: ``scale`` or ``up`` is invalid.
    """
    d = parse_bvh(data, path)
    try:
        return to_motion(d, scale=scale, up=up, name=name)
    except (SkeletonError, MotionError) as e:  # values the parser let through but the model rejects
        raise BVHParseError(str(e), path) from e


def read_bvh(path, scale: float | str | None = None, up: str = "y") -> Motion:
    """Read a BVH file as a :class:`Motion` (Z up, metres).

    Args:
        path: the file.
        scale: metres per file unit (or a unit name: m, cm, mm, inch, cmu); detected when None.
        up: the file's up axis (``"y"`` for nearly every BVH in the wild).

    Raises:
        BVHParseError: the file is malformed (the message names file and line).
        ParameterError: ``scale`` or ``up`` is invalid.
        FileNotFoundError: the file does not exist.
    """
    p = Path(path)
    with open(p, "rb") as fh:
        _check_start(_normalize_text(fh.read(_SNIFF_BYTES)), p)  # reject garbage before reading it all
        fh.seek(0)
        data = fh.read()
    return bvh_from_bytes(data, p, scale=scale, up=up, name=p.stem)


# --------------------------------------------------------------------------- writing


def _length_decimals(scale: float) -> int:
    """Decimals that resolve 1e-8 m in a unit of ``scale`` metres (at least 6)."""
    return int(min(12, max(6, np.ceil(np.log10(scale / 1e-8)))))


def to_bvh_text(motion: Motion, scale: float | str = "cm", up: str = "y", order: str = "zyx",
                precision: int | None = None) -> str:
    """BVH text of a motion.

    Args:
        scale: metres per written unit or a unit name (default centimetres).
        up: the written file's up axis, ``"y"`` or ``"z"``.
        order: intrinsic rotation order of every joint's channels (``"zyx"`` writes Zrotation Yrotation
            Xrotation).
        precision: decimals written for every value; by default 6, or more when the unit is so large
            that 6 decimals would not resolve 1e-8 m (8 for metres).

    Raises:
        ParameterError: an option is invalid, a joint name is empty or contains whitespace, or the
            joints are not in depth-first order.
    """
    scale = resolve_scale(scale)
    order = order.lower()
    if order not in quat.EULER_ORDERS:
        raise ParameterError(f"order must be one of {', '.join(quat.EULER_ORDERS)}, got {order!r}")
    up = up.lower()
    if up not in ("y", "z"):
        raise ParameterError(f"up must be 'y' or 'z', got {up!r}")
    if precision is None:
        precision = _length_decimals(scale)
    precision = int(precision)
    if not 0 <= precision <= 17:
        raise ParameterError(f"precision must be between 0 and 17 decimals, got {precision}")
    sk = motion.skeleton
    children = _writable_children(sk)
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
    lines = _hierarchy_lines(sk, children, offsets, end_offsets, rot_names, six, precision)
    lines.append("MOTION")
    lines.append(f"Frames: {motion.num_frames}")
    lines.append(f"Frame Time: {1.0 / motion.fps:.10f}")
    return "\n".join(lines) + "\n" + _frame_lines(root, trans, euler, precision) + "\n"


def _writable_children(sk: Skeleton) -> list[list[int]]:
    """Children of every joint, after checking the names and the depth-first order BVH needs."""
    for n in sk.names:
        if not n or any(ch.isspace() for ch in n) or n in ("{", "}"):
            raise ParameterError(f"joint name {n!r} cannot be written to BVH (empty or contains whitespace)")
    children = [[] for _ in sk.names]
    for j in range(1, sk.num_joints):
        children[sk.parents[j]].append(j)
    dfs, stack = [], [0]
    while stack:
        j = stack.pop()
        dfs.append(j)
        stack.extend(reversed(children[j]))
    if dfs != list(range(sk.num_joints)):
        raise ParameterError("skeleton joints are not in depth-first order; BVH needs parents listed before "
                             "their children and each subtree contiguous")
    return children


def _hierarchy_lines(sk: Skeleton, children, offsets, end_offsets, rot_names: str, six: bool,
                     precision: int) -> list[str]:
    """The ``HIERARCHY`` lines: offsets ``(J, 3)``, end offsets ``(E, 3)`` in written units and axes."""
    ends = [[] for _ in sk.names]
    for e, p in enumerate(sk.end_parents):
        ends[p].append(e)
    fmt = f"{{:.{precision}f}}"

    def off(v) -> str:
        return " ".join(fmt.format(0.0 if abs(x) < 0.5 * 10.0 ** -precision else x) for x in v)

    lines = ["HIERARCHY"]
    # Iterative depth-first emission: ("open", joint, depth) writes the joint's head and schedules its
    # children, end sites and closing brace; ("close", joint, depth) writes the brace.
    todo: list[tuple[str, int, int]] = [("open", 0, 0)]
    while todo:
        kind, j, depth = todo.pop()
        ind = "\t" * min(depth, _MAX_INDENT)  # deep chains would make the header quadratic
        if kind == "close":
            for e in ends[j]:
                lines.append(f"{ind}\tEnd Site")
                lines.append(f"{ind}\t{{")
                lines.append(f"{ind}\t\tOFFSET {off(end_offsets[e])}")
                lines.append(f"{ind}\t}}")
            lines.append(f"{ind}}}")
            continue
        kw = "ROOT" if j == 0 else "JOINT"
        lines.append(f"{ind}{kw} {sk.names[j]}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}\tOFFSET {off(offsets[j])}")
        if j == 0 or six:
            lines.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition {rot_names}")
        else:
            lines.append(f"{ind}\tCHANNELS 3 {rot_names}")
        todo.append(("close", j, depth))
        for k in reversed(children[j]):
            todo.append(("open", k, depth + 1))
    return lines


def _frame_lines(root, trans, euler, precision: int) -> str:
    """The frame lines: root positions ``(F, 3)``, joint translations ``(F, J, 3)`` or None, Euler
    angles ``(F, J, 3)`` in degrees, each joint's channels in the hierarchy's order."""
    f, num_joints = euler.shape[:2]
    cols = []
    for j in range(num_joints):
        if j == 0:
            cols.append(root)
        elif trans is not None:
            cols.append(trans[:, j])
        cols.append(euler[:, j])
    table = np.concatenate(cols, axis=1) if f else np.zeros((0, 1))
    table = np.where(np.abs(table) < 0.5 * 10.0 ** -precision, 0.0, table)  # no "-0.000000"
    row = " ".join([f"%.{precision}f"] * table.shape[1])
    return "\n".join(row % tuple(r) for r in table.tolist())


def write_bvh(path, motion: Motion, scale: float | str = "cm", up: str = "y", order: str = "zyx",
              precision: int | None = None) -> None:
    """Write ``motion`` as a BVH file, atomically (see :func:`to_bvh_text` for the options)."""
    text = to_bvh_text(motion, scale=scale, up=up, order=order, precision=precision)
    atomic_write_bytes(path, text.encode("utf-8"))
