"""Support phases: the per-clip sequence over {RS, LS, DS, FLIGHT}, its algebra and its extension.

Ménardais, Multon, Kulpa, Arnaldi, "Synchronization for dynamic blending of motions" (support-phase
synchronization), sections 4.1 to 4.3. A clip's *sequence of support phases* lists which feet carry
the body, element by element: ``RS`` right foot only, ``LS`` left foot only, ``DS`` both, ``FLIGHT``
none (the paper's empty set). ``ERR`` is the result of combining two incompatible elements.

The algebraic relation (4.1) ``a (+) b`` is the strike constraint of blending an element ``a`` with an
element ``b``: ``DS`` is neutral, ``FLIGHT`` absorbing, ``ERR`` absorbs ``RS``, ``LS`` and ``DS``, and
``RS (+) LS = ERR``. It is the join of the lattice ``DS < RS, LS < ERR < FLIGHT``; with the codes below
it is exactly a bitwise OR (``DS=0b000, RS=0b001, LS=0b010, ERR=0b011, FLIGHT=0b111``), hence
commutative, associative and idempotent, and vectorized with ``numpy.bitwise_or``.

Sequences (4.2) come from foot contacts (:mod:`kinodyn.contacts`: a foot touches when low *and* slow,
the paper's two parameters); consecutive equal elements are merged and durations kept. Cyclic clips
are marked; when a cyclic clip starts and ends in the same phase the two pieces are one element that
straddles the loop point (its start is negative). Extension (4.3): a cyclic sequence repeats whole;
any other sequence repeats its last element as long as needed.

The one encoding of support phases in kinodyn is :class:`Phase`; figures, the viewer and videos draw
them with :data:`PHASE_COLORS` and show them as time spans from :func:`time_spans`.

Units: seconds. Shapes: ``K`` elements, ``F`` frames.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from kinodyn.errors import ParameterError

__all__ = [
    "DS",
    "ERR",
    "FLIGHT",
    "LS",
    "PHASES",
    "PHASE_COLORS",
    "RS",
    "SUPPORT_PHASES",
    "Phase",
    "PhaseConfig",
    "PhaseSequence",
    "combine",
    "combine_all",
    "compatible",
    "contact_spans",
    "frame_phases",
    "from_labels",
    "from_motion",
    "opposite",
    "phase_name",
    "runs",
    "time_spans",
]


class Phase(enum.IntEnum):
    """Support phase codes; ``a | b`` is the paper's relation ``a (+) b``."""

    DS = 0b000
    RS = 0b001
    LS = 0b010
    ERR = 0b011
    FLIGHT = 0b111


DS, RS, LS, ERR, FLIGHT = Phase.DS, Phase.RS, Phase.LS, Phase.ERR, Phase.FLIGHT
#: Every element of the paper's set FS.
PHASES = (RS, LS, DS, FLIGHT, ERR)
#: The elements a clip's sequence is made of.
SUPPORT_PHASES = (RS, LS, DS, FLIGHT)
_NAMES = {int(p): p.name for p in Phase}
#: Colour of each phase code in every picture (``"#rrggbb"``).
PHASE_COLORS = {int(RS): "#f28e2b", int(LS): "#59a14f", int(DS): "#4e79a7", int(FLIGHT): "#c9ced6",
                int(ERR): "#e15759"}


def phase_name(p) -> str:
    """``"RS"``, ``"LS"``, ``"DS"``, ``"FLIGHT"`` or ``"ERR"`` for a phase code."""
    try:
        return _NAMES[int(p)]
    except KeyError:
        raise ParameterError(f"not a support-phase code: {p!r} (expected one of {sorted(_NAMES)})") from None


def combine(a, b):
    """The relation ``a (+) b`` (section 4.1), elementwise on codes or arrays of codes."""
    if isinstance(a, (int, np.integer)) and isinstance(b, (int, np.integer)):
        return Phase(int(a) | int(b))
    return np.bitwise_or(np.asarray(a, dtype=np.int8), np.asarray(b, dtype=np.int8))


def combine_all(phases, axis: int = 0):
    """``(+)`` over ``axis`` of an array of codes (equation 2); an empty list gives ``DS`` (the neutral)."""
    a = np.asarray(phases, dtype=np.int8)
    if a.shape[axis] == 0:
        return np.zeros(np.delete(a.shape, axis), dtype=np.int8) if a.ndim > 1 else DS
    out = np.bitwise_or.reduce(a, axis=axis)
    return Phase(int(out)) if np.ndim(out) == 0 else out


def compatible(*sequences) -> np.ndarray:
    """Element-by-element compatibility of ``n`` equally long code sequences (equation 3).

    Returns ``(K,)`` bool: True where the combination of the ``n`` elements is not ``ERR``.
    """
    if not sequences:
        raise ParameterError("compatible() needs at least one sequence")
    stack = np.stack([np.asarray(s, dtype=np.int8) for s in sequences])
    return np.bitwise_or.reduce(stack, axis=0) != ERR


def opposite(p: Phase) -> Phase:
    """``LS`` for ``RS`` and ``RS`` for ``LS`` (the other single-support constraint)."""
    if p == RS:
        return LS
    if p == LS:
        return RS
    raise ParameterError(f"opposite() is defined for RS and LS, got {phase_name(p)}")


def frame_phases(left, right) -> np.ndarray:
    """``(F,)`` phase code of every frame from per-foot contact labels ``left, right (F,)`` bool."""
    left = np.asarray(left, dtype=bool)
    right = np.asarray(right, dtype=bool)
    if left.shape != right.shape or left.ndim != 1:
        raise ParameterError(f"left and right labels must be equal (F,) arrays, got {left.shape} and {right.shape}")
    out = np.full(left.shape, int(FLIGHT), dtype=np.int8)
    out[left & right] = DS
    out[left & ~right] = LS
    out[~left & right] = RS
    return out


def runs(codes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of equal values of ``codes (F,)``: ``values (K,)``, ``starts (K,)``, ``stops (K,)`` (exclusive)."""
    c = np.asarray(codes)
    if len(c) == 0:
        e = np.zeros(0, dtype=np.int64)
        return c[:0], e, e
    cut = np.nonzero(c[1:] != c[:-1])[0] + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [len(c)]])
    return c[starts], starts, stops


def contact_spans(labels, fps: float, start: float = 0.0, names=None) -> list[tuple[float, float, str]]:
    """Support-phase spans ``(t0, t1, name)`` from foot contacts, consecutive equal phases merged.

    Args:
        labels: ``(F, 2)`` bool contacts, columns left and right.
        fps: their frame rate; frame ``k`` covers ``[start + k / fps, start + (k + 1) / fps)``.
        start: time of frame 0 (s).
        names: phase code -> name shown (default :func:`phase_name`).
    """
    labels = np.asarray(labels, dtype=bool)
    if labels.ndim != 2 or labels.shape[1] != 2:
        raise ParameterError(f"labels must have shape (F, 2), got {labels.shape}")
    codes = frame_phases(labels[:, 0], labels[:, 1])
    frames = np.arange(len(codes) + 1)
    spans = time_spans(codes, start + frames[:-1] / fps, start + frames[1:] / fps)
    name = phase_name if names is None else names.__getitem__
    return [(a, b, name(c)) for a, b, c in spans]


def time_spans(codes, begin, end, valid=None) -> list[tuple[float, float, int]]:
    """Runs of equal ``codes (F,)`` as time spans ``(t0, t1, code)``.

    Frame ``k`` covers ``[begin[k], end[k])`` (both ``(F,)``, seconds); a run of frames ``i..j`` gives
    ``(begin[i], end[j], code)``. Frames where ``valid (F,)`` bool is False are left out and split runs.
    """
    c = np.asarray(codes)
    v = np.ones(len(c), dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    if v.shape != c.shape or c.ndim != 1:
        raise ParameterError(f"codes and valid must be equal (F,) arrays, got {c.shape} and {v.shape}")
    if len(c) == 0:
        return []
    cut = np.nonzero((c[1:] != c[:-1]) | (v[1:] != v[:-1]))[0] + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [len(c)]])
    b = np.asarray(begin, dtype=np.float64)
    e = np.asarray(end, dtype=np.float64)
    return [(float(b[i]), float(e[j - 1]), int(c[i])) for i, j in zip(starts, stops) if v[i]]


@dataclass(frozen=True)
class PhaseConfig:
    """How a clip's sequence is built from its foot contacts.

    Attributes:
        min_duration: elements shorter than this many seconds are merged into a neighbour (contact
            detection flicker would otherwise create one-frame flights or double supports that no
            animator would call a phase). 0 keeps every element.
    """

    min_duration: float = 0.04

    def __post_init__(self):
        if not (np.isfinite(self.min_duration) and self.min_duration >= 0):
            raise ParameterError(f"min_duration must be a non-negative number of seconds, got {self.min_duration}")


@dataclass(frozen=True, eq=False)
class PhaseSequence:
    """The sequence of support phases of a clip or an action (section 4.2).

    Element ``i`` covers clip times ``[start + sum(durations[:i]), start + sum(durations[:i+1]))``.

    Attributes:
        phases: ``(K,)`` int8 phase codes, no two consecutive equal (except a one-element cyclic sequence
            repeated by extension), never ``ERR``.
        durations: ``(K,)`` seconds, positive.
        cyclic: the clip loops; its sequence repeats whole (section 4.3).
        start: clip time of the first element's start; negative for a cyclic clip whose first element
            straddles the loop point.
    """

    phases: np.ndarray
    durations: np.ndarray
    cyclic: bool = False
    start: float = 0.0

    def __post_init__(self):
        p = np.asarray(self.phases, dtype=np.int8).copy()
        d = np.asarray(self.durations, dtype=np.float64).copy()
        if p.ndim != 1 or d.shape != p.shape or len(p) == 0:
            raise ParameterError(f"phases and durations must be equal non-empty (K,) arrays, got {p.shape} "
                                 f"and {d.shape}")
        bad = ~np.isin(p, [int(x) for x in SUPPORT_PHASES])
        if np.any(bad):
            raise ParameterError(f"phases must be RS, LS, DS or FLIGHT codes, got {int(p[bad][0])} at element "
                                 f"{int(np.argmax(bad))}")
        if not np.all(np.isfinite(d)) or np.any(d <= 0):
            raise ParameterError(f"durations must be positive seconds, got minimum {d.min()}")
        if len(p) > 1 and np.any(p[1:] == p[:-1]):
            raise ParameterError("consecutive elements of a phase sequence must differ (merge them first)")
        if self.cyclic and len(p) > 1 and p[0] == p[-1]:
            raise ParameterError("a cyclic sequence must not start and end with the same phase (merge them)")
        if not np.isfinite(self.start):
            raise ParameterError(f"start must be finite, got {self.start}")
        p.setflags(write=False)
        d.setflags(write=False)
        object.__setattr__(self, "phases", p)
        object.__setattr__(self, "durations", d)
        object.__setattr__(self, "cyclic", bool(self.cyclic))
        object.__setattr__(self, "start", float(self.start))
        b = self.start + np.concatenate([[0.0], np.cumsum(d)])
        b.setflags(write=False)
        object.__setattr__(self, "_bounds", b)

    # ------------------------------------------------------------------ basics
    def __len__(self) -> int:
        return len(self.phases)

    @property
    def bounds(self) -> np.ndarray:
        """``(K + 1,)`` clip times of the element boundaries."""
        return self._bounds

    @property
    def total(self) -> float:
        """Sum of the durations (one period for a cyclic clip)."""
        return float(self._bounds[-1] - self._bounds[0])

    def __repr__(self) -> str:
        body = " ".join(f"{phase_name(p)}:{d:.3g}" for p, d in zip(self.phases, self.durations))
        return f"PhaseSequence({body}{', cyclic' if self.cyclic else ''}, start={self.start:.3g})"

    def names(self) -> list[str]:
        return [phase_name(p) for p in self.phases]

    # ------------------------------------------------------------------ extension (4.3)
    def element(self, k: int) -> tuple[int, float, float]:
        """Element ``k >= 0`` of the extended sequence: ``(phase, t0, t1)`` in extended clip time.

        A cyclic sequence repeats whole (element ``k`` is element ``k mod K`` one period later per
        cycle); any other sequence repeats its last element, each copy as long as the last element.
        Times past the clip's end are where a non-cyclic clip holds its last pose.
        """
        k = int(k)
        if k < 0:
            raise ParameterError(f"element index must be >= 0, got {k}")
        n = len(self.phases)
        b = self._bounds
        if self.cyclic:
            c, i = divmod(k, n)
            off = c * self.total
            return int(self.phases[i]), float(b[i] + off), float(b[i + 1] + off)
        if k < n:
            return int(self.phases[k]), float(b[k]), float(b[k + 1])
        dl = float(self.durations[-1])
        t0 = float(b[-1]) + (k - n) * dl
        return int(self.phases[-1]), t0, t0 + dl

    def extended(self, n: int, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Phases ``(n,)`` and durations ``(n,)`` of elements ``first .. first + n - 1`` (section 4.3)."""
        if n < 0:
            raise ParameterError(f"n must be >= 0, got {n}")
        k = np.arange(first, first + n)
        m = len(self.phases)
        idx = k % m if self.cyclic else np.minimum(k, m - 1)
        return self.phases[idx].copy(), self.durations[idx].copy()

    def index_at(self, t) -> np.ndarray:
        """Extended element index of clip times ``t`` (scalar or array), the inverse of :meth:`element`."""
        t = np.asarray(t, dtype=np.float64)
        b = self._bounds
        n = len(self.phases)
        if self.cyclic:
            c = np.floor((t - b[0]) / self.total)
            u = t - c * self.total
            i = np.clip(np.searchsorted(b, u, side="right") - 1, 0, n - 1)
            return (c * n + i).astype(np.int64)
        i = np.searchsorted(b, t, side="right") - 1
        past = t >= b[-1]
        extra = np.floor((t - b[-1]) / self.durations[-1]).astype(np.int64)
        return np.where(past, n + np.maximum(extra, 0), np.maximum(i, 0)).astype(np.int64)

    def phase_at(self, t) -> np.ndarray:
        """Phase code at clip times ``t`` (extended: cyclic wraps, non-cyclic holds the last element)."""
        k = np.asarray(self.index_at(t))
        n = len(self.phases)
        idx = k % n if self.cyclic else np.minimum(k, n - 1)
        return self.phases[idx]

    def left_share(self, t) -> np.ndarray:
        """Share of the body's weight on the left foot at clip times ``t`` implied by the sequence.

        1 in ``LS``, 0 in ``RS``; over a ``DS`` element the weight passes linearly from the single
        support before it to the single support after it (a double support between two steps of the
        same foot keeps that foot's share; a missing or non-single neighbour counts as 1/2). Flight
        gives 1/2. Used to decide which planted foot anchors the body (see
        :mod:`kinodyn.blend.footlock`) without a jump when a foot lifts.
        """
        t = np.asarray(t, dtype=np.float64)
        k = np.asarray(self.index_at(t))
        n = len(self.phases)
        share = np.where(self.phases == LS, 1.0, np.where(self.phases == RS, 0.0, 0.5))
        if self.cyclic:
            i = k % n
            prev, nxt = share[(i - 1) % n], share[(i + 1) % n]
            c = np.floor((t - self._bounds[0]) / self.total)
            u = t - c * self.total
            b0, b1 = self._bounds[i], self._bounds[i + 1]
        else:
            i = np.minimum(k, n - 1)
            prev = np.where(i > 0, share[np.maximum(i - 1, 0)], 0.5)
            nxt = np.where(i < n - 1, share[np.minimum(i + 1, n - 1)], 0.5)
            u = np.minimum(t, self._bounds[-1])   # past the end the last element repeats: hold its end
            b0, b1 = self._bounds[i], self._bounds[i + 1]
        frac = np.clip((u - b0) / np.maximum(b1 - b0, 1e-12), 0.0, 1.0)
        ds = self.phases[i] == DS
        return np.where(ds, (1.0 - frac) * prev + frac * nxt, share[i])

    # ------------------------------------------------------------------ adaptation
    def time_scaled(self, speed: float) -> PhaseSequence:
        """The sequence of the clip played ``speed`` times faster (an action that scales time adapts its
        sequence the same way it adapts its motion: durations and start divided by ``speed``)."""
        if not (np.isfinite(speed) and speed > 0):
            raise ParameterError(f"speed must be a positive number, got {speed}")
        return PhaseSequence(self.phases, self.durations / speed, self.cyclic, self.start / speed)


def _merge_short(codes, starts, stops, min_len: float, cyclic: bool):
    """Merge runs shorter than ``min_len`` frames into their longer neighbour, then equal neighbours.

    For a cyclic run list the first and last runs are neighbours; when they become equal the last run
    is folded into the first, whose start moves before 0. Returns ``codes, starts, stops``.
    """
    codes = [int(c) for c in codes]
    starts = [int(x) for x in starts]
    stops = [int(x) for x in stops]
    while len(codes) > 1:
        lens = [b - a for a, b in zip(starts, stops)]
        i = int(np.argmin(lens))
        if lens[i] >= min_len:
            break
        n = len(codes)
        cands = [j for j in ((i - 1) % n if cyclic or i > 0 else None, (i + 1) % n if cyclic or i < n - 1 else None)
                 if j is not None and j != i]
        codes[i] = codes[max(cands, key=lambda c: lens[c])]
        c2, s2, e2 = [codes[0]], [starts[0]], [stops[0]]
        for c, x, y in zip(codes[1:], starts[1:], stops[1:]):
            if c == c2[-1]:
                e2[-1] = y
            else:
                c2.append(c)
                s2.append(x)
                e2.append(y)
        if cyclic and len(c2) > 1 and c2[0] == c2[-1]:
            s2[0] -= e2[-1] - s2[-1]
            c2, s2, e2 = c2[:-1], s2[:-1], e2[:-1]
        codes, starts, stops = c2, s2, e2
    return np.array(codes, dtype=np.int8), np.array(starts, dtype=np.int64), np.array(stops, dtype=np.int64)


def _merge_loop_point(vals: np.ndarray, starts: np.ndarray, stops: np.ndarray):
    """A cyclic run list whose first and last runs are equal: one run straddling the loop point.

    The merged run starts before 0 (``starts[0]`` becomes negative); returns ``vals, starts``.
    """
    if len(vals) > 1 and vals[0] == vals[-1]:
        shift = int(stops[-1] - starts[-1])
        vals, starts = vals[:-1], starts[:-1].copy()
        starts[0] -= shift
    return vals, starts


def from_labels(left, right, fps: float, cyclic: bool = False, config: PhaseConfig = PhaseConfig()) -> PhaseSequence:
    """The sequence of a clip from per-frame foot contact labels (section 4.2).

    Frame ``f`` stands for clip time ``f / fps``; element boundaries fall half-way between frames. A cyclic
    clip's last frame equals its first, so frames ``0 .. F-2`` make one period of ``(F - 1) / fps`` s.

    Args:
        left, right: ``(F,)`` bool contact labels.
        fps: frame rate of the labels.
        cyclic: the clip loops.
        config: :class:`PhaseConfig`.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"fps must be positive, got {fps}")
    codes = frame_phases(left, right)
    n = len(codes)
    if n < 2:
        raise ParameterError(f"a phase sequence needs at least 2 frames, got {n}")
    if cyclic:
        codes = codes[:-1]
    vals, starts, stops = runs(codes)
    min_len = config.min_duration * fps
    if cyclic:
        vals, starts = _merge_loop_point(vals, starts, stops)
        vals, starts, stops = _merge_short(vals, starts, np.concatenate([starts[1:], [starts[0] + n - 1]]),
                                           min_len, True)
        vals, starts = _merge_loop_point(vals, starts, stops)
        if len(vals) == 1:
            return PhaseSequence(vals, np.array([(n - 1) / fps]), True, 0.0)
        b = np.concatenate([starts, [starts[0] + n - 1]]).astype(np.float64) - 0.5
        return PhaseSequence(vals, np.diff(b) / fps, True, b[0] / fps)
    vals, starts, stops = _merge_short(vals, starts, stops, min_len, False)
    b = np.concatenate([starts, [stops[-1]]]).astype(np.float64) - 0.5
    b[0], b[-1] = 0.0, n - 1.0
    return PhaseSequence(vals, np.diff(b) / fps, False, 0.0)


def from_motion(motion, cyclic: bool = False, contact_config=None, config: PhaseConfig = PhaseConfig(),
                feet=None) -> PhaseSequence:
    """The sequence of a :class:`~kinodyn.motion.Motion` from its detected foot contacts.

    Args:
        motion: the clip.
        cyclic: whether it loops (the built-in library's ``info(name).cyclic``).
        contact_config: :class:`kinodyn.contacts.ContactConfig` (height and speed thresholds).
        config: :class:`PhaseConfig`.
        feet: optional foot joint indices per side (see :func:`kinodyn.contacts.find_feet`).
    """
    from kinodyn import contacts

    cc = contacts.ContactConfig() if contact_config is None else contact_config
    c = contacts.detect(motion, cc, feet)
    return from_labels(c.labels["left"], c.labels["right"], motion.fps, cyclic, config)
