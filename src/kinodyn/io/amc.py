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
locate the line of any error, a line-by-line reader groups the values by bone name. ASF skeletons are
read by :mod:`kinodyn.io.asf` (its names are re-exported here).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinodyn.errors import AMCParseError, MotionError, ParameterError, SkeletonError
from kinodyn.io import _numparse
from kinodyn.io._acclaim import (
    INT_RE,
    MAX_ABS_VALUE,
    NUMBER_RE,
    ROT_DOFS,
    TRANS_DOFS,
    decode_text,
    metres_per_unit,
    order_euler,
    read_text,
    token_kind,
    up_turn,
)
from kinodyn.io.asf import PASS_ASF, AsfSkeleton, find_asf, parse_asf, read_asf
from kinodyn.math import quat
from kinodyn.motion import Motion

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
            v = float(parts[1]) if len(parts) == 2 and NUMBER_RE.match(parts[1]) else -1.0
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
        if len(toks) == 1 and INT_RE.match(t0):
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
            if NUMBER_RE.match(tok) is None:
                raise AMCParseError(f"expected a number, found {token_kind(tok)} {tok[:40]!r}", path, ln)
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
        if len(toks) == 1 and INT_RE.match(toks[0]):
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
    text = read_text(p, AMCParseError)
    return amc_from_text(text, asf, p, scale=scale, up=up, fps=fps, name=p.stem)


def amc_from_text(text: str, asf: AsfSkeleton, path=None, scale: float | str | None = None, up: str = "y",
                  fps: float | None = None, name: str = "") -> Motion:
    """A :class:`~kinodyn.motion.Motion` from the text of an AMC file and its skeleton (what
    :func:`read_amc` does after reading the files; same options).

    Raises:
        AMCParseError: the text is malformed; the message names ``path`` and the line.
    """
    p = path
    turn = up_turn(up)
    s = metres_per_unit(scale, asf.metres_per_unit)
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
                if d in TRANS_DOFS:
                    root_pos[:, "xyz".index(d[1])] = v[:, k]
        rot = [k for k, d in enumerate(dofs) if d in ROT_DOFS]
        if not rot:
            continue
        order, ang = order_euler([dofs[k][1] for k in rot], v[:, rot] * to_rad)
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
    if not any(d in TRANS_DOFS for d in asf.dofs[0]):
        root_pos[:] = asf.skeleton(scale=1.0, up=up).offsets[0]
    try:
        sk = asf.skeleton(scale=s, up=up)
        return Motion(sk, root_pos * s, local, fps or file_fps or CMU_FPS, None, name)
    except (SkeletonError, MotionError) as e:
        raise AMCParseError(str(e), p) from e
