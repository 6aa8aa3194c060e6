"""What the Acclaim ASF and AMC readers share: number checks, text decoding, units and axes.

Private to :mod:`kinodyn.io` (:mod:`kinodyn.io.asf`, :mod:`kinodyn.io.amc`); the format is described in
:mod:`kinodyn.io.amc`.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from kinodyn.errors import AMCParseError, ParameterError

#: Largest magnitude accepted for any number (file units or angles).
MAX_ABS_VALUE = 1e9
MAX_BONES = 10_000
ROT_DOFS = ("rx", "ry", "rz")
TRANS_DOFS = ("tx", "ty", "tz")
NUMBER_RE = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
INT_RE = re.compile(r"[0-9]+\Z")
LIMIT_RE = re.compile(r"\(\s*([^\s()]+)\s+([^\s()]+)\s*\)")


def up_turn(up: str):
    """The turn from a file's up axis to kinodyn's Z up (``None`` for a Z-up file)."""
    from kinodyn.io.bvh import Y_UP_TO_Z_UP

    up = str(up).lower()
    if up not in ("y", "z"):
        raise ParameterError(f"up must be 'y' or 'z', got {up!r}")
    return Y_UP_TO_Z_UP if up == "y" else None


def metres_per_unit(scale, default: float) -> float:
    """Metres per file unit: ``scale`` (a number or unit name) or, when it is None, ``default``."""
    from kinodyn.io.bvh import resolve_scale

    if scale is None:
        return default
    return resolve_scale(scale)


def order_euler(axes: list[str], angles: np.ndarray) -> tuple[str, np.ndarray]:
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


def token_kind(tok: str) -> str:
    """How to name a token that is not a number in an error message."""
    return "a non-finite value" if tok.lower().lstrip("+-") in ("nan", "inf", "infinity") else "text"


def read_text(path: Path, err) -> str:
    return decode_text(path.read_bytes(), path, err)
