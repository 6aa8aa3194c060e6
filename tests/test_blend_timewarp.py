"""Durations of synchronized elements and time warps (sections 5.2 and 5.3)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinodyn.blend import timewarp as tw
from kinodyn.phases import DS, LS, RS, PhaseSequence
from kinodyn.blend.sync import SyncConfig, Synchronizer
from kinodyn.errors import ParameterError
from kinodyn.math import interp

_TOL = 1e-9


def test_step_durations_are_the_weighted_sum():
    spans = np.array([[0.3, 0.1], [0.2, np.nan]])
    w = np.array([[3.0, 1.0], [1.0, 5.0]])
    d = tw.step_durations(spans, w)
    assert d[0] == pytest.approx((3 * 0.3 + 1 * 0.1) / 4)
    assert d[1] == pytest.approx(0.2)  # an absent action has no say
    assert tw.step_durations([[0.3, 0.1]], [[0.0, 0.0]])[0] == pytest.approx(0.2)  # no weight: mean
    with pytest.raises(ParameterError):
        tw.step_durations([[np.nan]], [[1.0]])


def test_smooth_warp_is_catmull_rom_without_clipping():
    rng = np.random.default_rng(3)
    kt = np.cumsum(rng.uniform(0.1, 0.5, 8))
    kh = np.cumsum(rng.uniform(0.1, 0.5, 8))
    t = np.linspace(kt[0], kt[-1], 301)
    got = tw.smooth_warp(kt, kh, t, tw.WarpConfig(tension=0.0, monotone=False))
    np.testing.assert_allclose(got, interp.catmull_rom(kt, kh, t), atol=1e-12)
    # passes through the knots
    np.testing.assert_allclose(tw.smooth_warp(kt, kh, kt), kh, atol=_TOL)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.02, 1.0), min_size=3, max_size=10), st.lists(st.floats(0.01, 2.0), min_size=3, max_size=10),
       st.floats(0.0, 0.9))
def test_smooth_warp_is_monotone_and_c1(dts, dhs, tension):
    n = min(len(dts), len(dhs))
    kt = np.concatenate([[0.0], np.cumsum(dts[:n])])
    kh = np.concatenate([[0.0], np.cumsum(dhs[:n])])
    cfg = tw.WarpConfig(tension=tension)
    t = np.linspace(0.0, kt[-1], 2001)
    h = tw.smooth_warp(kt, kh, t, cfg)
    assert np.all(np.diff(h) >= -1e-9)  # action time never runs backwards
    # speed is continuous at the knots: one-sided finite differences agree
    eps = 1e-8
    for k in kt[1:-1]:
        left = (tw.smooth_warp(kt, kh, [k], cfg) - tw.smooth_warp(kt, kh, [k - eps], cfg)) / eps
        right = (tw.smooth_warp(kt, kh, [k + eps], cfg) - tw.smooth_warp(kt, kh, [k], cfg)) / eps
        assert left[0] == pytest.approx(right[0], rel=1e-3, abs=1e-3)


def test_piecewise_linear_warp_has_speed_jumps_the_spline_removes():
    kt = np.array([0.0, 0.2, 0.4, 0.6])
    kh = np.array([0.0, 0.1, 0.4, 0.5])   # slopes 0.5, 1.5, 0.5
    eps = 1e-6
    lin = tw.piecewise_linear(kt, kh, [0.2 - eps, 0.2, 0.2 + eps])
    assert (lin[2] - lin[1]) / eps == pytest.approx(1.5) and (lin[1] - lin[0]) / eps == pytest.approx(0.5)
    sm = tw.smooth_warp(kt, kh, [0.2 - eps, 0.2, 0.2 + eps])
    assert (sm[2] - sm[1]) / eps == pytest.approx((sm[1] - sm[0]) / eps, rel=1e-3)


def test_hermite_coefficients_match_the_endpoints():
    c = tw.hermite_coefficients(1.0, 1.5, 2.0, 2.4, 0.7, 1.1)
    assert tw.eval_poly(c, 0.0) == pytest.approx(2.0) and tw.eval_poly(c, 0.5) == pytest.approx(2.4)
    d = lambda u: c[1] + 2 * c[2] * u + 3 * c[3] * u * u
    assert d(0.0) == pytest.approx(0.7) and d(0.5) == pytest.approx(1.1)


def _planner(weights):
    sync = Synchronizer(SyncConfig(nk=3, phase_match=False))
    planner = tw.WarpPlanner(sync, lambda t: weights)
    return sync, planner


def test_planner_times_steps_with_equation_6_and_the_hold_split():
    sync, planner = _planner({"a": 1.0, "b": 3.0})
    a = PhaseSequence([RS, DS, LS, DS], [0.4, 0.1, 0.4, 0.1], cyclic=True)
    b = PhaseSequence([RS, DS, LS, DS], [0.2, 0.05, 0.2, 0.05], cyclic=True)
    sync.request("a", a)
    planner.start(0.0)
    sync.request("b", b)
    sync.enter_next()
    planner.enter()
    k = sync.current
    ta = next(t for t in sync.tracks if t.key == "a")
    tb = next(t for t in sync.tracks if t.key == "b")
    for s in range(k, sync.frontier):
        sa = planner.timing["a"].knots[s + 1] - planner.timing["a"].knots[s]
        sb = planner.timing["b"].knots[s + 1] - planner.timing["b"].knots[s]
        # each action spends its element's duration (divided among held steps) ...
        if ta.elems.count(ta.elem(s)) == 1:
            assert sa == pytest.approx(a.durations[ta.elem(s) % 4])
        # ... and the step lasts the weighted mean (equation 6), clipped so both play at 0.5x to 2x
        d = planner.T[s + 1] - planner.T[s]
        assert d == pytest.approx(tw.bounded_duration((1 * sa + 3 * sb) / 4, [sa, sb], 0.5, 2.0))
        if max(sa, sb) <= 4.0 * min(sa, sb):   # a duration exists that plays both within the bounds
            assert 0.5 - 1e-9 <= sa / d <= 2.0 + 1e-9 and 0.5 - 1e-9 <= sb / d <= 2.0 + 1e-9
    # the segment being played is frozen, C1 with the previous one
    seg = planner.segment("a")
    assert seg.t0 == pytest.approx(planner.T[k]) and seg.t1 == pytest.approx(planner.T[k + 1])
    assert tw.eval_poly(np.array(seg.coef), seg.t1 - seg.t0) == pytest.approx(planner.timing["a"].knots[k + 1])
    assert tb.first == k


def test_played_warp_is_continuous_in_value_and_speed():
    """Across a real mix (built-in walk then run), consecutive frozen segments join with equal value and
    equal speed, except where a changed plan forced a tangent to be clipped (reported, rare)."""
    from kinodyn.blend.demo import transition_script
    from kinodyn.blend.script import run_script

    r = run_script(transition_script())
    timing = r.timing
    jumps = total = 0
    for key, tm in timing.items():
        segs = tm.segments
        for s0, s1 in itertools.pairwise(segs):
            if abs(s0.t1 - s1.t0) > 1e-9:
                continue
            u = s0.t1 - s0.t0
            c = s0.coef
            v0 = tw.eval_poly(np.array(c), u)
            d0 = c[1] + 2 * c[2] * u + 3 * c[3] * u * u
            assert v0 == pytest.approx(s1.coef[0], abs=1e-9), key   # the action never jumps in time
            total += 1
            jumps += abs(d0 - s1.coef[1]) > 1e-6
    assert total > 50
    assert jumps <= 0.05 * total


def test_step_durations_keep_every_action_within_half_to_twice_its_speed():
    """Equation 6 alone plays a 0.55 s stance and a 0.13 s stance (a walk and a run) at 1.6x and 0.36x;
    the bounded duration keeps both within 0.5x-2x where one exists, and misses both bounds by the same
    factor where none does."""
    d = (0.55 + 0.13) / 2
    assert 0.13 / d < 0.5                                    # the unbounded mean
    b = tw.bounded_duration(d, [0.55, 0.30], 0.5, 2.0)
    assert 0.5 <= 0.55 / b <= 2.0 and 0.5 <= 0.30 / b <= 2.0
    g = tw.bounded_duration(d, [0.55, 0.10], 0.5, 2.0)       # 5.5x apart: no duration fits both
    assert (0.55 / g) / 2.0 == pytest.approx(0.5 / (0.10 / g))
    assert tw.bounded_duration(0.3, [0.3, 0.4], 0.5, 2.0) == 0.3   # within the bounds: unchanged


def test_weighted_tempo_keeps_the_heavier_action_within_its_bounds():
    """A 0.73 s walk stance and a 0.13 s run stance cannot both play within 0.5x-2x. By default both miss
    by the same factor; with ``by_weight`` the heavier action keeps its bounds (the lighter one misses
    them), an action under TEMPO_WEIGHT of the heaviest does not bound the step, and two actions of the
    top weight that cannot agree fall back to the geometric middle."""
    spans = [0.73, 0.13]
    g = tw.bounded_duration(0.3, spans, 0.5, 2.0, [0.6, 0.4])
    assert not 0.5 <= 0.13 / g <= 2.0 and not 0.5 <= 0.73 / g <= 2.0
    heavy_run = tw.bounded_duration(0.3, spans, 0.5, 2.0, [0.4, 0.6], by_weight=True)
    assert 0.5 <= 0.13 / heavy_run <= 2.0
    heavy_walk = tw.bounded_duration(0.3, spans, 0.5, 2.0, [0.6, 0.4], by_weight=True)
    assert 0.5 <= 0.73 / heavy_walk <= 2.0
    gone = tw.bounded_duration(0.13, spans, 0.5, 2.0, [0.01, 1.0], by_weight=True)
    assert gone == pytest.approx(0.13)                       # the nearly gone walk has no say
    assert tw.bounded_duration(0.13, spans, 0.5, 2.0, [0.03, 1.0], by_weight=True) > 0.13 / 2.0 - _TOL
    tie = tw.bounded_duration(0.3, spans, 0.5, 2.0, [0.5, 0.5], by_weight=True)
    assert tie == pytest.approx(g)
    assert tw.bounded_duration(0.3, [0.3, 0.4], 0.5, 2.0, [1.0, 0.2], by_weight=True) == 0.3
    with pytest.raises(ParameterError):
        tw.WarpConfig(tempo="fastest")


@given(st.floats(0.0, 3.0), st.floats(0.0, 3.0), st.floats(0.3, 2.5))
@settings(max_examples=200, deadline=None)
def test_bounded_tangents_keep_the_speed_within_the_rates(m0, m1, sec):
    """The Hermite segment's speed is a quadratic Bezier of m0, 3 sec - m0 - m1, m1: with the tangents
    of bounded_tangents it stays within [0.5, 2] (widened to the secant) wherever the frozen start speed
    allows, and the start speed is never changed (the played speed stays continuous)."""
    lo, hi = min(0.5, sec), max(2.0, sec)
    b0, b1 = tw.bounded_tangents(m0, m1, sec, 0.5, 2.0)
    assert b0 == pytest.approx(min(max(m0, 0.0), 3.0 * sec))
    s = np.linspace(0.0, 1.0, 101)
    speed = b0 * (1 - s) ** 2 + 2 * (3 * sec - b0 - b1) * s * (1 - s) + b1 * s * s
    if lo <= b0 <= hi and max(lo, 3 * sec - b0 - hi) <= min(hi, 3 * sec - b0 - lo):   # an end tangent exists
        assert speed.min() >= lo - 1e-9 and speed.max() <= hi + 1e-9
    c = tw.hermite_coefficients(0.0, 1.0, 0.0, sec, b0, b1)
    np.testing.assert_allclose(c[1] + 2 * c[2] * s + 3 * c[3] * s * s, speed, atol=1e-9)


def _walk_into_run(tempo_hold: float, steps: int = 14):
    """A slow walk cycle (0.7 s single supports) joined by a run (0.15 s supports, 0.2 s flights), timed
    by the planner: ``[(step, {key: (element, action time spent, step duration)}), ...]`` of the steps
    played, and the synchronizer's nominal durations."""
    from kinodyn.phases import FLIGHT

    walk = PhaseSequence([DS, LS, DS, RS], [0.1, 0.7, 0.1, 0.7], cyclic=True)
    run = PhaseSequence([LS, FLIGHT, RS, FLIGHT], [0.15, 0.2, 0.15, 0.2], cyclic=True)
    sync = Synchronizer(SyncConfig(nk=5, tempo_hold=tempo_hold))
    planner = tw.WarpPlanner(sync, lambda t: {"walk": 1.0, "run": 1.0})
    sync.request("walk", walk, 1)
    planner.start(0.0)
    sync.request("run", run, 1)
    played, nominal = [], {}
    for _ in range(steps):
        sync.enter_next()
        planner.enter()
        k = sync.current
        d = planner.T[k + 1] - planner.T[k]
        row = {}
        for t in sync.tracks:
            kn = planner.timing[t.key].knots
            if t.elem(k) is not None and k + 1 in kn:
                row[t.key] = (t.elem(k), kn[k + 1] - kn[k], d)
        played.append((k, row))
        nominal[k] = sync.nominal[k]
    return played, nominal


@pytest.mark.parametrize("tempo_hold", [2.5, 0.0])
def test_tempo_holds_keep_a_slow_and_a_fast_cycle_within_half_to_twice_their_speed(tempo_hold):
    """A 0.7 s single support cannot share one step with a 0.15 s one at 0.5x-2x of both speeds (no
    duration fits both); tempo holds spread the walk's single support over the run's support and flight,
    and every step then plays both within the bounds. Without them (``tempo_hold=0``) some step cannot."""
    played, _ = _walk_into_run(tempo_hold)
    rates = [sp / d for _, row in played if len(row) == 2 for _, sp, d in row.values()]
    assert len(rates) >= 16
    inside = all(0.5 - _TOL <= r <= 2.0 + _TOL for r in rates)
    assert inside == (tempo_hold > 0), (min(rates), max(rates))


def test_a_held_element_is_split_by_the_nominal_durations_of_its_steps():
    """The walk's single support held over several steps spends its time in them in proportion to their
    nominal durations (one speed through them), not in equal shares."""
    played, nominal = _walk_into_run(2.5)
    runs = {}
    for k, row in played:
        if "walk" in row and len(row) == 2:
            e, sp, _ = row["walk"]
            runs.setdefault(e, []).append(sp / nominal[k])
    held = [r for e, r in runs.items() if len(r) >= 2]
    assert held, runs
    for r in held:
        np.testing.assert_allclose(r, r[0], rtol=1e-9)
