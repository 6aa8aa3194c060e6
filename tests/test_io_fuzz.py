"""Fuzzing the motion-file readers: mutated files either load or raise a kinodyn error.

Starting from small valid files, hypothesis applies byte flips, truncations, line deletions,
duplications and swaps, insertions, and token replacements (nan, inf, text, huge numbers, keywords,
braces, binary bytes). Reading must succeed (with finite results) or raise
:class:`kinodyn.errors.KinodynError`; parse errors must name the file. Anything else (IndexError,
numpy's ValueError, MemoryError, RecursionError, a RuntimeWarning turned into an error by the pytest
configuration) fails the test.
"""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinodyn.errors import FileFormatError, KinodynError
from kinodyn.io.amc import amc_from_text, decode_text, parse_asf
from kinodyn.io.bvh import bvh_from_bytes

SEED_BVH = b"""HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT Head
    {
      OFFSET 0 12.5 1
      CHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation Zrotation
      End Site
      {
        OFFSET 0 4 0
      }
    }
  }
  JOINT Leg
  {
    OFFSET 3 -1 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 -40 0
    }
  }
}
MOTION
Frames: 3
Frame Time: .0083333
1.5 90.0 -3.25 10 20 30 5 -5 45 0 12.5 1 0 0 0 -15 2 3
1.6 90.1 -3.20 11 21 31 6 -4 46 0 12.5 1 1e1 0 0 -14 2.5 3.5
1.7 90.2 -3.15 12 22 32 7 -3 47 0 13.0 1 0 .5 -0 -13 3 4
"""

SEED_ASF = """:version 1.10
:name fuzz
:units
  mass 1.0
  length 0.45
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name lfemur
     direction 0.34202 -0.939693 0
     length 7.1578
     axis 0 0 20  XYZ
    dof rx ry rz
    limits (-160.0 20.0)
           (-70.0 70.0)
           (-60.0 70.0)
  end
  begin
     id 2
     name ltibia
     direction 0.34202 -0.939693 0
     length 7.49137
     axis 0 0 20 XYZ
    dof rx
    limits (-10.0 170.0)
  end
  begin
     id 3
     name head
     direction 0 1 0
     length 2
     axis 0 0 0 XYZ
    dof rx rz
  end
:hierarchy
  begin
    root lfemur head
    lfemur ltibia
  end
"""

SEED_AMC = """:FULLY-SPECIFIED
:DEGREES
1
root 9.37 17.86 -17.31 -2.01 -7.59 -3.23
lfemur 4.0 1.2 -13.8
ltibia 20.0
head 10.5 -2.5
2
root 9.38 17.87 -17.32 -2.02 -7.58 -3.10
lfemur 4.1 1.3 -13.7
ltibia 20.5
head 10.6 -2.6
3
root 9.39 17.88 -17.33 -2.03 -7.57 -3.00
lfemur 4.2 1.4 -13.6
ltibia 21.0
head 10.7 -2.7
"""

TOKENS = [b"nan", b"NaN", b"inf", b"-inf", b"Infinity", b"1e400", b"-1e309", b"1e-400", b"abc", b"",
          b"99999999999999999999", b"9999999999999999999", b"1e9", b"1e12", b"1.5.5", b"-", b".", b"+.",
          b"1e", b"{", b"}", b"JOINT", b"ROOT", b"End", b"Site", b"CHANNELS", b"OFFSET", b"MOTION", b"HIERARCHY",
          b"Frames:", b"Frame Time:", b"0x10", b"1_0", "\u0663".encode(), "\u00b2".encode(), b"\x00", b"\xff\xfe",
          b"3000000000", b"6", b"3", b"0", b"-1", b"4294967296", b"\r\n", b"\n", b"\t", b"Xposition", b"Zrotation",
          b"begin", b"end", b"root", b":bonedata", b":hierarchy", b"dof", b"rx", b"tx", b"axis", b"XYZ", b"XXY",
          b"(1 2)", b"lfemur", b"head"]


@st.composite
def mutations(draw):
    kind = draw(st.sampled_from(["flip", "truncate", "delete_line", "dup_line", "swap_lines", "token", "insert",
                                 "token", "token"]))
    a = draw(st.integers(0, 10_000))
    b = draw(st.integers(0, 10_000))
    if kind == "flip":
        return kind, a, draw(st.integers(0, 255))
    if kind == "insert":
        return kind, a, draw(st.one_of(st.sampled_from(TOKENS), st.binary(min_size=1, max_size=8)))
    if kind == "token":
        return kind, a, draw(st.sampled_from(TOKENS))
    return kind, a, b


def mutate(data: bytes, ops) -> bytes:
    for kind, a, b in ops:
        if kind == "flip" and data:
            i = a % len(data)
            data = data[:i] + bytes([b]) + data[i + 1:]
        elif kind == "truncate":
            data = data[: a % (len(data) + 1)]
        elif kind in ("delete_line", "dup_line", "swap_lines"):
            lines = data.split(b"\n")
            i = a % len(lines)
            if kind == "delete_line":
                del lines[i]
            elif kind == "dup_line":
                lines.insert(i, lines[i])
            else:
                j = b % len(lines)
                lines[i], lines[j] = lines[j], lines[i]
            data = b"\n".join(lines)
        elif kind == "insert":
            i = a % (len(data) + 1)
            data = data[:i] + b + data[i:]
        elif kind == "token":
            toks = list(_token_spans(data))
            if toks:
                s, e = toks[a % len(toks)]
                data = data[:s] + b + data[e:]
    return data


def _token_spans(data: bytes):
    i, n = 0, len(data)
    while i < n:
        while i < n and data[i] in b" \t\r\n":
            i += 1
        s = i
        while i < n and data[i] not in b" \t\r\n":
            i += 1
        if i > s:
            yield s, i


_SETTINGS = {"deadline": None, "derandomize": True, "database": None,
             "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much]}


def _check_error(e: KinodynError, path: str):
    """A bad file is reported as a FileFormatError naming the file (and its line, where there is one) in
    one line of text: never another kind of error, a message without the file, or a traceback's worth."""
    assert isinstance(e, FileFormatError), f"{type(e).__name__}: {e}"
    assert e.path == path, str(e)
    assert e.line is None or e.line >= 1, str(e)
    assert str(e).startswith(f"{path}:" if e.line is None else f"{path}:{e.line}: "), str(e)
    assert e.reason.strip() and "\n" not in str(e), str(e)


def test_seeds_are_valid():
    m = bvh_from_bytes(SEED_BVH, "seed.bvh")
    assert m.num_frames == 3 and m.translations is not None
    asf = parse_asf(SEED_ASF, "seed.asf")
    assert amc_from_text(SEED_AMC, asf, "seed.amc").num_frames == 3


def test_bvh_fuzz():
    """At least 1,000 mutated BVH files: each loads or raises a KinodynError naming the file."""
    count = {"n": 0, "ok": 0}

    @settings(max_examples=1100, **_SETTINGS)
    @given(ops=st.lists(mutations(), min_size=1, max_size=4), scale=st.sampled_from([None, None, "cm", 0.5]),
           up=st.sampled_from(["y", "y", "z"]), body_only=st.booleans())
    def run(ops, scale, up, body_only):
        count["n"] += 1
        if body_only:  # half the files keep their hierarchy intact and have the MOTION part mutated
            k = SEED_BVH.index(b"MOTION")
            data = SEED_BVH[:k] + mutate(SEED_BVH[k:], ops)
        else:
            data = mutate(SEED_BVH, ops)
        try:
            m = bvh_from_bytes(data, "fuzz.bvh", scale=scale, up=up)
        except KinodynError as e:
            _check_error(e, "fuzz.bvh")
            return
        count["ok"] += 1
        assert np.isfinite(m.global_positions()).all()
        assert np.isfinite(m.root_pos).all() and m.fps > 0

    run()
    assert count["n"] >= 1000, count
    assert 0.02 * count["n"] < count["ok"] < count["n"], count  # the mutations hit both outcomes


def test_amc_fuzz():
    """Mutated AMC files against a fixed skeleton."""
    asf = parse_asf(SEED_ASF, "seed.asf")
    count = {"n": 0, "ok": 0}

    @settings(max_examples=300, **_SETTINGS)
    @given(ops=st.lists(mutations(), min_size=1, max_size=4))
    def run(ops):
        count["n"] += 1
        data = mutate(SEED_AMC.encode(), ops)
        try:
            m = amc_from_text(decode_text(data, "fuzz.amc"), asf, "fuzz.amc")
        except KinodynError as e:
            _check_error(e, "fuzz.amc")
            return
        count["ok"] += 1
        assert np.isfinite(m.global_positions()).all()

    run()
    assert count["n"] >= 300
    assert 0.05 * count["n"] < count["ok"] < count["n"], count  # a reader rejecting everything fails here


def test_asf_fuzz():
    """Mutated ASF files: parse, build the skeleton, read a motion with it."""
    count = {"n": 0, "asf_ok": 0, "ok": 0}

    @settings(max_examples=300, **_SETTINGS)
    @given(ops=st.lists(mutations(), min_size=1, max_size=4))
    def run(ops):
        count["n"] += 1
        data = mutate(SEED_ASF.encode(), ops)
        try:
            asf = parse_asf(decode_text(data, "fuzz.asf"), "fuzz.asf")
            sk = asf.skeleton()
            assert np.isfinite(sk.offsets).all()
        except KinodynError as e:
            _check_error(e, "fuzz.asf")
            return
        count["asf_ok"] += 1
        try:
            m = amc_from_text(SEED_AMC, asf, "seed.amc")
        except KinodynError as e:
            _check_error(e, "seed.amc")
            return
        count["ok"] += 1
        assert np.isfinite(m.global_positions()).all()

    run()
    assert count["n"] >= 300
    # both readers accept a fair share of the mutated skeletons and reject the rest
    assert 0.05 * count["n"] < count["asf_ok"] < count["n"], count
    assert 0 < count["ok"] <= count["asf_ok"], count
