"""Fast time alignment of one chosen reaction clip against a simulated motion (dynamic response, section 5).

Instead of every pair of frames, the timing space (simulation frame ``fs``, clip frame ``fm``) is sampled
sparsely and uniformly, every ``stride`` frames on both axes (10 in the paper). Sample sets are taken one
simulation row at a time from the start of the simulation, since good matches lie early (the paper's
colour plate); the sampling stops once ``patience`` successive rows bring no improvement. The best
samples are then refined with BFGS (``scipy.optimize``) on continuous frame offsets, the error D being
evaluated on poses interpolated between frames (positions linearly, orientations by slerp) with the
same per-window ground alignment as the exhaustive search (:mod:`kinodyn.response.search`).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numba
import numpy as np
from scipy.optimize import minimize

from kinodyn.errors import ParameterError
from kinodyn.math import quat, xform
from kinodyn.response.search import Windows, window_errors, windows

__all__ = ["AlignConfig", "AlignResult", "AlignStatus", "continuous_error", "continuous_error_reference",
           "fast_align"]


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
    refine: int = 2
    step: float = 0.25
    max_iter: int = 8

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
    u = (t - a)[:, None]
    p = pos[a] * (1.0 - u[..., None]) + pos[b] * u[..., None]
    r = quat.slerp(rot[a], rot[b], u)
    return p, r


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
    """Body ``j`` at continuous frame ``t`` (clamped): position lerp, orientation slerp."""
    t = min(max(t, 0.0), pos.shape[0] - 1.0)
    a = int(np.floor(t))
    b = min(a + 1, pos.shape[0] - 1)
    u = t - a
    for k in range(3):
        out_p[k] = pos[a, j, k] * (1.0 - u) + pos[b, j, k] * u
    d = 0.0
    for k in range(4):
        d += rot[a, j, k] * rot[b, j, k]
    sign = 1.0 if d >= 0.0 else -1.0
    d = min(abs(d), 1.0)
    theta = np.arccos(d)
    st = np.sin(theta)
    if st < 1e-8:
        wa, wb = 1.0 - u, u
    else:
        wa, wb = np.sin((1.0 - u) * theta) / st, np.sin(u * theta) / st
    n = 0.0
    for k in range(4):
        out_q[k] = wa * rot[a, j, k] + wb * sign * rot[b, j, k]
        n += out_q[k] * out_q[k]
    n = np.sqrt(n)
    for k in range(4):
        out_q[k] /= n


# long kernel: interpolated, ground-aligned windows of both tracks and their error D in one pass
@numba.njit(cache=True)
def _continuous_kernel(sp, sr, cp, cr, fs, fm, wp, wt, ww):  # pragma: no cover - compiled
    j_n = sp.shape[1]
    p0 = np.empty(3)
    q0 = np.empty(4)
    frame = np.empty((2, 3))  # x, y, heading of each window's first frame
    for side in range(2):
        pos, rot, t = (sp, sr, fs) if side == 0 else (cp, cr, fm)
        _sample_frame(pos, rot, t, 0, p0, q0)
        w, z = (q0[0], q0[3]) if q0[0] >= 0.0 else (-q0[0], -q0[3])
        frame[side, 0], frame[side, 1], frame[side, 2] = p0[0], p0[1], 2.0 * np.arctan2(z, w)
    pa, qa, pb, qb = np.empty(3), np.empty(4), np.empty(3), np.empty(4)
    la, lb = np.empty(3), np.empty(4)
    total = 0.0
    for i in range(ww.shape[0]):
        row = 0.0
        for j in range(j_n):
            _sample_frame(sp, sr, fs + i, j, pa, qa)
            _sample_frame(cp, cr, fm + i, j, pb, qb)
            for side in range(2):
                p, q = (pa, qa) if side == 0 else (pb, qb)
                c, s = np.cos(-0.5 * frame[side, 2]), np.sin(-0.5 * frame[side, 2])
                x, y = p[0] - frame[side, 0], p[1] - frame[side, 1]
                c2, s2 = c * c - s * s, 2.0 * c * s
                la[0], la[1], la[2] = c2 * x - s2 * y, s2 * x + c2 * y, p[2]
                # (c, 0, 0, s) * q
                lb[0] = c * q[0] - s * q[3]
                lb[1] = c * q[1] - s * q[2]
                lb[2] = c * q[2] + s * q[1]
                lb[3] = c * q[3] + s * q[0]
                for k in range(3):
                    p[k] = la[k]
                for k in range(4):
                    q[k] = lb[k]
            d = np.sqrt((pa[0] - pb[0]) ** 2 + (pa[1] - pb[1]) ** 2 + (pa[2] - pb[2]) ** 2)
            dot = min(abs(qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3]), 1.0)
            row += wp[j] * d + wt[j] * 2.0 * np.sqrt(2.0 - 2.0 * dot)
        total += ww[i] * row
    return total


def continuous_error(sim_tracks, clip_tracks, fs: float, fm: float, weights) -> float:
    """Error D between the windows starting at continuous frames ``fs`` of the simulation and ``fm`` of
    the clip (tracks ``(pos (F, J, 3), rot (F, J, 4))``; ``weights`` = ``(wp, wt, ww)``), with poses
    interpolated between frames and each window in the ground frame of its first (interpolated) frame."""
    wp, wt, ww = weights
    return float(_continuous_kernel(sim_tracks[0], sim_tracks[1], clip_tracks[0], clip_tracks[1], float(fs),
                                    float(fm), wp, wt, ww))


def _sample(sim: Windows, clip_win: Windows, weights, cfg: AlignConfig):
    """Row-by-row sparse sampling from the start of the simulation, with early stopping."""
    wp, wt, ww = weights
    cols = np.arange(0, len(clip_win), cfg.stride)
    lib = Windows(clip_win.pos[cols], clip_win.rot[cols], clip_win.ground[cols])
    best, since, rows, found = np.inf, 0, 0, []
    for s in range(0, len(sim), cfg.stride):
        row = Windows(sim.pos[s:s + 1], sim.rot[s:s + 1], sim.ground[s:s + 1])
        d = window_errors(row, lib, wp, wt, ww)[0]
        rows += 1
        found += [(float(e), s, int(c)) for e, c in zip(d, cols)]
        if d.min() < best - 1e-12:
            best, since = float(d.min()), 0
        else:
            since += 1
            if since >= cfg.patience:
                break
    found.sort()
    return found, rows, rows * len(cols)


def fast_align(sim: Windows, sim_tracks, library, clip: int, config: AlignConfig = AlignConfig()) -> AlignResult:
    """Timing of clip ``clip`` of ``library`` against a simulated segment.

    Args:
        sim: the segment's :class:`Windows` (as for the exhaustive search).
        sim_tracks: its body tracks ``(pos (S, J, 3), rot (S, J, 4))``.
        library: a :class:`kinodyn.response.library.ReactionLibrary`.
        clip: index of the clip to align.
        config: :class:`AlignConfig`.
    """
    if not 0 <= clip < len(library):
        raise ParameterError(f"clip must be an index into the {len(library)}-clip library, got {clip}")
    a, b = library.rows[clip]
    if len(sim) == 0 or b <= a:
        raise ParameterError("the simulated segment and the clip must both be as long as the search window")
    clip_win = Windows(library.windows.pos[a:b], library.windows.rot[a:b], library.windows.ground[a:b])
    found, rows, evals = _sample(sim, clip_win, library.weights, config)
    best_e, best_s, best_m = found[0]
    result = (best_e, float(best_s), float(best_m))
    status = AlignStatus.SAMPLED
    hi = np.array([len(sim) - 1.0, len(clip_win) - 1.0])
    tracks = library.tracks[clip]

    def objective(x):
        xc = np.clip(x, 0.0, hi)
        over = float(np.sum((x - xc) ** 2))
        return continuous_error(sim_tracks, tracks, xc[0], xc[1], library.weights) + over

    for e0, s0, m0 in found[:config.refine]:
        opt = minimize(objective, np.array([s0, m0], dtype=np.float64), method="BFGS",
                       options={"maxiter": config.max_iter, "eps": config.step, "gtol": 1e-3})
        evals += int(opt.nfev)
        x = np.clip(opt.x, 0.0, hi)
        for cand in (x, np.round(x)):  # the nearest whole frames too: often the optimum sits on one
            e = continuous_error(sim_tracks, tracks, cand[0], cand[1], library.weights)
            evals += 1
            if e < result[0]:
                result = (e, float(cand[0]), float(cand[1]))
                status = AlignStatus.CONVERGED if opt.success else AlignStatus.MAX_ITER
    return AlignResult(result[1], result[2], result[0], best_e, evals, rows, status)
