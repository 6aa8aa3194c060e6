"""Chronological organization of support phases (section 5.1) and the guarantee of appendix A."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from kinodyn.phases import DS, ERR, FLIGHT, LS, RS, PhaseSequence, combine_all
from kinodyn.blend.holds import appendix_set, brute_force_holds, resolve, step_phase
from kinodyn.blend.sync import SyncConfig, Synchronizer
from kinodyn.errors import ParameterError

SUPPORT = [int(RS), int(LS), int(DS), int(FLIGHT)]


def _cases(max_n=4):
    for n in range(1, max_n + 1):
        for old in itertools.product(SUPPORT, repeat=n):
            if combine_all(list(old)) == ERR:
                continue
            for nxt in itertools.product(SUPPORT, repeat=n):
                yield old, nxt


def test_resolution_always_exists_and_progresses_exhaustively():
    """Every valid previous step and every candidate step (up to 4 actions, every priority order):
    the chosen holds give a step without ERR, at least one action advances, and brute force agrees
    that a solution exists (appendix A)."""
    count = 0
    for old, nxt in _cases(3):
        brute = brute_force_holds(old, nxt)
        assert brute, (old, nxt)  # appendix A: a solution always exists
        for prio in itertools.permutations(range(len(old))):
            r = resolve(old, nxt, prio)
            assert r.phase != ERR and len(r.held) < len(old)
            assert r.phase == step_phase(old, nxt, set(r.held))
            assert tuple(sorted(r.held)) in brute
            count += 1
    assert count > 10_000


def test_appendix_set_is_never_empty_and_synchronizes():
    for old, nxt in _cases(4):
        if combine_all(list(nxt)) != ERR:
            continue
        keep = appendix_set(old, nxt)
        assert keep, (old, nxt)
        assert step_phase(old, nxt, set(range(len(old))) - keep) != ERR


def test_highest_priority_constraint_is_kept_when_the_previous_step_allows_it():
    """Section 5.1: from the highest priority down, the first candidate RS or LS gives the constraint;
    every action whose candidate is the other single support holds its element."""
    for old, nxt in _cases(4):
        prev = combine_all(list(old))
        if combine_all(list(nxt)) != ERR or prev not in (DS, FLIGHT):
            continue
        for prio in itertools.permutations(range(len(old))):
            top = max((i for i in range(len(old)) if nxt[i] in (RS, LS)), key=lambda i: prio[i])
            r = resolve(old, nxt, prio)
            if prev == DS:
                assert r.rule == "priority" and r.constraint == nxt[top]
                assert top not in r.held and r.phase == nxt[top]
                assert set(r.held) == {i for i in range(len(old)) if nxt[i] == (LS if nxt[top] == RS else RS)}
            else:  # after a flight the constraint holds unless a held flight element is needed
                assert r.phase in (nxt[top], FLIGHT, LS if nxt[top] == RS else RS)


def test_figure_8_the_double_support_is_enlarged():
    """Figure 8: S1(k+1) = DS, S1(k+2) = RS; S2(k+1) = FLIGHT, S2(k+2) = LS. Deleting or shortening does
    not help; enlarging S1(k+1) does."""
    r = resolve([DS, FLIGHT], [RS, LS], [0, 1])
    assert r.held == (0,) and r.phase == LS and r.constraint == LS
    # the same situation in a running synchronizer with nk = 1
    s1 = PhaseSequence([LS, DS, RS], [0.2, 0.2, 0.3])
    s2 = PhaseSequence([FLIGHT, LS], [0.2, 0.3])
    sync = Synchronizer(SyncConfig(nk=1, phase_match=False))
    sync.request("A1", s1, priority=0)
    sync.request("A2", s2, priority=1)   # tried when the next step is entered
    sync.enter_next()
    t1 = next(t for t in sync.tracks if t.key == "A1")
    t2 = next(t for t in sync.tracks if t.key == "A2")
    k = t2.first
    assert t1.code(t1.elem(k)) == DS and t2.code(t2.elem(k)) == FLIGHT
    assert t1.elem(k + 1) == t1.elem(k) and t2.code(t2.elem(k + 1)) == LS  # A1's DS is enlarged
    assert sync.phase(k + 1) == LS
    assert any(e.kind == "hold" and e.key == ("A1",) for e in sync.events)


def _script_sync(data):
    """Random action sets, start steps, stops and priorities driven through a synchronizer."""
    nk = data.draw(st.integers(1, 6))
    sync = Synchronizer(SyncConfig(nk=nk, max_start_delay=data.draw(st.integers(0, 4))))
    live = []
    n_actions = data.draw(st.integers(1, 6))
    requests = sorted(data.draw(st.lists(st.integers(0, 30), min_size=n_actions, max_size=n_actions)))
    stops = {}
    for i in range(n_actions):
        k = data.draw(st.integers(1, 6))
        ph = [data.draw(st.sampled_from(SUPPORT))]
        for _ in range(k - 1):
            ph.append(data.draw(st.sampled_from([c for c in SUPPORT if c != ph[-1]])))
        cyclic = data.draw(st.booleans()) and k > 1 and ph[0] != ph[-1]
        seq = PhaseSequence(ph, data.draw(st.lists(st.floats(0.05, 1.0), min_size=k, max_size=k)), cyclic)
        stops[i] = requests[i] + data.draw(st.integers(1, 40))
        live.append((requests[i], i, seq, data.draw(st.integers(0, 3))))
    return sync, live, stops


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_random_actions_always_synchronized(data):
    """Property: for random action sets, start times, stops and priorities the synchronizer always finds
    a solution: every synchronized step is free of ERR, the plan matches the tracks, elements advance by
    0 or 1 per step, and at every resolved conflict the highest-priority candidate single support
    allowed by the previous step is the constraint kept."""
    import kinodyn.blend.sync as sync_module

    sync, reqs, stops = _script_sync(data)
    calls = []

    def recording(old, nxt, priorities):
        res = real_resolve(old, nxt, priorities)
        calls.append((list(old), list(nxt), list(priorities), res))
        return res

    real_resolve, sync_module.resolve = sync_module.resolve, recording
    try:
        _drive(sync, reqs, stops)
    finally:
        sync_module.resolve = real_resolve
    for step, res, keys in sync.resolutions:
        assert res.phase != ERR and len(res.held) < len(keys)
    for old, nxt, prio, res in calls:
        _assert_kept_constraint(old, nxt, prio, res)


def _or(codes) -> int:
    out = 0
    for c in codes:
        out |= c
    return out


def _assert_kept_constraint(old, nxt, prio, res):
    """The single support kept at a conflict is the highest-priority candidate allowed by the previous
    step (ties in input order); the other one is kept only when keeping that one cannot work."""
    if res.rule == "free":
        assert _or(nxt) != ERR and res.held == ()
        return
    prev = _or(old)
    order = sorted(range(len(nxt)), key=lambda i: -prio[i])
    kept = next(nxt[i] for i in order if nxt[i] in (RS, LS) and (nxt[i] | prev) != ERR)
    if res.rule == "priority":
        assert res.constraint == kept, (old, nxt, prio, res)
    if res.rule == "other":
        assert res.constraint == (RS if kept == LS else LS), (old, nxt, prio, res)
        opposite = RS if kept == LS else LS
        held = [i for i in range(len(nxt)) if nxt[i] == opposite]
        tried = _or(old[i] if i in held else nxt[i] for i in range(len(nxt)))
        assert tried == ERR or len(held) == len(nxt), (old, nxt, prio, res)  # keeping `kept` failed
    if res.constraint is not None:
        advancing = [nxt[i] for i in range(len(nxt)) if i not in res.held]
        assert (RS if res.constraint == LS else LS) not in advancing, (old, nxt, prio, res)


def _drive(sync, reqs, stops):
    started = set()
    for step in range(80):
        for r in reqs:
            if r[0] == step and r[1] not in started:
                sync.request(r[1], r[2], r[3])
                started.add(r[1])
        for key, s in stops.items():
            if s == step and key in started:
                try:
                    sync.remove(key)
                except ParameterError:
                    pass
        if sync.idle and not sync.pending:
            continue
        sync.enter_next()
        for s in range(sync.current, sync.frontier + 1):
            ph = [t.code(t.elem(s)) for t in sync.tracks if t.elem(s) is not None]
            assert combine_all(ph) != ERR if ph else True
            assert (combine_all(ph) if ph else DS) == sync.phase(s)
        for t in sync.tracks:
            d = np.diff(t.elems)
            assert np.all((d == 0) | (d == 1))


def test_new_action_waits_for_a_compatible_step():
    walk = PhaseSequence([RS, DS, LS, DS], [0.3, 0.1, 0.3, 0.1], cyclic=True)
    hop = PhaseSequence([LS, DS], [0.2, 0.2])  # a left hop, then stands
    sync = Synchronizer(SyncConfig(nk=2, phase_match=False))
    sync.request("walk", walk, 1)
    assert sync.tracks[0].first == sync.current
    sync.request("hop", hop, 1)
    waited = 0
    while sync.pending:
        sync.enter_next()
        waited += 1
        assert waited < 10
    hop_track = next(t for t in sync.tracks if t.key == "hop")
    # it starts where its LS meets the walk's LS or a double support, never the walk's RS
    k = hop_track.first
    walk_track = next(t for t in sync.tracks if t.key == "walk")
    assert walk_track.code(walk_track.elem(k)) in (LS, DS)
    kinds = [e.kind for e in sync.events if e.key == "hop"]
    assert kinds[-1] == "start"


def test_forced_start_joins_through_the_hold_rule():
    """An action whose first elements never fit directly joins at the frontier after max_start_delay."""
    alternate = PhaseSequence([RS, LS], [0.3, 0.3], cyclic=True)
    stand_left = PhaseSequence([LS], [0.3])   # LS, LS, LS ... never fits the alternation directly
    sync = Synchronizer(SyncConfig(nk=3, max_start_delay=2, phase_match=False))
    sync.request("a", alternate, 0)
    sync.request("b", stand_left, 5)
    for _ in range(12):
        sync.enter_next()
        for s in range(sync.current, sync.frontier + 1):
            assert sync.phase(s) != ERR
    kinds = [e.kind for e in sync.events if e.key == "b"]
    assert kinds == ["wait", "wait", "force", "start"]
    # the higher-priority stance is then kept: the alternation holds its LS
    a = next(t for t in sync.tracks if t.key == "a")
    assert all(a.code(a.elem(s)) == LS for s in range(sync.current, sync.frontier + 1))


def test_phase_match_starts_a_cycle_on_the_matching_support():
    walk = PhaseSequence([DS, LS, DS, RS], [0.1, 0.3, 0.1, 0.3], cyclic=True)
    run = PhaseSequence([RS, FLIGHT, LS, FLIGHT], [0.2, 0.1, 0.2, 0.1], cyclic=True)
    sync = Synchronizer(SyncConfig(nk=5))
    sync.request("walk", walk, 1)
    sync.request("run", run, 1)
    sync.enter_next()
    run_t = next(t for t in sync.tracks if t.key == "run")
    walk_t = next(t for t in sync.tracks if t.key == "walk")
    for s in range(run_t.first, sync.frontier + 1):
        a, b = walk_t.code(walk_t.elem(s)), run_t.code(run_t.elem(s))
        # single supports meet the same single support; double supports meet flights
        assert (a == b) or ({a, b} <= {DS, FLIGHT}), (s, a, b)


def test_removal_behind_a_flight_is_put_off():
    """FLIGHT absorbs conflicts: removing the jumping action may not reveal an RS meeting an LS."""
    sync = Synchronizer(SyncConfig(nk=3, phase_match=False))
    sync.request("jump", PhaseSequence([FLIGHT], [1.0]), 5)
    sync.request("r", PhaseSequence([RS], [0.2]), 0)
    sync.request("l", PhaseSequence([LS], [0.2]), 0)
    for _ in range(3):
        sync.enter_next()
    assert {t.key for t in sync.tracks} == {"jump", "r", "l"}
    sync.remove("jump")
    for _ in range(6):
        sync.enter_next()
        for s in range(sync.current, sync.frontier + 1):
            assert sync.phase(s) != ERR


def test_errors_name_the_problem():
    with pytest.raises(ParameterError, match="nk must be"):
        SyncConfig(nk=0)
    for bad in (0.5, -1.0, float("inf"), float("nan")):
        with pytest.raises(ParameterError, match="tempo_hold must be"):
            SyncConfig(tempo_hold=bad)
    with pytest.raises(ParameterError, match="equal lengths"):
        resolve([DS], [RS, LS], [0, 1])
    with pytest.raises(ParameterError, match="combines to ERR"):
        resolve([RS, LS], [DS, DS], [0, 1])
    sync = Synchronizer()
    sync.request("a", PhaseSequence([DS], [1.0]))
    with pytest.raises(ParameterError, match="already known"):
        sync.request("a", PhaseSequence([DS], [1.0]))
    with pytest.raises(ParameterError, match="no action"):
        sync.remove("zzz")


def test_a_start_waits_for_its_not_before_step():
    walk = PhaseSequence([RS, DS, LS, DS], [0.3, 0.1, 0.3, 0.1], cyclic=True)
    stand = PhaseSequence([DS, RS, DS], [0.5, 0.5, 0.5])
    sync = Synchronizer(SyncConfig(nk=3))
    sync.request("walk", walk, 1)
    sync.request("kick", stand, 2, not_before=sync.current + 3)
    for _ in range(4):
        sync.enter_next()
    kick = next(t for t in sync.tracks + sync.pending if t.key == "kick")
    assert kick.first == kick.not_before and not [e for e in sync.events if e.kind == "wait"]


def test_split_holds_a_lone_element_into_a_new_step_and_keeps_the_frontier():
    """A lone action's long element is cut at once: the current step ends, the element is held into
    the next one (its later elements move one step on), the frontier stays where it was."""
    kick = PhaseSequence([DS, RS, DS], [0.5, 0.8, 0.7])
    sync = Synchronizer(SyncConfig(nk=3))
    sync.request("kick", kick, 2)
    t = sync.tracks[0]
    k, front, elems = sync.current, sync.frontier, list(t.elems)
    assert sync.split(0.2)
    assert sync.frontier == front and t.elems == [elems[0]] + elems[:-1]
    assert [sync.phase(s) for s in range(k, front + 1)] == [t.code(e) for e in t.elems]
    assert sync.nominal[k] == 0.2 and sync.nominal[k + 1] == pytest.approx(0.3)
    sync.request("walk", PhaseSequence([RS, DS, LS, DS], [0.3, 0.1, 0.3, 0.1], cyclic=True), 1)
    sync.enter_next()
    assert len(sync.tracks) == 2 and not sync.split(0.1)  # only a lone action is split
