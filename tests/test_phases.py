"""Support-phase sequences and their algebra (section 4 of the synchronization paper)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinodyn import phases as P
from kinodyn.phases import DS, ERR, FLIGHT, LS, RS
from kinodyn.errors import ParameterError

_TOL = 1e-9
ELEMENTS = [RS, LS, DS, FLIGHT, ERR]
codes = st.sampled_from(ELEMENTS)


def _rule(a, b):
    """The relation written from the paper's four rules (an oracle independent of the bit codes)."""
    if a == FLIGHT or b == FLIGHT:
        return FLIGHT                      # FLIGHT is absorbing
    if a == DS:
        return b                           # DS is neutral
    if b == DS:
        return a
    if a == ERR or b == ERR:
        return ERR                         # ERR absorbs RS, LS, DS
    if a == b:
        return a
    return ERR                             # RS with LS


def test_relation_matches_the_papers_rules_on_the_whole_table():
    for a, b in itertools.product(ELEMENTS, repeat=2):
        assert P.combine(a, b) == _rule(a, b), (a.name, b.name)


@given(codes, codes)
def test_commutative(a, b):
    assert P.combine(a, b) == P.combine(b, a)


@given(codes, codes, codes)
def test_associative(a, b, c):
    assert P.combine(P.combine(a, b), c) == P.combine(a, P.combine(b, c))


@given(codes)
def test_neutral_absorbing_and_idempotent(a):
    assert P.combine(DS, a) == a
    assert P.combine(FLIGHT, a) == FLIGHT
    assert P.combine(a, a) == a
    if a in (RS, LS, DS):
        assert P.combine(ERR, a) == ERR


def test_rs_with_ls_is_an_error():
    assert P.combine(RS, LS) == ERR
    assert P.opposite(RS) == LS and P.opposite(LS) == RS
    with pytest.raises(ParameterError):
        P.opposite(DS)


@given(st.lists(st.lists(codes, min_size=6, max_size=6), min_size=1, max_size=5))
def test_compatibility_of_n_sequences_is_elementwise_fold(seqs):
    got = P.compatible(*seqs)
    for k in range(6):
        acc = DS
        for s in seqs:
            acc = _rule(acc, s[k])
        assert got[k] == (acc != ERR)
    arr = np.array(seqs, dtype=np.int8)
    assert np.array_equal(P.combine_all(arr, axis=0) != ERR, got)


def test_frame_phases_and_runs():
    left = np.array([1, 1, 0, 0, 1, 0], bool)
    right = np.array([1, 0, 0, 1, 1, 1], bool)
    assert P.frame_phases(left, right).tolist() == [DS, LS, FLIGHT, RS, DS, RS]
    vals, a, b = P.runs([2, 2, 0, 1, 1, 1])
    assert vals.tolist() == [2, 0, 1] and a.tolist() == [0, 2, 3] and b.tolist() == [2, 3, 6]


def test_sequence_from_labels_merges_and_keeps_durations():
    # 10 fps: DS 2 frames, LS 3, DS 1 (kept: min_duration 0), RS 4
    left = np.array([1, 1, 1, 1, 1, 1, 0, 0, 0, 0], bool)
    right = np.array([1, 1, 0, 0, 0, 1, 1, 1, 1, 1], bool)
    s = P.from_labels(left, right, 10.0, cyclic=False, config=P.PhaseConfig(0.0))
    assert s.names() == ["DS", "LS", "DS", "RS"]
    # boundaries half-way between frames, ends at 0 and (F - 1) / fps
    np.testing.assert_allclose(s.bounds, [0.0, 0.15, 0.45, 0.55, 0.9], atol=_TOL)
    assert s.total == pytest.approx(0.9)
    # min_duration merges the one-frame double support into its longer neighbour
    s2 = P.from_labels(left, right, 10.0, cyclic=False, config=P.PhaseConfig(0.15))
    assert s2.names() == ["DS", "LS", "RS"]


def test_cyclic_sequence_folds_the_loop_point():
    # the last frame equals the first; the RS run at the end continues the RS at the start
    left = np.array([0, 0, 1, 1, 1, 1, 0, 0, 0], bool)
    right = np.array([1, 1, 1, 0, 0, 1, 1, 1, 1], bool)
    s = P.from_labels(left, right, 10.0, cyclic=True, config=P.PhaseConfig(0.0))
    assert s.cyclic
    assert s.names() == ["RS", "DS", "LS", "DS"]
    assert s.start == pytest.approx(-0.25)       # the RS element straddles the loop point
    assert s.total == pytest.approx(0.8)         # one period: (F - 1) / fps
    with pytest.raises(ParameterError):
        P.PhaseSequence([RS, DS, RS], [0.1, 0.1, 0.1], cyclic=True)


def test_extension_cyclic_repeats_whole_others_repeat_last():
    cyc = P.PhaseSequence([RS, DS, LS, DS], [0.3, 0.1, 0.3, 0.1], cyclic=True)
    ph, d = cyc.extended(10)
    assert ph.tolist() == [RS, DS, LS, DS] * 2 + [RS, DS]
    assert d.tolist() == pytest.approx([0.3, 0.1, 0.3, 0.1] * 2 + [0.3, 0.1])
    one = P.PhaseSequence([DS, LS, DS], [0.4, 0.8, 0.4])
    ph, d = one.extended(6)
    assert ph.tolist() == [DS, LS, DS, DS, DS, DS]
    # element times: cyclic copies are one period later; non-cyclic copies follow the clip's end
    assert cyc.element(5)[1:] == pytest.approx((0.8 + 0.3, 0.8 + 0.4))
    assert one.element(4)[1:] == pytest.approx((1.6 + 0.4, 1.6 + 0.8))


@given(st.floats(-3.0, 10.0))
def test_index_at_inverts_element(t):
    for seq in (P.PhaseSequence([RS, DS, LS, DS], [0.3, 0.1, 0.3, 0.1], cyclic=True, start=-0.05),
                P.PhaseSequence([DS, LS, DS], [0.4, 0.8, 0.4])):
        if t < seq.start:  # extended sequences start at their first element
            continue
        k = int(seq.index_at(t))
        ph, t0, t1 = seq.element(k)
        assert t0 - 1e-9 <= t < t1 + 1e-9
        assert seq.phase_at(t) == ph


def test_time_scaling_adapts_the_sequence_like_the_motion():
    s = P.PhaseSequence([RS, DS, LS, DS], [0.3, 0.1, 0.3, 0.1], cyclic=True, start=-0.05)
    f = s.time_scaled(2.0)
    np.testing.assert_allclose(f.durations, s.durations / 2)
    assert f.start == pytest.approx(-0.025) and f.phases.tolist() == s.phases.tolist()
    with pytest.raises(ParameterError):
        s.time_scaled(0.0)


def test_invalid_sequences_are_refused():
    with pytest.raises(ParameterError, match="consecutive"):
        P.PhaseSequence([RS, RS], [0.1, 0.1])
    with pytest.raises(ParameterError, match="positive"):
        P.PhaseSequence([RS, LS], [0.1, 0.0])
    with pytest.raises(ParameterError, match="RS, LS, DS or FLIGHT"):
        P.PhaseSequence([ERR], [0.1])


@settings(deadline=None, max_examples=20)
@given(st.lists(st.booleans(), min_size=4, max_size=40), st.lists(st.booleans(), min_size=4, max_size=40),
       st.booleans())
def test_sequence_covers_the_clip_and_matches_frame_phases(left, right, cyclic):
    n = min(len(left), len(right))
    left, right = np.array(left[:n]), np.array(right[:n])
    if cyclic:
        left[-1], right[-1] = left[0], right[0]
    s = P.from_labels(left, right, 30.0, cyclic, P.PhaseConfig(0.0))
    assert s.total == pytest.approx((n - 1) / 30.0)
    assert np.all(s.phases[1:] != s.phases[:-1])
    # every frame (away from boundaries) reads back its own phase
    fr = P.frame_phases(left, right)
    t = np.arange(n) / 30.0
    got = s.phase_at(t)
    assert np.array_equal(got[:-1] if cyclic else got, fr[:-1] if cyclic else fr)


def test_builtin_clips_have_the_expected_cycles():
    from kinodyn.data import library as L

    walk = P.from_motion(L.load("walk"), cyclic=True)
    names = walk.names()
    assert walk.cyclic and set(names) == {"DS", "LS", "RS"}
    for a, b in zip(names, names[1:] + names[:1]):  # single supports alternate through double supports
        assert (a == "DS") != (b == "DS")
    run = P.from_motion(L.load("run"), cyclic=True)
    assert set(run.names()) == {"LS", "RS", "FLIGHT"}
    assert P.from_motion(L.load("jump")).names() == ["DS", "FLIGHT", "DS"]
    assert P.from_motion(L.load("idle"), cyclic=True).names() == ["DS"]


def test_left_share_passes_the_weight_over_double_supports():
    """1 on the left single support, 0 on the right one, linear over the double support between them;
    a double support between two steps of the same foot keeps that foot's share."""
    seq = P.PhaseSequence(np.array([RS, DS, LS, DS, LS], dtype=np.int8), np.array([0.4, 0.2, 0.4, 0.1, 0.3]))
    t = np.array([0.1, 0.4, 0.45, 0.5, 0.55, 0.6, 0.8, 1.05, 1.2, 5.0])
    np.testing.assert_allclose(seq.left_share(t), [0.0, 0.0, 0.25, 0.5, 0.75, 1.0, 1.0, 1.0, 1.0, 1.0], atol=1e-12)
    # ends of a non-cyclic clip: an unknown neighbour counts as one half
    ends = P.PhaseSequence(np.array([DS, RS, DS], dtype=np.int8), np.array([0.2, 0.4, 0.2]))
    np.testing.assert_allclose(ends.left_share([0.0, 0.1, 0.2, 0.7, 0.8, 3.0]), [0.5, 0.25, 0.0, 0.25, 0.5, 0.5],
                               atol=1e-12)


def test_left_share_of_a_cyclic_sequence_wraps_and_is_continuous():
    seq = P.PhaseSequence(np.array([DS, LS, DS, RS], dtype=np.int8), np.array([0.1, 0.4, 0.1, 0.4]), cyclic=True,
                          start=-0.05)
    t = np.linspace(-3.0, 3.0, 6001)
    share = seq.left_share(t)
    assert share.min() == 0.0 and share.max() == 1.0
    assert np.abs(np.diff(share)).max() < 0.011   # linear ramps of 0.1 s sampled every 1 ms
    np.testing.assert_allclose(seq.left_share(t + seq.total), share, atol=1e-9)
    assert seq.left_share(0.0) == pytest.approx(0.5)   # middle of the DS from RS to LS (it straddles 0)


def test_time_spans_merge_equal_codes_and_leave_out_invalid_frames():
    codes = np.array([RS, RS, LS, LS, LS, DS, DS], dtype=np.int8)
    begin = np.arange(7) * 0.1
    end = begin + 0.1
    assert P.time_spans(codes, begin, end) == [(0.0, begin[1] + 0.1, int(RS)), (0.2, begin[4] + 0.1, int(LS)),
                                               (0.5, begin[6] + 0.1, int(DS))]
    valid = np.array([1, 1, 1, 0, 1, 1, 1], dtype=bool)  # an invalid frame splits the LS run
    got = P.time_spans(codes, begin, end, valid)
    assert [(round(a, 9), round(b, 9), c) for a, b, c in got] == [(0.0, 0.2, int(RS)), (0.2, 0.3, int(LS)),
                                                                   (0.4, 0.5, int(LS)), (0.5, 0.7, int(DS))]
    assert P.time_spans(codes[:0], begin[:0], end[:0]) == []
    with pytest.raises(ParameterError, match="equal"):
        P.time_spans(codes, begin, end, valid[:3])


def test_every_phase_has_one_colour():
    assert set(P.PHASE_COLORS) == {int(p) for p in P.PHASES}
    assert len(set(P.PHASE_COLORS.values())) == len(P.PHASES)
