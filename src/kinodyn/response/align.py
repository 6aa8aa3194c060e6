"""Fast time alignment of one chosen reaction clip against a simulated motion (dynamic response, section 5).

Instead of every pair of frames, the timing space (simulation frame ``fs``, clip frame ``fm``) is sampled
sparsely and uniformly, every ``stride`` frames on both axes (10 in the paper). Sample sets are taken one
simulation row at a time from the start of the simulation, since good matches lie early (the paper's
colour plate); the sampling stops once ``patience`` successive rows bring no improvement. The best
samples are then refined with BFGS on continuous frame offsets, the error D being evaluated on poses
interpolated between frames (positions linearly, orientations by normalized lerp, which between
neighbouring frames of the built-in clips stays within 0.003 degrees of slerp) with the same per-window
ground alignment as the exhaustive search (:mod:`kinodyn.response.search`).

Sampling and refinement run compiled, so that one evaluation of D costs a few microseconds: the BFGS is
Numerical Recipes' ``dfpmin`` (the paper's choice) with central-difference gradients, checked against
scipy's BFGS on the same objective (:func:`refine_reference`).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numba
import numpy as np
from scipy.optimize import minimize

from kinodyn.errors import ParameterError
from kinodyn.math import quat, xform
from kinodyn.response.search import Windows

# Fast-math without reassociation (as the exhaustive search's kernel): each window's arithmetic keeps its
# written order, so a timing is the same whatever the vectorization.
_NO_REASSOC = {"nnan", "ninf", "nsz", "arcp", "contract", "afn"}

__all__ = ["AlignConfig", "AlignResult", "AlignStatus", "continuous_error", "continuous_error_reference",
           "fast_align", "refine_reference"]


class AlignStatus(enum.Enum):
    """Why the refinement stopped."""

    CONVERGED = "converged"
    MAX_ITER = "max_iterations"
    SAMPLED = "sampled"  # no refinement asked for (or it found nothing better)


@dataclass(frozen=True)
class AlignConfig:
    """Parameters of the fast alignment.

    Attributes:
        stride: sample spacing in frames on both axes.
        patience: successive simulation rows without improvement before the sampling stops.
        refine: BFGS starting points (the best samples); 0 keeps the best sample.
        step: finite-difference step of the gradient, in frames.
        max_iter: BFGS iteration limit per start.
    """

    stride: int = 10
    patience: int = 2
    refine: int = 1
    step: float = 0.25
    max_iter: int = 20

    def __post_init__(self):
        if self.stride < 1 or self.patience < 1 or self.refine < 0 or self.max_iter < 1 or not self.step > 0:
            raise ParameterError(f"stride, patience, max_iter must be >= 1, refine >= 0 and step > 0; got {self}")


@dataclass(frozen=True)
class AlignResult:
    """The timing found for one clip.

    Attributes:
        sim_frame, clip_frame: continuous first frames of the matched windows.
        error: error D there.
        sampled_error: the best sampled error before refinement.
        evaluations: how many windows were compared in all.
        rows: simulation rows sampled before stopping.
        status: :class:`AlignStatus`.
    """

    sim_frame: float
    clip_frame: float
    error: float
    sampled_error: float
    evaluations: int
    rows: int
    status: AlignStatus


def _interp_tracks(pos, rot, t: np.ndarray):
    """Tracks ``(F, J, 3)``/``(F, J, 4)`` at continuous frames ``t (n,)`` (clamped to the track)."""
    t = np.clip(t, 0.0, len(pos) - 1.0)
    a = np.floor(t).astype(np.int64)
    b = np.minimum(a + 1, len(pos) - 1)
    u = (t - a)[:, None, None]
    p = pos[a] * (1.0 - u) + pos[b] * u
    sign = np.where(np.sum(rot[a] * rot[b], axis=-1, keepdims=True) >= 0.0, 1.0, -1.0)
    r = rot[a] * (1.0 - u) + sign * rot[b] * u
    return p, r / np.linalg.norm(r, axis=-1, keepdims=True)


def _window_at(pos, rot, start: float, length: int) -> Windows:
    p, r = _interp_tracks(pos, rot, start + np.arange(length, dtype=np.float64))
    g = xform.from_root(p[:1, 0], r[:1, 0])
    q_inv = quat.conj(quat.from_heading(g[:, 2]))
    p = quat.mul_vec(q_inv[:, None, :], p - np.array([g[0, 0], g[0, 1], 0.0]))
    r = quat.mul(q_inv[:, None, :], r)
    return Windows(p[None], r[None], g)


def continuous_error_reference(sim_tracks, clip_tracks, fs: float, fm: float, weights) -> float:
    """:func:`continuous_error` in plain numpy (the oracle the compiled version is tested against)."""
    wp, wt, ww = weights
    a = _window_at(*sim_tracks, fs, len(ww))
    b = _window_at(*clip_tracks, fm, len(ww))
    d = np.linalg.norm(a.pos[0] - b.pos[0], axis=-1)  # (W, J)
    c = np.minimum(np.abs(np.sum(a.rot[0] * b.rot[0], axis=-1)), 1.0)
    return float(ww @ (d @ wp + (2.0 * np.sqrt(2.0 - 2.0 * c)) @ wt))


@numba.njit(cache=True, inline="always")
def _sample_frame(pos, rot, t, j, out_p, out_q):  # pragma: no cover - compiled
    """Body ``j`` at continuous frame ``t`` (clamped): position lerp, orientation nlerp."""
    t = min(max(t, 0.0), pos.shape[0] - 1.0)
    a = int(np.floor(t))
    b = min(a + 1, pos.shape[0] - 1)
    u = t - a
    for k in range(3):
        out_p[k] = pos[a, j, k] * (1.0 - u) + pos[b, j, k] * u
    d = 0.0
    for k in range(4):
        d += rot[a, j, k] * rot[b, j, k]
    wb = u if d >= 0.0 else -u
    n = 0.0
    for k in range(4):
        out_q[k] = (1.0 - u) * rot[a, j, k] + wb * rot[b, j, k]
        n += out_q[k] * out_q[k]
    n = np.sqrt(n)
    for k in range(4):
        out_q[k] /= n


@numba.njit(cache=True, fastmath=_NO_REASSOC)
def _aligned(pos, rot, t, out_p, out_q):  # pragma: no cover - compiled
    """Window ``out_p (W, J, 3)``/``out_q (W, J, 4)`` of a track from continuous frame ``t`` (each frame
    clamped to the track; positions lerped, orientations nlerped), in the ground frame (floor position,
    heading) of its first, interpolated frame."""
    p, q = np.empty(3), np.empty(4)
    _sample_frame(pos, rot, t, 0, p, q)
    w, z = (q[0], q[3]) if q[0] >= 0.0 else (-q[0], -q[3])
    x0, y0, h = p[0], p[1], 2.0 * np.arctan2(z, w)
    c, s = np.cos(-0.5 * h), np.sin(-0.5 * h)
    c2, s2 = c * c - s * s, 2.0 * c * s
    last = pos.shape[0] - 1
    for i in range(out_p.shape[0]):
        ti = min(max(t + i, 0.0), last * 1.0)
        a = int(np.floor(ti))
        b = min(a + 1, last)
        u = ti - a
        v = 1.0 - u
        for j in range(pos.shape[1]):
            x = pos[a, j, 0] * v + pos[b, j, 0] * u - x0
            y = pos[a, j, 1] * v + pos[b, j, 1] * u - y0
            out_p[i, j, 0], out_p[i, j, 1] = c2 * x - s2 * y, s2 * x + c2 * y
            out_p[i, j, 2] = pos[a, j, 2] * v + pos[b, j, 2] * u
            d = rot[a, j, 0] * rot[b, j, 0] + rot[a, j, 1] * rot[b, j, 1] + rot[a, j, 2] * rot[b, j, 2] \
                + rot[a, j, 3] * rot[b, j, 3]
            ub = u if d >= 0.0 else -u
            q0 = v * rot[a, j, 0] + ub * rot[b, j, 0]
            q1 = v * rot[a, j, 1] + ub * rot[b, j, 1]
            q2 = v * rot[a, j, 2] + ub * rot[b, j, 2]
            q3 = v * rot[a, j, 3] + ub * rot[b, j, 3]
            n = 1.0 / np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
            # (c, 0, 0, s) * q, normalized
            out_q[i, j, 0] = (c * q0 - s * q3) * n
            out_q[i, j, 1] = (c * q1 - s * q2) * n
            out_q[i, j, 2] = (c * q2 + s * q1) * n
            out_q[i, j, 3] = (c * q3 + s * q0) * n


@numba.njit(cache=True)
def _compare(ap, aq, bp, bq, wp, wt, ww):  # pragma: no cover - compiled
    """Error D between two ground-aligned windows (the sum of :mod:`kinodyn.response.search`)."""
    total = 0.0
    for i in range(ww.shape[0]):
        row = 0.0
        for j in range(ap.shape[1]):
            d = np.sqrt((ap[i, j, 0] - bp[i, j, 0]) ** 2 + (ap[i, j, 1] - bp[i, j, 1]) ** 2
                        + (ap[i, j, 2] - bp[i, j, 2]) ** 2)
            dot = min(abs(aq[i, j, 0] * bq[i, j, 0] + aq[i, j, 1] * bq[i, j, 1] + aq[i, j, 2] * bq[i, j, 2]
                          + aq[i, j, 3] * bq[i, j, 3]), 1.0)
            row += wp[j] * d + wt[j] * 2.0 * np.sqrt(2.0 - 2.0 * dot)
        total += ww[i] * row
    return total


@numba.njit(cache=True)
def _continuous_kernel(sp, sr, cp, cr, fs, fm, wp, wt, ww):  # pragma: no cover - compiled
    w_n, j_n = ww.shape[0], sp.shape[1]
    ap, aq = np.empty((w_n, j_n, 3)), np.empty((w_n, j_n, 4))
    bp, bq = np.empty((w_n, j_n, 3)), np.empty((w_n, j_n, 4))
    _aligned(sp, sr, fs, ap, aq)
    _aligned(cp, cr, fm, bp, bq)
    return _compare(ap, aq, bp, bq, wp, wt, ww)


def continuous_error(sim_tracks, clip_tracks, fs: float, fm: float, weights) -> float:
    """Error D between the windows starting at continuous frames ``fs`` of the simulation and ``fm`` of
    the clip (tracks ``(pos (F, J, 3), rot (F, J, 4))``; ``weights`` = ``(wp, wt, ww)``), with poses
    interpolated between frames and each window in the ground frame of its first (interpolated) frame."""
    wp, wt, ww = weights
    return float(_continuous_kernel(sim_tracks[0], sim_tracks[1], clip_tracks[0], clip_tracks[1], float(fs),
                                    float(fm), wp, wt, ww))


@numba.njit(cache=True)
def _sample(sp, sr, lp, lr, wp, wt, ww, n_sim, stride, patience):  # pragma: no cover - compiled
    """Row-by-row sparse sampling from the start of the simulation, with early stopping: the sampled
    ``(err, sim frame, clip frame)`` rows and how many simulation rows were taken. ``lp``/``lr`` are the
    clip's ground-aligned windows (every ``stride``-th is compared)."""
    w_n, j_n = ww.shape[0], sp.shape[1]
    ap, aq = np.empty((w_n, j_n, 3)), np.empty((w_n, j_n, 4))
    cols = np.arange(0, lp.shape[0], stride)
    out = np.empty((((n_sim - 1) // stride + 1) * cols.shape[0], 3))
    best, since, rows, k = np.inf, 0, 0, 0
    for s in range(0, n_sim, stride):
        _aligned(sp, sr, float(s), ap, aq)
        rows += 1
        row_best = np.inf
        for c in cols:
            e = _compare(ap, aq, lp[c], lr[c], wp, wt, ww)
            out[k, 0], out[k, 1], out[k, 2] = e, s, c
            k += 1
            row_best = min(row_best, e)
        if row_best < best - 1e-12:
            best, since = row_best, 0
        else:
            since += 1
            if since >= patience:
                break
    return out[:k], rows


_CACHE = 4  # windows kept per side while refining: a gradient reuses the windows at the current point
_XTOL = 0.01  # frames: BFGS stops once a step moves the timing less (the pipeline rounds it to frames)


@numba.njit(cache=True)
def _cached(pos, rot, t, ts, cp, cq, nxt):  # pragma: no cover - compiled
    """Slot of the cache ``(ts (C,), cp (C, W, J, 3), cq (C, W, J, 4), nxt (1,))`` holding the window of a
    track at frame ``t``, computing it into the oldest slot when absent."""
    for k in range(ts.shape[0]):
        if ts[k] == t:
            return k
    k = nxt[0]
    nxt[0] = (k + 1) % ts.shape[0]
    _aligned(pos, rot, t, cp[k], cq[k])
    ts[k] = t
    return k


@numba.njit(cache=True)
def _objective(tracks, caches, x, hi, wp, wt, ww):  # pragma: no cover - compiled
    """D at ``x`` clamped into ``[0, hi]``, plus the squared distance outside (keeps BFGS inside);
    ``tracks`` = (sim pos, sim rot, clip pos, clip rot), ``caches`` two window caches (:func:`_cached`)."""
    a = min(max(x[0], 0.0), hi[0])
    b = min(max(x[1], 0.0), hi[1])
    sp, sr, cp, cr = tracks
    (ta, pa, qa, na), (tb, pb, qb, nb) = caches
    i = _cached(sp, sr, a, ta, pa, qa, na)
    k = _cached(cp, cr, b, tb, pb, qb, nb)
    return _compare(pa[i], qa[i], pb[k], qb[k], wp, wt, ww) + (x[0] - a) ** 2 + (x[1] - b) ** 2


@numba.njit(cache=True)
def _gradient(tracks, caches, x, hi, wp, wt, ww, h, g):  # pragma: no cover - compiled
    """Central-difference gradient of :func:`_objective` with step ``h`` into ``g``; 4 evaluations."""
    y = x.copy()
    for k in range(2):
        y[k] = x[k] + h
        fp = _objective(tracks, caches, y, hi, wp, wt, ww)
        y[k] = x[k] - h
        fm = _objective(tracks, caches, y, hi, wp, wt, ww)
        y[k] = x[k]
        g[k] = (fp - fm) / (2.0 * h)


def _new_caches(w: int, j: int):
    return tuple((np.full(_CACHE, np.nan), np.empty((_CACHE, w, j, 3)), np.empty((_CACHE, w, j, 4)),
                  np.zeros(1, dtype=np.int64)) for _ in range(2))


# BFGS: inverse-Hessian update and backtracking line search as in Numerical Recipes' dfpmin
@numba.njit(cache=True)
def _bfgs(tracks, caches, x0, hi, wp, wt, ww, h, max_iter, max_step, gtol):  # pragma: no cover - compiled
    """Minimise :func:`_objective` from ``x0``: ``(x, f, evaluations, converged)``."""
    x = x0.copy()
    f = _objective(tracks, caches, x, hi, wp, wt, ww)
    g, g_new = np.empty(2), np.empty(2)
    _gradient(tracks, caches, x, hi, wp, wt, ww, h, g)
    evals = 5
    hess = np.eye(2)
    gn = np.sqrt(g[0] ** 2 + g[1] ** 2)
    if gn < gtol:
        return x, f, evals, True
    hess *= min(1.0, max_step / gn)  # first step: steepest descent, at most max_step frames
    for _ in range(max_iter):
        p = -(hess @ g)
        pn = np.sqrt(p[0] ** 2 + p[1] ** 2)
        if pn > max_step:
            p *= max_step / pn
        slope = g[0] * p[0] + g[1] * p[1]
        if slope >= 0.0:  # not a descent direction: restart from steepest descent
            hess = np.eye(2) * min(1.0, max_step / gn)
            p = -(hess @ g)
            slope = g[0] * p[0] + g[1] * p[1]
        alpha, x_new, f_new = 1.0, x + p, 0.0
        while True:
            x_new = x + alpha * p
            f_new = _objective(tracks, caches, x_new, hi, wp, wt, ww)
            evals += 1
            if f_new <= f + 1e-4 * alpha * slope or alpha < 1e-3:
                break
            alpha *= 0.5
        if f_new > f:  # no decrease along the direction: stop here
            return x, f, evals, False
        step = x_new - x
        if step[0] ** 2 + step[1] ** 2 < _XTOL ** 2:  # moving by less than _XTOL frames: done
            return x_new, f_new, evals, True
        _gradient(tracks, caches, x_new, hi, wp, wt, ww, h, g_new)
        evals += 4
        s, yv = x_new - x, g_new - g
        x, f = x_new, f_new
        g[:] = g_new
        gn = np.sqrt(g[0] ** 2 + g[1] ** 2)
        if gn < gtol:
            return x, f, evals, True
        sy = s[0] * yv[0] + s[1] * yv[1]
        if sy > 1e-12:
            hy = hess @ yv
            yhy = yv[0] * hy[0] + yv[1] * hy[1]
            u = s / sy - hy / yhy
            hess += np.outer(s, s) / sy - np.outer(hy, hy) / yhy + yhy * np.outer(u, u)
    return x, f, evals, False


def fast_align(sim: Windows | None, sim_tracks, library, clip: int,
               config: AlignConfig = AlignConfig()) -> AlignResult:
    """Timing of clip ``clip`` of ``library`` against a simulated segment.

    Sampling and refinement run compiled (the BFGS of Numerical Recipes, as in the paper; scipy's is the
    oracle it is tested against, :func:`refine_reference`), each evaluation of D a few microseconds.

    Args:
        sim: the segment's :class:`Windows` (as for the exhaustive search), or None: only its length is
            used and the tracks give it.
        sim_tracks: its body tracks ``(pos (S, J, 3), rot (S, J, 4))``.
        library: a :class:`kinodyn.response.library.ReactionLibrary`.
        clip: index of the clip to align.
        config: :class:`AlignConfig`.
    """
    if not 0 <= clip < len(library):
        raise ParameterError(f"clip must be an index into the {len(library)}-clip library, got {clip}")
    a, b = library.rows[clip]
    w = library.window
    n_sim = len(sim) if sim is not None else (0 if sim_tracks is None else len(sim_tracks[0]) - w + 1)
    if n_sim <= 0 or b <= a:
        raise ParameterError("the simulated segment and the clip must both be as long as the search window")
    sp, sr = (np.ascontiguousarray(t, dtype=np.float64) for t in sim_tracks)
    cp, cr = library.tracks[clip]
    wp, wt, ww = library.weights
    found, rows = _sample(sp, sr, library.windows.pos[a:b], library.windows.rot[a:b], wp, wt, ww, n_sim,
                          config.stride, config.patience)
    found = found[np.argsort(found[:, 0], kind="stable")]
    best_e = float(found[0, 0])
    result = (best_e, float(found[0, 1]), float(found[0, 2]))
    evals, status = len(found), AlignStatus.SAMPLED
    hi = np.array([n_sim - 1.0, b - a - 1.0])
    caches = _new_caches(w, sp.shape[1])
    for e0, s0, m0 in found[:config.refine]:
        x, _, n, ok = _bfgs((sp, sr, cp, cr), caches, np.array([s0, m0]), hi, wp, wt, ww, config.step,
                            config.max_iter, float(config.stride), 1e-3)
        evals += int(n)
        x = np.clip(x, 0.0, hi)
        for cand in (x, np.round(x)):  # the nearest whole frames too: often the optimum sits on one
            e = float(_continuous_kernel(sp, sr, cp, cr, cand[0], cand[1], wp, wt, ww))
            evals += 1
            if e < result[0]:
                result = (e, float(cand[0]), float(cand[1]))
                status = AlignStatus.CONVERGED if ok else AlignStatus.MAX_ITER
    return AlignResult(result[1], result[2], result[0], best_e, evals, rows, status)


def refine_reference(sim_tracks, clip_tracks, start, hi, weights, config: AlignConfig = AlignConfig()):
    """scipy's BFGS on the same objective from ``start (2,)`` within ``[0, hi (2,)]``: ``(x (2,), D)``
    (the oracle the compiled refinement of :func:`fast_align` is tested against)."""
    hi = np.asarray(hi, dtype=np.float64)

    def objective(x):
        xc = np.clip(x, 0.0, hi)
        return continuous_error(sim_tracks, clip_tracks, xc[0], xc[1], weights) + float(np.sum((x - xc) ** 2))

    opt = minimize(objective, np.asarray(start, dtype=np.float64), method="BFGS",
                   options={"maxiter": 50, "eps": config.step, "gtol": 1e-3})
    return np.clip(opt.x, 0.0, hi), float(opt.fun)
