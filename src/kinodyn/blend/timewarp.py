"""Durations of the synchronized elements and the time warp of each action (sections 5.2 and 5.3).

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization. Once the elements are organized
(:mod:`kinodyn.blend.sync`), step ``s`` lasts ``D(s) = sum_i P_i D_i(s)`` (equation 6): the
priority-weighted sum of what each action would spend there, with ``P_i`` the action's weight on the
legs (its priority-resolved blend weight, normalized over the actions in the step). An element held
over several steps spends its own duration in them in proportion to the steps' nominal durations
(the synchronizer's; ``1/m`` of it in each of ``m`` steps where they are unknown), so it plays at one
speed through them. Action ``i`` then plays its element of step
``s`` during ``[T_s, T_s + D(s))``: the time warp ``t' = H_i(t)`` maps real time to the action's time
through the knots ``(T_s, h_i(s))``. ``H_i`` is piecewise linear and its slope (the action's speed)
jumps at every knot, so it is replaced by a cardinal spline through the same knots (figure 10), a
cubic Hermite curve with tangents ``(1 - c) (h_{s+1} - h_{s-1}) / (T_{s+1} - T_{s-1})`` (``c`` the
tension; ``c = 0`` is Catmull-Rom), clipped to ``[0, 3 min(secants)]`` so the warp never runs
backwards (Fritsch-Carlson). The spline passes through the knots, so every action is inside the
right element at every instant, and its speed is continuous.

In real time the future knots move (new actions, stops, enlarged elements): :class:`WarpPlanner`
freezes the segment being played, and the tangent at its end, when a step is entered, so the curve
actually played is C1 even though later knots change.

Units: seconds of real time (``t``, ``T``) and of action time (``h``).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from kinodyn.errors import ParameterError

#: Share of the heaviest action's leg weight under which an action does not bound a step's duration.
TEMPO_WEIGHT = 0.02

__all__ = [
    "Segment",
    "WarpConfig",
    "WarpPlanner",
    "bounded_duration",
    "bounded_tangents",
    "cardinal_tangents",
    "eval_poly",
    "hermite_coefficients",
    "piecewise_linear",
    "smooth_warp",
    "step_durations",
]


@dataclass(frozen=True)
class WarpConfig:
    """Time-warp parameters.

    Attributes:
        tension: cardinal-spline tension ``c`` in ``[0, 1)``; 0 is Catmull-Rom.
        monotone: clip tangents so the warp never decreases (action time never runs backwards), and
            keep each knot's tangent between the speeds of the two segments it joins.
        min_rate, max_rate: bounds on every action's speed (action time per second): a step lasts the
            duration of equation 6 clipped so that each action present plays its span within them
            (where the spans differ too much for both bounds, the geometric middle of the two limits).
        tempo: which actions bound a step's duration (:func:`bounded_duration`): ``"all"`` (every
            action present) or ``"weighted"`` (by decreasing leg weight, as far as they agree; an
            action under 2 % of the heaviest's weight does not count).
        bounded_speed: keep the speed within ``[min_rate, max_rate]`` inside every segment too, not
            only on average over each step (:func:`bounded_tangents`; the cubic otherwise dips and
            overshoots between its knots).
    """

    tension: float = 0.0
    monotone: bool = True
    min_rate: float = 0.5
    max_rate: float = 2.0
    tempo: str = "all"
    bounded_speed: bool = False

    def __post_init__(self):
        if self.tempo not in ("all", "weighted"):
            raise ParameterError(f"tempo must be 'all' or 'weighted', got {self.tempo!r}")
        if not (np.isfinite(self.tension) and 0.0 <= self.tension < 1.0):
            raise ParameterError(f"tension must be in [0, 1), got {self.tension}")
        if not (0.0 < self.min_rate <= 1.0 <= self.max_rate and np.isfinite(self.max_rate)):
            raise ParameterError(f"rates must satisfy 0 < min_rate <= 1 <= max_rate < inf, got "
                                 f"{self.min_rate} and {self.max_rate}")


def step_durations(spans, weights) -> np.ndarray:
    """Equation 6: ``D(s) = sum_i P_i D_i(s)`` with ``P`` normalized over the actions of each step.

    Args:
        spans: ``(S, n)`` action time each action spends in each step (NaN where absent).
        weights: ``(S, n)`` non-negative weights (priority-resolved blend weights).

    Returns:
        ``(S,)`` step durations in seconds. A step where every present action has zero weight takes
        the plain mean of the spans.
    """
    d = np.asarray(spans, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    if d.shape != w.shape or d.ndim != 2:
        raise ParameterError(f"spans and weights must be equal (S, n) arrays, got {d.shape} and {w.shape}")
    present = np.isfinite(d)
    if np.any(~present.any(axis=1)):
        raise ParameterError("every step needs at least one action")
    w = np.where(present, np.maximum(w, 0.0), 0.0)
    d0 = np.where(present, d, 0.0)
    sw = w.sum(axis=1)
    mean = d0.sum(axis=1) / present.sum(axis=1)
    return np.where(sw > 0, (w * d0).sum(axis=1) / np.where(sw > 0, sw, 1.0), mean)


def bounded_duration(d: float, spans, min_rate: float, max_rate: float, weights=None,
                     by_weight: bool = False) -> float:
    """Step duration ``d`` clipped so that the spans of ``spans`` (action time each action spends in the
    step) play at rates within ``[min_rate, max_rate]``.

    Default: every span bounds the step; where no duration fits them all, the geometric middle of the
    two limits (both bounds missed by the same factor); ``weights`` do not change the bounds.

    ``by_weight``: the actions are taken by decreasing leg weight (``weights``; default all equal), each
    narrowing the range of durations its span allows, until one whose range no longer meets the
    heavier ones' (spans that differ too much for both bounds): that one and the lighter ones play out
    of their bounds, the heavier ones keep theirs. Actions under :data:`TEMPO_WEIGHT` of the heaviest
    do not bound the step (a fading action no longer sets the tempo). Where two actions of the top
    weight cannot agree, the geometric middle of their limits.
    """
    w = [1.0] * len(spans) if weights is None else list(weights)
    if not by_weight:
        group = [x for x in spans if x > 0]
        if not group:
            return d
        lo, hi = max(group) / max_rate, min(group) / min_rate
        return min(max(d, lo), hi) if lo <= hi else math.sqrt(lo * hi)
    pairs = sorted(((wi, x) for x, wi in zip(spans, w) if x > 0), key=lambda p: -p[0])
    if not pairs:
        return d
    top = pairs[0][0]
    lo, hi = -math.inf, math.inf
    for wi, x in pairs:
        if wi < TEMPO_WEIGHT * top and lo > -math.inf:
            break
        a, b = x / max_rate, x / min_rate
        if max(lo, a) > min(hi, b):
            if wi >= top:  # two actions of the top weight that cannot agree
                return math.sqrt(max(lo, a) * min(hi, b))
            break
        lo, hi = max(lo, a), min(hi, b)
    return min(max(d, lo), hi)


def bounded_tangents(m0: float, m1: float, sec: float, lo: float, hi: float) -> tuple[float, float]:
    """End tangents of a cubic Hermite segment of secant ``sec`` whose speed stays within ``[lo, hi]``
    (widened to include ``sec``).

    The speed along the segment is a quadratic Bezier curve with control values ``m0``,
    ``3 sec - m0 - m1`` and ``m1``, so it stays within the bounds when all three do. Only ``m1`` moves:
    the speed at the segment's start, frozen by the previous segment, stays continuous (a jump in an
    action's speed is a jump in the root's velocity); where no ``m1`` is enough, the closest one.
    """
    lo, hi = min(lo, sec), max(hi, sec)
    m0 = min(max(m0, 0.0), 3.0 * sec)
    a, b = max(lo, 3.0 * sec - m0 - hi), min(hi, 3.0 * sec - m0 - lo)
    if a <= b:
        return m0, min(max(m1, a), b)
    # no end tangent is enough: the one closest to it, within the bounds
    return m0, min(max(a if 3.0 * sec - m0 - hi > hi else b, lo), hi)


def _limit(m, left, right):
    """Clip tangents to ``[0, 3 min(left, right)]`` (monotone cubic Hermite)."""
    lim = 3.0 * np.minimum(left, right)
    return np.clip(m, 0.0, np.maximum(lim, 0.0))


def cardinal_tangents(t, h, tension: float = 0.0, monotone: bool = True) -> np.ndarray:
    """Tangents of the cardinal spline through knots ``(t (K,), h (K,))``; one-sided at the ends."""
    t = np.asarray(t, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    if t.ndim != 1 or t.shape != h.shape or len(t) < 2:
        raise ParameterError(f"knots must be equal (K,) arrays with K >= 2, got {t.shape} and {h.shape}")
    if np.any(np.diff(t) <= 0):
        raise ParameterError("knot times must be strictly increasing")
    sec = np.diff(h) / np.diff(t)
    m = np.empty_like(t)
    m[1:-1] = (1.0 - tension) * (h[2:] - h[:-2]) / (t[2:] - t[:-2])
    m[0] = sec[0]
    m[-1] = sec[-1]
    if monotone:
        m[1:-1] = _limit(m[1:-1], sec[:-1], sec[1:])
        m[0] = max(sec[0], 0.0)
        m[-1] = max(sec[-1], 0.0)
    return m


def hermite_coefficients(t0: float, t1: float, h0: float, h1: float, m0: float, m1: float) -> np.ndarray:
    """``(4,)`` polynomial coefficients ``c`` of the cubic Hermite segment, ``h(u) = sum c_j u^j``,
    ``u = t - t0`` in ``[0, t1 - t0]``."""
    dt = t1 - t0
    if not dt > 0:
        raise ParameterError(f"a segment needs t1 > t0, got {t0} and {t1}")
    dh = h1 - h0
    c2 = (3.0 * dh / dt - 2.0 * m0 - m1) / dt
    c3 = (m0 + m1 - 2.0 * dh / dt) / (dt * dt)
    return np.array([h0, m0, c2, c3])


def eval_poly(c, u) -> np.ndarray:
    """Evaluate cubic coefficients ``c (..., 4)`` at ``u (...)`` (Horner)."""
    c = np.asarray(c, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    return ((c[..., 3] * u + c[..., 2]) * u + c[..., 1]) * u + c[..., 0]


def piecewise_linear(knot_t, knot_h, times) -> np.ndarray:
    """The unsmoothed warp ``H(t)``: linear between knots ``(knot_t (K,), knot_h (K,))`` at ``times (T,)``."""
    return np.interp(np.asarray(times, dtype=np.float64), knot_t, knot_h)


def smooth_warp(knot_t, knot_h, times, config: WarpConfig = WarpConfig()) -> np.ndarray:
    """The cardinal-spline warp through the knots at ``times (T,)`` (figure 10's dashed curve).

    With ``tension=0`` and no tangent clipping this is :func:`kinodyn.math.interp.catmull_rom`.
    """
    kt = np.asarray(knot_t, dtype=np.float64)
    kh = np.asarray(knot_h, dtype=np.float64)
    m = cardinal_tangents(kt, kh, config.tension, config.monotone)
    t = np.clip(np.asarray(times, dtype=np.float64), kt[0], kt[-1])
    i = np.clip(np.searchsorted(kt, t, side="right") - 1, 0, len(kt) - 2)
    dt = kt[i + 1] - kt[i]
    dh = kh[i + 1] - kh[i]
    c2 = (3.0 * dh / dt - 2.0 * m[i] - m[i + 1]) / dt
    c3 = (m[i] + m[i + 1] - 2.0 * dh / dt) / (dt * dt)
    u = t - kt[i]
    return ((c3 * u + c2) * u + m[i]) * u + kh[i]


# ----------------------------------------------------------------------------------------- planner


class Segment(NamedTuple):
    """The frozen piece of one action's warp being played: ``h(t) = eval_poly(coef, t - t0)`` on
    ``[t0, t1]``."""

    t0: float
    t1: float
    coef: tuple[float, float, float, float]


@dataclass
class _TrackTiming:
    knots: dict[int, float] = field(default_factory=dict)   # step -> action time at T[step]
    tangent: dict[int, float] = field(default_factory=dict)  # frozen tangents
    history: list[tuple[float, float]] = field(default_factory=list)  # played knots (T, h)
    segments: list[Segment] = field(default_factory=list)
    current: Segment | None = None


class WarpPlanner:
    """Step boundaries and per-action warps of one character, driven by a
    :class:`~kinodyn.blend.sync.Synchronizer` (mutable real-time state).

    Args:
        sync: the synchronizer whose plan is timed.
        weights_at: ``f(t) -> {key: weight}``: the leg weights ``P_i`` of the actions at real time ``t``.
            When it is a bound method whose object has ``weights_valid_until`` (set by the call), the
            weights are reused for later steps that begin before that time.
        config: :class:`WarpConfig`.
        keep_history: record played knots and segments (for figure 10).
    """

    def __init__(self, sync, weights_at, config: WarpConfig = WarpConfig(), keep_history: bool = True):
        self.sync = sync
        self.weights_at = weights_at
        self.config = config
        self.T: dict[int, float] = {}
        self.timing: dict[object, _TrackTiming] = {}
        self.timing_history: dict[object, _TrackTiming] = {}  # every action's timing, kept after it ends
        self.keep_history = keep_history

    # ------------------------------------------------------------------ planning
    def _share(self, tr, step: int, frozen_from: int, knots: dict) -> float:
        """Action time that track ``tr`` spends in ``step`` (the hold split of an enlarged element): its
        element's time (what is left of it after the frozen steps) split over the steps it is held in,
        in proportion to their nominal durations (:attr:`~kinodyn.blend.sync.Synchronizer.nominal`;
        equal shares where a step has none), so it plays at one speed through them."""
        elems = tr.elems
        j = step - tr.first
        e = elems[j]
        a = j
        while a > 0 and elems[a - 1] == e:
            a -= 1
        b = j
        n = len(elems)
        while b + 1 < n and elems[b + 1] == e:
            b += 1
        t0, t1 = tr.span(e)
        a += tr.first
        b += tr.first
        if a < frozen_from:
            rest, a = max(t1 - knots[frozen_from], 0.0), frozen_from
        else:
            rest = t1 - t0
        nom = getattr(self.sync, "nominal", None) or {}
        ws = [nom.get(s, 0.0) for s in range(a, b + 1)]
        tot = sum(ws)
        if not all(w > 0 for w in ws) or not tot > 0:
            return rest / (b - a + 1)
        return rest * nom[step] / tot

    def plan(self, from_step: int) -> None:
        """Recompute boundaries and knots of steps ``from_step .. frontier`` (earlier ones are frozen)."""
        sync = self.sync
        T = self.T
        # step keys are consecutive integers: drop those after from_step
        st = from_step + 1
        while st in T:
            del T[st]
            st += 1
        timing = self.timing
        for tm in timing.values():
            kn = tm.knots
            if kn and max(kn) > from_step:
                for st in [x for x in kn if x > from_step]:
                    del kn[st]
        tracks = sync.tracks
        for tr in tracks:
            if tr.key not in timing:
                tm = timing[tr.key] = _TrackTiming()
                if self.keep_history:
                    self.timing_history[tr.key] = tm
        owner = getattr(self.weights_at, "__self__", None)
        w_time = T[from_step]
        w_now = self.weights_at(w_time)
        until = getattr(owner, "weights_valid_until", -math.inf)
        share = self._share
        # per track: (track, knots, first, elems, end) looked up once
        rows = [(tr, timing[tr.key].knots, tr.first, tr.elems, tr.end, tr.key) for tr in tracks]
        for s in range(from_step, sync.frontier + 1):
            num = den = tot = 0.0
            cnt = 0
            spans = []
            ws = []
            ts = T[s]
            if ts >= until and ts != w_time:  # a ramp event lies behind (or a ramp runs): weigh again
                w_time = ts
                w_now = self.weights_at(ts)
                until = getattr(owner, "weights_valid_until", -math.inf)
            for tr, kn, first, elems, end, key in rows:
                j = s - first if first is not None else -1
                n = len(elems)
                if j < 0 or j >= n or (end is not None and s >= end):
                    continue
                e = elems[j]
                if j == 0:  # a track starts at the beginning of its first element
                    kn[s] = tr.span(e)[0]
                if (j == 0 or elems[j - 1] != e) and (j + 1 == n or elems[j + 1] != e):
                    # an element played in one step only (the common case of _share)
                    t0, t1 = tr.span(e)
                    sp = t1 - t0
                else:
                    sp = share(tr, s, from_step, kn)
                spans.append((kn, sp))
                w = w_now.get(key, 0.0)
                ws.append(w)
                num += w * sp
                den += w
                tot += sp
                cnt += 1
            if not cnt:
                T[s + 1] = ts
                break
            d = num / den if den > 0 else tot / cnt  # equation 6 (plain mean when no weight)
            d = bounded_duration(d, [sp for _, sp in spans], self.config.min_rate, self.config.max_rate, ws,
                                 self.config.tempo == "weighted")
            T[s + 1] = ts + max(d, 1e-4)
            for kn, sp in spans:
                kn[s + 1] = kn[s] + sp

    def start(self, now: float) -> None:
        """A fresh plan begins at real time ``now`` with the synchronizer's current step."""
        k = self.sync.current
        self.sync.dirty = None
        self.T = {k: float(now)}
        for key in list(self.timing):
            if not any(t.key == key for t in self.sync.tracks):
                del self.timing[key]
        self.plan(k)
        self.freeze(k)

    def enter(self) -> None:
        """The synchronizer has entered its current step: re-time what changed and freeze its segments.

        Only steps from the earliest one the synchronizer changed (a start, an enlarged element, a
        removal) or not yet timed (the new frontier) are planned again.
        """
        sync = self.sync
        k = sync.current
        live = {t.key for t in sync.tracks}
        if not live.issuperset(self.timing):
            for key in [x for x in self.timing if x not in live]:
                del self.timing[key]
        T = self.T
        st = k - 1  # step keys are consecutive integers: drop those before k
        while st in T:
            del T[st]
            st -= 1
        for tm in self.timing.values():  # knots of played steps are in the history, not needed here
            kn = tm.knots
            if kn and min(kn) < k:
                for st in [x for x in kn if x < k]:
                    del kn[st]
        last = max(T) - 1  # last step with a duration
        start = last + 1 if sync.dirty is None else min(sync.dirty, last + 1)
        start = max(start, k)
        if start not in self.T:
            start = k
        sync.dirty = None
        self.plan(start)
        self.freeze(k)

    def replan(self) -> None:
        """Weights or actions changed mid-step: re-time the steps after the current one."""
        k = self.sync.current
        if k + 1 in self.T:
            self.sync.dirty = None
            self.plan(k + 1)

    def split(self, now: float) -> bool:
        """End the current step at ``now`` (:meth:`~kinodyn.blend.sync.Synchronizer.split`): the
        segments being played stop there, at the action time and speed they reach (so the warp stays
        C1), and the steps after it are planned again. Returns whether the synchronizer split it."""
        k = self.sync.current
        T = self.T
        if not (k + 1 in T and T[k] < now < T[k + 1]) or len(self.timing) != 1:
            return False
        tm = next(iter(self.timing.values()))
        seg = tm.current
        if seg is None or seg.t0 != T[k]:
            return False
        c, u = seg.coef, now - seg.t0
        h = float(eval_poly(c, u))
        if not self.sync.split(h - tm.knots[k]):
            return False
        tm.current = Segment(seg.t0, now, c)
        if self.keep_history and tm.segments:
            tm.segments[-1] = tm.current
        tm.knots[k + 1] = h
        tm.tangent = {k + 1: (3.0 * c[3] * u + 2.0 * c[2]) * u + c[1]}
        T[k + 1] = now
        self.sync.dirty = None
        self.plan(k + 1)
        return True

    def freeze(self, k: int) -> None:
        """Fix the Hermite segment of every action present in step ``k``."""
        T = self.T
        t0, t1 = T[k], T[k + 1]
        tension, mono = self.config.tension, self.config.monotone
        has2 = k + 2 in T
        timing = self.timing
        for tr in self.sync.tracks:
            first, elems, end = tr.first, tr.elems, tr.end
            j = k - first if first is not None else -1
            if j < 0 or j >= len(elems) or (end is not None and k >= end):
                continue
            next_in = j + 1 < len(elems) and (end is None or k + 1 < end)
            tm = timing[tr.key]
            kn = tm.knots
            h0, h1 = kn[k], kn[k + 1]
            sec = (h1 - h0) / (t1 - t0)
            # the tangent frozen at the end of the previous segment keeps the speed continuous; it is
            # only clipped when a changed plan would make this segment run backwards (alpha <= 3).
            m0 = tm.tangent.get(k, sec)
            if has2 and next_in and k + 2 in kn:
                h2, t2 = kn[k + 2], T[k + 2]
                m1 = (1.0 - tension) * (h2 - h0) / (t2 - t0)
                if mono:
                    sec2 = (h2 - h1) / max(t2 - t1, 1e-12)
                    lo, hi = min(sec, sec2), max(sec, sec2)
                    m1 = min(max(m1, lo, 0.0), hi, 3.0 * lo)
            else:
                m1 = sec
            if mono:
                m0 = min(max(m0, 0.0), 3.0 * sec)
                m1 = min(max(m1, 0.0), 3.0 * sec)
            if self.config.bounded_speed:
                m0, m1 = bounded_tangents(m0, m1, sec, self.config.min_rate, self.config.max_rate)
            tm.tangent = {k + 1: m1}
            dt_, dh = t1 - t0, h1 - h0
            c2 = (3.0 * dh / dt_ - 2.0 * m0 - m1) / dt_
            c3 = (m0 + m1 - 2.0 * dh / dt_) / (dt_ * dt_)
            seg = Segment(t0, t1, (h0, m0, c2, c3))
            if self.keep_history:
                tm.history.append((t0, h0))
                tm.segments.append(seg)
            tm.current = seg

    def segment(self, key) -> Segment:
        return self.timing[key].current

    def time_of(self, key, h: float) -> float | None:
        """Planned real time at which action ``key`` reaches action time ``h`` (linear between knots);
        ``None`` beyond the plan."""
        tm = self.timing.get(key)
        if tm is None:
            return None
        steps = sorted(s for s in tm.knots if s in self.T)
        for a, b in itertools.pairwise(steps):
            ha, hb = tm.knots[a], tm.knots[b]
            if ha <= h <= hb and hb > ha:
                return self.T[a] + (h - ha) / (hb - ha) * (self.T[b] - self.T[a])
        return None
