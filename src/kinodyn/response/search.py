"""Exhaustive time alignment of a simulated motion against a reaction library (dynamic response, section 5).

For a simulated segment and every reaction clip, the windowed error

    D(fs, fm) = sum_i w_i sum_b ( wp_b |p_b(fs + i) - p_b(fm + i)| + wt_b angle(q_b(fs + i), q_b(fm + i)) )

is evaluated for every pair (simulation frame ``fs``, clip frame ``fm``) whose window of ``W`` frames fits
both motions. Before comparing a window, each side is expressed in the ground frame (floor position and
heading of the root, :mod:`kinodyn.math.xform`) of its own first frame, so the error ignores where the
character stands and which way it faces: the paper's per-window alignment. ``p_b`` are body (joint)
positions in metres, ``q_b`` body orientations; the angle between two orientations is measured as
``4 sin(angle / 4)`` (the quaternion chord, equal to the angle within 1 % up to 50 degrees and
monotone in it, and free of an arccos per term), and ``wt_b`` turns radians into metres.

The search is the quality reference the fast alignment (:mod:`kinodyn.response.align`) is measured
against and labels the classifier's training set, so it runs as one compiled kernel over precomputed
window stacks (no Python loop over frame pairs).

Uses :mod:`kinodyn.kinematics` (forward kinematics) and :mod:`kinodyn.math` only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.kinematics import forward_kinematics
from kinodyn.math import quat, xform
from kinodyn.motion import Motion

# Fast-math without reassociation: the error sums keep their written order, so a labelled dataset is the
# same bit for bit whatever process, thread count or array alignment computes it.
_NO_REASSOC = {"nnan", "ninf", "nsz", "arcp", "contract", "afn"}

__all__ = ["SearchConfig", "SearchResult", "Windows", "body_tracks", "body_weights", "exhaustive",
           "window_errors", "windows"]


@dataclass(frozen=True)
class SearchConfig:
    """Parameters of the windowed error D.

    Attributes:
        window_s: window length in seconds (``W = round(window_s * fps)`` frames, at least 2).
        position_weight: default ``wp_b`` for every body (per metre).
        angle_weight: default ``wt_b`` for every body (metres per radian).
        weights: per body name, ``(wp_b, wt_b)`` overriding the defaults (e.g. ``{"Hips": (2.0, 0.5)}``).
        decay: window weights ``w_i`` fall off as ``exp(-decay * i / W)`` (0 = uniform); they sum to 1.
    """

    window_s: float = 0.2
    position_weight: float = 1.0
    angle_weight: float = 0.2
    weights: dict = field(default_factory=dict)
    decay: float = 0.0

    def __post_init__(self):
        if not self.window_s > 0:
            raise ParameterError(f"window_s must be > 0 seconds, got {self.window_s}")
        if self.position_weight < 0 or self.angle_weight < 0 or self.decay < 0:
            raise ParameterError("position_weight, angle_weight and decay must be >= 0, got "
                                 f"{self.position_weight}, {self.angle_weight}, {self.decay}")

    def window(self, fps: float) -> int:
        """Window length in frames at ``fps``."""
        return max(2, int(round(self.window_s * fps)))

    def frame_weights(self, fps: float) -> np.ndarray:
        """``(W,)`` window weights ``w_i``, summing to 1."""
        n = self.window(fps)
        w = np.exp(-self.decay * np.arange(n) / n)
        return w / w.sum()


def body_tracks(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Global positions ``(F, J, 3)`` and orientations ``(F, J, 4)`` of every joint (body) of ``motion``."""
    rot, pos = forward_kinematics(motion)
    return pos, rot


def body_weights(names, config: SearchConfig) -> tuple[np.ndarray, np.ndarray]:
    """``(J,)`` position and angle weights for bodies ``names`` under ``config``."""
    unknown = set(config.weights) - set(names)
    if unknown:
        raise ParameterError(f"weights name bodies the skeleton lacks: {sorted(unknown)}; bodies: {list(names)}")
    wp = np.array([config.weights.get(n, (config.position_weight, config.angle_weight))[0] for n in names])
    wt = np.array([config.weights.get(n, (config.position_weight, config.angle_weight))[1] for n in names])
    return wp.astype(np.float64), wt.astype(np.float64)


@dataclass(frozen=True)
class Windows:
    """Every window of ``W`` frames of some body tracks, each in the ground frame of its first frame.

    Attributes:
        pos: ``(N, W, J, 3)`` positions.
        rot: ``(N, W, J, 4)`` orientations.
        ground: ``(N, 3)`` ground transform (x, y, heading) of each window's first frame.
    """

    pos: np.ndarray
    rot: np.ndarray
    ground: np.ndarray

    def __len__(self) -> int:
        return len(self.pos)


def windows(pos: np.ndarray, rot: np.ndarray, window: int, root: int = 0) -> Windows:
    """All windows of ``window`` frames of body tracks ``pos (F, J, 3)``, ``rot (F, J, 4)``.

    Window ``s`` covers frames ``s .. s + window - 1`` and is expressed in the ground frame of frame ``s``
    (the root body ``root`` gives floor position and heading). ``F - window + 1`` windows (none when the
    track is shorter than the window).
    """
    pos = np.asarray(pos, dtype=np.float64)
    rot = np.asarray(rot, dtype=np.float64)
    f = len(pos)
    n = f - window + 1
    if n <= 0:
        j = pos.shape[1]
        return Windows(np.zeros((0, window, j, 3)), np.zeros((0, window, j, 4)), np.zeros((0, 3)))
    g = xform.from_root(pos[:n, root], rot[:n, root])
    q_inv = quat.conj(quat.from_heading(g[:, 2]))  # (n, 4)
    idx = np.arange(n)[:, None] + np.arange(window)[None, :]  # (n, W)
    p = pos[idx] - np.concatenate([g[:, :2], np.zeros((n, 1))], axis=1)[:, None, None, :]
    p = quat.mul_vec(q_inv[:, None, None, :], p)
    r = quat.mul(q_inv[:, None, None, :], rot[idx])
    return Windows(p, r, g)


# long kernel: the whole error D for every (window, window) pair in one compiled loop nest
@numba.njit(cache=True, fastmath=_NO_REASSOC, parallel=True)
def _errors_kernel(sp, sr, lp, lr, wp, wt, ww, out):  # pragma: no cover - compiled
    s_n, w_n, j_n = sp.shape[0], sp.shape[1], sp.shape[2]
    m_n = lp.shape[0]
    for s in numba.prange(s_n):
        for m in range(m_n):
            acc = 0.0
            for i in range(w_n):
                row = 0.0
                for j in range(j_n):
                    dx = sp[s, i, j, 0] - lp[m, i, j, 0]
                    dy = sp[s, i, j, 1] - lp[m, i, j, 1]
                    dz = sp[s, i, j, 2] - lp[m, i, j, 2]
                    d = np.sqrt(dx * dx + dy * dy + dz * dz)
                    c = abs(sr[s, i, j, 0] * lr[m, i, j, 0] + sr[s, i, j, 1] * lr[m, i, j, 1]
                            + sr[s, i, j, 2] * lr[m, i, j, 2] + sr[s, i, j, 3] * lr[m, i, j, 3])
                    if c > 1.0:
                        c = 1.0
                    # 4 sin(angle / 4): the rotation angle to within 1 % up to 50 degrees, monotone.
                    row += wp[j] * d + wt[j] * 2.0 * np.sqrt(2.0 - 2.0 * c)
                acc += ww[i] * row
            out[s, m] = acc


def window_errors(sim: Windows, lib: Windows, wp: np.ndarray, wt: np.ndarray, ww: np.ndarray) -> np.ndarray:
    """``(S, M)`` error D between every simulation window and every library window.

    Args:
        sim, lib: :class:`Windows` of the same window length and bodies.
        wp, wt: ``(J,)`` position and angle weights.
        ww: ``(W,)`` window weights.
    """
    if sim.pos.shape[1:] != lib.pos.shape[1:]:
        raise ParameterError(f"windows must have the same shape (W, J, 3): simulation {sim.pos.shape[1:]}, "
                             f"library {lib.pos.shape[1:]}")
    out = np.empty((len(sim), len(lib)))
    if out.size:
        _errors_kernel(np.ascontiguousarray(sim.pos), np.ascontiguousarray(sim.rot),
                       np.ascontiguousarray(lib.pos), np.ascontiguousarray(lib.rot),
                       np.ascontiguousarray(wp, dtype=np.float64), np.ascontiguousarray(wt, dtype=np.float64),
                       np.ascontiguousarray(ww, dtype=np.float64), out)
    return out


@dataclass(frozen=True)
class SearchResult:
    """The best (clip, simulation frame, clip frame) over the searched clips.

    Attributes:
        clip: index of the best clip in the library.
        sim_frame: first frame of the best window in the simulated segment.
        clip_frame: first frame of the best window in the clip.
        error: its error D.
        per_clip: ``(K,)`` best error of each clip (inf where a clip is shorter than the window or
            was not searched).
        surfaces: per clip, the ``(S, M_k)`` error surface over (simulation frame, clip frame), or None
            unless asked for.
    """

    clip: int
    sim_frame: int
    clip_frame: int
    error: float
    per_clip: np.ndarray
    surfaces: tuple | None = None


def exhaustive(sim: Windows, library, clips=None, keep_surfaces: bool = False) -> SearchResult:
    """Search every clip of ``library`` (a :class:`kinodyn.response.library.ReactionLibrary`) and every
    pair of frames for the smallest error D against the simulated windows ``sim``.

    Args:
        sim: :class:`Windows` of the simulated segment (same window length and bodies as the library).
        library: the reaction library (its ``windows``, ``rows``, ``weights``).
        clips: optional indices of the clips to search (default all).
        keep_surfaces: also return each clip's error surface (for plots).
    """
    if len(sim) == 0:
        raise ParameterError("the simulated segment is shorter than the search window")
    wp, wt, ww = library.weights
    d = window_errors(sim, library.windows, wp, wt, ww)  # (S, rows)
    k = len(library)
    per_clip = np.full(k, np.inf)
    best = (np.inf, -1, -1, -1)
    surfaces = []
    wanted = range(k) if clips is None else [int(c) for c in clips]
    for c in range(k):
        a, b = library.rows[c]
        if c not in wanted or b <= a:
            surfaces.append(None)
            continue
        surf = d[:, a:b]
        flat = int(np.argmin(surf))
        s, m = divmod(flat, surf.shape[1])
        per_clip[c] = surf[s, m]
        if surf[s, m] < best[0]:
            best = (float(surf[s, m]), c, s, m)
        surfaces.append(surf if keep_surfaces else None)
    if best[1] < 0:
        raise ParameterError("no searched clip is as long as the search window")
    return SearchResult(best[1], best[2], best[3], best[0], per_clip, tuple(surfaces) if keep_surfaces else None)
