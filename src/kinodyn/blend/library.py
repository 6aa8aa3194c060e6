"""Clips for blending: the packed :class:`~kinodyn.clips.ClipStore` with each clip's support.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, section 4.2: every clip the mixer
plays carries its support-phase sequence, detected from foot contacts unless given. One contact
detection per clip gives both the sequence and the height of its planted feet
(:func:`kinodyn.clips.rest_height`), which the support constraints keep. Every function returns a new
store (stores are frozen).

Uses: :mod:`kinodyn.clips` (the store), :mod:`kinodyn.contacts`, :mod:`kinodyn.phases`,
:mod:`kinodyn.blend.parametric` (blended cycles).
"""

from __future__ import annotations

from kinodyn import contacts
from kinodyn import phases as _phases
from kinodyn.blend.parametric import blend_cycles
from kinodyn.phases import PhaseConfig, PhaseSequence
from kinodyn.clips import ClipStore, ClipSupport, rest_height
from kinodyn.errors import MotionError, ParameterError, UnknownNameError
from kinodyn.motion import Motion

__all__ = ["add_blend", "add_clip", "builtin", "neutral_source", "sequence", "sequences"]


def add_clip(store: ClipStore, name: str, motion: Motion, cyclic: bool = False,
             sequence: PhaseSequence | None = None, feet=None, contact_config=None,
             phase_config: PhaseConfig | None = None) -> ClipStore:
    """``store`` with one more clip and its support.

    Args:
        store: the :class:`~kinodyn.clips.ClipStore` to add to.
        name: unique name.
        motion: the clip (see :meth:`kinodyn.clips.ClipStore.add`).
        cyclic: the clip loops (closed by :func:`kinodyn.clips.close_loop`).
        sequence: its support-phase sequence; detected from foot contacts when ``None``.
        feet: foot joints for contact detection (see :func:`kinodyn.contacts.find_feet`).
        contact_config: :class:`kinodyn.contacts.ContactConfig` used to build sequences.
        phase_config: :class:`~kinodyn.phases.PhaseConfig` (default: its defaults).
    """
    if not isinstance(store, ClipStore):
        raise ParameterError(f"store must be a ClipStore, got {type(store).__name__}")
    motion = store.prepare(name, motion)
    if sequence is not None and sequence.cyclic != bool(cyclic):
        raise ParameterError(f"clip {name!r}: sequence.cyclic={sequence.cyclic} but cyclic={cyclic}")
    try:
        found = contacts.detect(motion, contact_config or contacts.ContactConfig(), feet)
    except UnknownNameError:
        if sequence is None:
            raise
        found = None
    if sequence is None:
        sequence = _phases.from_labels(found.labels["left"], found.labels["right"], motion.fps, cyclic,
                                       phase_config or PhaseConfig())
    t = motion.times()
    support = ClipSupport(sequence.phases, sequence.durations, float(sequence.start),
                          sequence.phase_at(t).astype("int8"), sequence.left_share(t), rest_height(found))
    return store.add(name, motion, cyclic, support)


def sequence(store: ClipStore, name) -> PhaseSequence:
    """The support-phase sequence of a clip of ``store``."""
    k = store.index(name)
    phases, durations, start = store.support(k)
    if not len(phases):
        raise MotionError(f"clip {store.names[k]!r} has no support-phase sequence in this store")
    return PhaseSequence(phases, durations, bool(store.is_cyclic[k]), start)


def sequences(store: ClipStore) -> list[PhaseSequence]:
    """Every clip's sequence, in store order."""
    return [sequence(store, k) for k in range(len(store))]


def neutral_source(store: ClipStore, seqs: list[PhaseSequence], neutral: str | None = None) -> tuple[int, float]:
    """Clip index and clip time of the neutral double-support pose the mixer blends in: the clip named
    ``neutral`` at its start, else ``idle`` at its start, else the middle of the first clip's first
    double support (its start when it has none); ``seqs`` are the store's sequences (:func:`sequences`)."""
    if neutral is None and "idle" in store.names:
        neutral = "idle"
    if neutral is not None:
        return store.index(neutral), 0.0
    seq = seqs[0]
    ds = [i for i, p in enumerate(seq.phases) if p == _phases.DS]
    return 0, 0.0 if not ds else max(0.0, (seq.bounds[ds[0]] + seq.bounds[ds[0] + 1]) / 2)


def add_blend(store: ClipStore, name: str, weights: dict) -> ClipStore:
    """``store`` with the cycle between its clips at ``weights`` (``{clip: weight}``) added, a parametric
    model (:func:`kinodyn.blend.parametric.blend_cycles`).

    The clips must be cyclic and share a support pattern; the new clip's sequence is built with it.
    """
    if not isinstance(weights, dict) or not weights:
        raise ParameterError(f"weights must map clip names to weights, got {weights!r}")
    idx = [store.index(k) for k in weights]
    for i in idx:
        if not store.is_cyclic[i]:
            raise MotionError(f"clip {store.names[i]!r} is not cyclic; only cycles blend into a new cycle")
    motions = [store.motion(i) for i in idx]
    motion, seq = blend_cycles(motions, list(weights.values()), [sequence(store, i) for i in idx],
                               fps=motions[0].fps)
    return add_clip(store, name, motion.replace(name=name), cyclic=True, sequence=seq)


def builtin(names=None, contact_config=None, phase_config: PhaseConfig | None = None) -> ClipStore:
    """The built-in clips of :mod:`kinodyn.data.library` (all of them, or ``names``) with their support."""
    from kinodyn.data import library as data_lib
    from kinodyn.data.skeleton import humanoid

    store = ClipStore.empty(humanoid())
    for n in (data_lib.names() if names is None else names):
        store = add_clip(store, n, data_lib.load(n), data_lib.info(n).cyclic, contact_config=contact_config,
                         phase_config=phase_config)
    return store
