"""A compiled parser for the numeric body of motion files (BVH ``MOTION`` blocks).

The numbers of a 10,000-frame BVH file are about a million decimal strings; numpy's text readers spend
a quarter of a second on them. This parser makes one pass over the bytes: it accumulates up to 18
significant digits into an integer and scales by an exact power of ten (Clinger's fast path, which is
correctly rounded whenever the mantissa is below 2**53 and the decimal exponent within +-22), and it
counts the values on every line so that ragged lines are reported with their line number. Digits
beyond the 18th significant one (which would overflow the 64-bit accumulator) only shift the exponent,
far below float64 resolution. Values whose magnitude exceeds ``max_abs`` (inf included) stop the parse
with :data:`HUGE`, so absurd numbers never reach the arithmetic downstream. :func:`parse_named_lines`
is the variant for AMC frames (a bone name, then numbers, on each line).

Accepted tokens: ``[+-]digits[.digits][(e|E)[+-]digits]`` (either side of the point may be empty but
not both), separated by spaces, tabs, CR or LF. Anything else (``nan``, ``inf``, ``1,5``, letters) is
an error.
"""

from __future__ import annotations

import numba
import numpy as np

OK = 0
BAD_TOKEN = 1
BAD_COUNT = 2
TOO_MANY_LINES = 3
HUGE = 4

_POW10 = np.array([10.0 ** k for k in range(23)])


@numba.njit(cache=True)
def _scale(mant, exp10, pow10):  # pragma: no cover - compiled
    if mant == 0:
        return 0.0
    if mant < 9007199254740992 and -22 <= exp10 <= 22:
        if exp10 >= 0:
            return float(mant) * pow10[exp10]
        return float(mant) / pow10[-exp10]
    return float(mant) * 10.0 ** exp10


@numba.njit(cache=True, inline="always")
def _number(buf, i, n, pow10):  # pragma: no cover - compiled
    """Parse the number starting at ``buf[i]``; returns ``(ok, value, next_i)``.

    ``ok`` is False when the token is not a plain decimal (or is not followed by whitespace/end).
    """
    c = buf[i]
    neg = False
    if c == 45 or c == 43:
        neg = c == 45
        i += 1
    mant = 0
    nd = 0
    exp10 = 0
    digits = 0
    while i < n and 48 <= buf[i] <= 57:
        if nd < 18:
            mant = mant * 10 + (buf[i] - 48)
            if mant != 0:
                nd += 1
        else:
            exp10 += 1
        digits += 1
        i += 1
    if i < n and buf[i] == 46:  # '.'
        i += 1
        while i < n and 48 <= buf[i] <= 57:
            if nd < 18:
                mant = mant * 10 + (buf[i] - 48)
                if mant != 0:
                    nd += 1
                exp10 -= 1
            digits += 1
            i += 1
    if digits == 0:
        return False, 0.0, i
    if i < n and (buf[i] == 101 or buf[i] == 69):  # e / E
        i += 1
        eneg = False
        if i < n and (buf[i] == 45 or buf[i] == 43):
            eneg = buf[i] == 45
            i += 1
        e = 0
        ed = 0
        while i < n and 48 <= buf[i] <= 57:
            if e < 100000:
                e = e * 10 + (buf[i] - 48)
            ed += 1
            i += 1
        if ed == 0:
            return False, 0.0, i
        exp10 += -e if eneg else e
    if i < n and not (buf[i] == 32 or buf[i] == 9 or buf[i] == 13 or buf[i] == 10):
        return False, 0.0, i
    v = _scale(mant, exp10, pow10)
    return True, -v if neg else v, i


# long kernel: one pass over the bytes with the scanner state in registers; split, it would pass that state
@numba.njit(cache=True)
def parse_rows(buf, per_line, max_lines, out, pow10, max_abs):  # pragma: no cover - compiled
    """Parse whitespace-separated decimals, ``per_line`` values on each non-blank line.

    Returns ``(status, n_lines, bad_line, bad_pos, bad_count)``; ``bad_line`` counts every line of
    ``buf`` from 0, blank ones too. ``out`` must hold ``max_lines * per_line`` values.
    """
    n = buf.shape[0]
    i = 0
    line = 0
    rows = 0
    in_line = 0
    k = 0
    while i < n:
        c = buf[i]
        if c == 10:  # LF ends a line
            if in_line != 0:
                if in_line != per_line:
                    return BAD_COUNT, rows, line, i, in_line
                rows += 1
                in_line = 0
            line += 1
            i += 1
            continue
        if c == 32 or c == 9 or c == 13:
            i += 1
            continue
        # a number starts here (the code of _number, written out: the inlined call costs ~30% here)
        start = i
        neg = False
        if c == 45 or c == 43:
            neg = c == 45
            i += 1
        mant = 0
        nd = 0
        exp10 = 0
        digits = 0
        while i < n and 48 <= buf[i] <= 57:
            if nd < 18:
                mant = mant * 10 + (buf[i] - 48)
                if mant != 0:
                    nd += 1
            else:
                exp10 += 1
            digits += 1
            i += 1
        if i < n and buf[i] == 46:  # '.'
            i += 1
            while i < n and 48 <= buf[i] <= 57:
                if nd < 18:
                    mant = mant * 10 + (buf[i] - 48)
                    if mant != 0:
                        nd += 1
                    exp10 -= 1
                digits += 1
                i += 1
        if digits == 0:
            return BAD_TOKEN, rows, line, start, in_line
        if i < n and (buf[i] == 101 or buf[i] == 69):  # e / E
            i += 1
            eneg = False
            if i < n and (buf[i] == 45 or buf[i] == 43):
                eneg = buf[i] == 45
                i += 1
            e = 0
            ed = 0
            while i < n and 48 <= buf[i] <= 57:
                if e < 100000:
                    e = e * 10 + (buf[i] - 48)
                ed += 1
                i += 1
            if ed == 0:
                return BAD_TOKEN, rows, line, start, in_line
            exp10 += -e if eneg else e
        if i < n and not (buf[i] == 32 or buf[i] == 9 or buf[i] == 13 or buf[i] == 10):
            return BAD_TOKEN, rows, line, start, in_line
        if in_line >= per_line:
            return BAD_COUNT, rows, line, start, in_line + 1
        if rows >= max_lines:
            return TOO_MANY_LINES, rows, line, start, in_line
        v = _scale(mant, exp10, pow10)
        if not v <= max_abs:  # also catches inf
            return HUGE, rows, line, start, in_line
        out[k] = -v if neg else v
        k += 1
        in_line += 1
    if in_line != 0:
        if in_line != per_line:
            return BAD_COUNT, rows, line, n, in_line
        rows += 1
    return OK, rows, line, n, 0


@numba.njit(cache=True)
def parse_named_lines(buf, out, counts, name_start, name_len, pow10, max_abs):  # pragma: no cover - compiled
    """Parse lines of the form ``[name] number number ...`` (AMC frames).

    A line's first token is a *name* when it does not start like a number (digit, sign or point): it is
    skipped and its byte offset and length are stored in ``name_start[line]``/``name_len[line]`` (which
    the caller fills with -1/0 beforehand). ``counts[line]`` receives the count of numbers on each line
    and ``out`` the numbers in order. ``counts``, ``name_start`` and ``name_len`` need one slot per line,
    ``out`` room for every number (``len(buf) // 2 + 1`` is enough). Returns ``(status, n_values,
    bad_line, bad_pos)``.
    """
    n = buf.shape[0]
    i = 0
    line = 0
    k = 0
    in_line = 0
    at_start = True
    while i < n:
        c = buf[i]
        if c == 10:
            counts[line] = in_line
            line += 1
            in_line = 0
            at_start = True
            i += 1
            continue
        if c == 32 or c == 9 or c == 13:
            i += 1
            continue
        start = i
        if at_start:
            at_start = False
            if not (48 <= c <= 57 or c == 43 or c == 45 or c == 46):
                while i < n and not (buf[i] == 32 or buf[i] == 9 or buf[i] == 13 or buf[i] == 10):
                    i += 1
                name_start[line] = start
                name_len[line] = i - start
                continue
        ok, v, i = _number(buf, i, n, pow10)
        if not ok:
            return BAD_TOKEN, k, line, start
        if not abs(v) <= max_abs:
            return HUGE, k, line, start
        out[k] = v
        k += 1
        in_line += 1
    counts[line] = in_line
    return OK, k, line, n


def parse(buf: bytes | np.ndarray, per_line: int, max_lines: int, max_abs: float = 1e300):
    """Parse ``buf``; returns ``(values (rows, per_line), status, n_rows, bad_line, bad_pos, bad_count)``.

    ``status`` is :data:`OK` or the first problem met (:data:`BAD_TOKEN`, :data:`BAD_COUNT`,
    :data:`TOO_MANY_LINES`, :data:`HUGE`); ``bad_line`` counts lines of ``buf`` from 0 and ``bad_pos`` is
    the byte offset of the offending token.
    """
    arr = np.frombuffer(buf, dtype=np.uint8) if isinstance(buf, (bytes, bytearray, memoryview)) else buf
    # Each value takes at least two bytes (a digit and a separator), which bounds the rows present, so a
    # huge declared frame count never allocates more than the text can hold.
    limit = min(max_lines, arr.shape[0] // max(2 * per_line, 1) + 1)
    out = np.empty(limit * per_line)
    status, rows, line, pos, count = parse_rows(arr, per_line, limit, out, _POW10, float(max_abs))
    return out[: rows * per_line].reshape(rows, per_line), status, rows, line, pos, count


@numba.njit(cache=True, parallel=True)
def euler_columns_to_quat(values, cols, axes, out):  # pragma: no cover - compiled
    """Quaternions ``out (F, J, 4)`` from Euler degrees stored in columns of ``values (F, C)``.

    ``cols (J, 3)`` are the column of each joint's first, second and third rotation channel (-1 for a
    joint without rotation channels: identity); ``axes (J, 3)`` the axis (0, 1, 2 = x, y, z) each
    channel turns about, applied intrinsically in that order (``R0 @ R1 @ R2``).
    """
    n_frames, n_joints = values.shape[0], cols.shape[0]
    deg2half = np.pi / 360.0
    for f in numba.prange(n_frames):
        for j in range(n_joints):
            w, x, y, z = 1.0, 0.0, 0.0, 0.0
            if cols[j, 0] >= 0:
                for k in range(3):
                    h = values[f, cols[j, k]] * deg2half
                    c = np.cos(h)
                    s = np.sin(h)
                    a = axes[j, k]
                    if a == 0:
                        w, x, y, z = w * c - x * s, w * s + x * c, y * c + z * s, z * c - y * s
                    elif a == 1:
                        w, x, y, z = w * c - y * s, x * c - z * s, w * s + y * c, z * c + x * s
                    else:
                        w, x, y, z = w * c - z * s, x * c + y * s, y * c - x * s, w * s + z * c
            out[f, j, 0] = w
            out[f, j, 1] = x
            out[f, j, 2] = y
            out[f, j, 3] = z


def parse_named(buf: bytes | np.ndarray, max_abs: float = 1e300):
    """Run :func:`parse_named_lines` on ``buf``.

    Returns ``(values, counts, name_start, name_len, status, bad_line, bad_pos)`` with one entry of
    ``counts``/``name_start``/``name_len`` per line of ``buf`` (``name_start`` -1 on lines without a name).
    """
    arr = np.frombuffer(buf, dtype=np.uint8) if isinstance(buf, (bytes, bytearray, memoryview)) else buf
    n_lines = int(np.count_nonzero(arr == 10)) + 1
    counts = np.zeros(n_lines, dtype=np.int64)
    name_start = np.full(n_lines, -1, dtype=np.int64)
    name_len = np.zeros(n_lines, dtype=np.int64)
    out = np.empty(arr.shape[0] // 2 + 1)
    status, k, line, pos = parse_named_lines(arr, out, counts, name_start, name_len, _POW10, float(max_abs))
    return out[:k], counts, name_start, name_len, status, line, pos
