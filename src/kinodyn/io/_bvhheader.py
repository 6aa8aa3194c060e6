"""The HIERARCHY part of a BVH file: a token stream with line numbers and the joint tree it declares.

Private to :mod:`kinodyn.io` (used by :func:`kinodyn.io.bvh.parse_bvh`, where the format is described).
"""

from __future__ import annotations

import re

from kinodyn.errors import BVHParseError

#: Largest number of joints accepted in a hierarchy.
MAX_JOINTS = 10_000
#: Largest magnitude accepted for any number in the file (file units or degrees).
MAX_ABS_VALUE = 1e9

CHANNEL_RE = re.compile(r"^([XYZxyz])(position|rotation)$", re.IGNORECASE)
NUMBER_RE = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
UINT_RE = re.compile(r"[0-9]+\Z")


def parse_number(tok: str) -> float | None:
    """``float(tok)`` for a plain decimal (``[+-]digits[.digits][e[+-]digits]``), else None.

    Python's ``float`` also takes ``nan``, ``inf``, ``1_000`` and non-ASCII digits; BVH does not.
    """
    if NUMBER_RE.match(tok) is None:
        return None
    return float(tok)


class Header:
    """A lazy token stream over the hierarchy text, with line numbers and one token of look-ahead."""

    def __init__(self, text: str, path):
        self.path = path
        self.last_line = text.count("\n") + 1
        self._gen = self._tokens(text)
        self._ahead: tuple[str, int] | None = None
        self._line = 1

    @staticmethod
    def _tokens(text: str):
        for ln, line in enumerate(text.split("\n"), start=1):
            for tok in line.split():
                yield tok, ln

    def _fill(self) -> tuple[str, int] | None:
        if self._ahead is None:
            self._ahead = next(self._gen, None)
        return self._ahead

    def err(self, msg: str, line: int | None = None):
        if line is None:
            t = self._fill()
            line = t[1] if t is not None else self.last_line
        return BVHParseError(msg, self.path, line)

    def next(self, what: str) -> tuple[str, int]:
        t = self._fill()
        if t is None:
            raise self.err(f"unexpected end of the hierarchy, expected {what}", self._line)
        self._ahead = None
        self._line = t[1]
        return t

    def expect(self, word: str, context: str = "") -> int:
        tok, ln = self.next(repr(word))
        if tok.upper() != word.upper():
            raise self.err(f"expected {word!r}{context}, found {tok[:40]!r}", ln)
        return ln

    def number(self, what: str) -> float:
        tok, ln = self.next(what)
        v = parse_number(tok)
        if v is None:
            low = tok.lower().lstrip("+-")
            kind = "a non-finite value" if low in ("nan", "inf", "infinity") else "text"
            raise self.err(f"expected a number for {what}, found {kind} {tok[:40]!r}", ln)
        if abs(v) > MAX_ABS_VALUE:
            raise self.err(f"{what} is out of range: {tok[:40]!r} (limit {MAX_ABS_VALUE:g})", ln)
        return v

    def peek(self) -> str | None:
        t = self._fill()
        return None if t is None else t[0]


def parse_hierarchy(h: Header):
    """Read ``HIERARCHY ROOT ...`` (iteratively: nesting depth is limited only by :data:`MAX_JOINTS`)."""
    names: list[str] = []
    name_set: set[str] = set()
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    end_parents: list[int] = []
    end_offsets: list[list[float]] = []

    def offset(what: str) -> list[float]:
        h.expect("OFFSET", f" in {what}")
        return [h.number(f"{what} OFFSET x"), h.number(f"{what} OFFSET y"), h.number(f"{what} OFFSET z")]

    def open_joint(parent: int) -> int:
        name, ln = h.next("a joint name")
        if name in ("{", "}"):
            raise h.err("joint has no name", ln)
        if name in name_set:
            raise h.err(f"joint name {name[:40]!r} is used twice", ln)
        if len(names) >= MAX_JOINTS:
            raise h.err(f"more than {MAX_JOINTS} joints in the hierarchy", ln)
        h.expect("{", f" after joint name {name[:40]!r}")
        idx = len(names)
        names.append(name)
        name_set.add(name)
        parents.append(parent)
        offsets.append(offset(f"joint {name[:40]!r}"))
        tok, ln = h.next("CHANNELS")
        if tok.upper() != "CHANNELS":
            raise h.err(f"expected 'CHANNELS' for joint {name[:40]!r}, found {tok[:40]!r}", ln)
        cnt_tok, ln = h.next("a channel count")
        if not UINT_RE.match(cnt_tok):
            raise h.err(f"channel count of joint {name[:40]!r} must be an integer, found {cnt_tok[:40]!r}", ln)
        cnt = int(cnt_tok) if len(cnt_tok) < 10 else 10 ** 9
        if cnt not in (0, 3, 6):
            raise h.err(f"joint {name[:40]!r} declares {cnt_tok[:20]} channels; expected 3 or 6", ln)
        chans = []
        for _ in range(cnt):
            c, cl = h.next("a channel name")
            if not CHANNEL_RE.match(c):
                raise h.err(f"unknown channel {c[:40]!r} on joint {name[:40]!r} (expected e.g. Xposition, Zrotation)",
                            cl)
            chans.append(c[0].upper() + c[1:].lower())
        rot = [c for c in chans if c.endswith("rotation")]
        pos = [c for c in chans if c.endswith("position")]
        if len(set(chans)) != len(chans) or len(rot) not in (0, 3) or len(pos) not in (0, 3):
            raise h.err(f"joint {name[:40]!r} must have three distinct rotation channels (and optionally three "
                        f"position channels), found {' '.join(chans)}", ln)
        channels.append(tuple(chans))
        return idx

    h.expect("HIERARCHY")
    tok, ln = h.next("ROOT")
    if tok.upper() != "ROOT":
        raise h.err(f"expected 'ROOT', found {tok[:40]!r}", ln)
    stack = [open_joint(-1)]
    while stack:
        cur = stack[-1]
        tok, ln = h.next(f"'JOINT', 'End Site' or '}}' to close joint {names[cur][:40]!r}")
        up = tok.upper()
        if up == "}":
            stack.pop()
        elif up == "JOINT":
            stack.append(open_joint(cur))
        elif up == "END":
            h.expect("Site", " after 'End'")
            h.expect("{", " after 'End Site'")
            end_parents.append(cur)
            end_offsets.append(offset(f"end site of {names[cur][:40]!r}"))
            h.expect("}", " to close the end site")
        else:
            raise h.err(f"expected 'JOINT', 'End Site' or '}}' inside joint {names[cur][:40]!r}, found {tok[:40]!r}",
                        ln)
    if h.peek() is not None and h.peek().upper() == "ROOT":
        raise h.err("files with more than one ROOT are not supported")
    if not channels[0]:
        raise h.err(f"the root joint {names[0][:40]!r} has no channels", 2)
    return names, parents, offsets, channels, end_parents, end_offsets
