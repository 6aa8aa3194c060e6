"""A parametric locomotion model: cycles of one support pattern blended by weights.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, section 3: an action may replay a
clip or adapt it as a parametric model does, and "when the actions are parametric models, they just
have to modify the sequence the same way as they adapt the motion". Here the model is the classic
registered blend of locomotion cycles (a slow and a fast walk give every walk in between): the cycles
share a support pattern (``DS LS DS RS`` for a walk), the blended cycle's element ``k`` lasts the
weighted sum of the cycles' element ``k`` durations, every cycle is time-warped element by element onto
that timeline, poses are averaged with the weights and the root's displacement over each frame is the
weighted sum of the cycles' displacements over the same phase. The blended motion and its sequence are
built together, so the sequence is adapted exactly as the motion is.

The result is an ordinary cyclic clip (``Motion`` plus ``PhaseSequence``) that the mixer plays, time
scales and synchronizes like any other; :func:`kinodyn.blend.library.add_blend` adds one to a
clip store, and a blend script's ``clips`` section accepts ``{mix: {walk: 0.5, slow_walk: 0.5}}``.

Shapes: ``C`` cycles, ``K`` elements, ``F`` frames, ``J`` joints. Units: seconds, metres.
"""

from __future__ import annotations

import numpy as np

from kinodyn.phases import PhaseSequence
from kinodyn.blend.pose import blend_rotations
from kinodyn.clips import ClipStore
from kinodyn.errors import MotionError, ParameterError
from kinodyn.math import quat, xform
from kinodyn.motion import Motion

__all__ = ["blend_cycles", "register_cycles"]


def register_cycles(sequences) -> list[int]:
    """For each cyclic sequence, the element index at which it matches the first sequence's pattern.

    Returns ``r`` such that ``sequences[i].phases`` rotated left by ``r[i]`` equals
    ``sequences[0].phases``.

    Raises:
        MotionError: a sequence is not cyclic or does not share the first one's support pattern.
    """
    ref = np.asarray(sequences[0].phases)
    out = []
    for i, s in enumerate(sequences):
        if not s.cyclic:
            raise MotionError(f"cycle {i} is not cyclic; a parametric blend needs looping cycles")
        p = np.asarray(s.phases)
        shift = [r for r in range(len(p)) if len(p) == len(ref) and np.array_equal(np.roll(p, -r), ref)]
        if not shift:
            raise MotionError(f"cycle {i} has the support pattern [{' '.join(s.names())}], not that of "
                              f"cycle 0 [{' '.join(sequences[0].names())}]; only cycles of one pattern "
                              "blend without sliding")
        out.append(shift[0])
    return out


def blend_cycles(motions, weights, sequences=None, fps: float | None = None, contact_config=None
                 ) -> tuple[Motion, PhaseSequence]:
    """The cycle between ``motions`` at ``weights``, and its support-phase sequence.

    Args:
        motions: ``C`` cyclic clips (one cycle each, last frame = first frame moved on) of the same
            skeleton topology; other bone lengths are retargeted to the first clip's skeleton.
        weights: ``(C,)`` non-negative weights (normalized here).
        sequences: their cyclic :class:`~kinodyn.phases.PhaseSequence`; detected from foot
            contacts when ``None``.
        fps: frame rate of the result (default: the first clip's).
        contact_config: :class:`kinodyn.contacts.ContactConfig` for detecting the sequences.

    Returns:
        ``(motion, sequence)``: one blended cycle starting at the first element of the first clip's
        pattern, and its cyclic sequence (element durations the weighted sums, scaled by at most half a
        frame so that the cycle lasts a whole number of frames).

    Raises:
        ParameterError: bad weights or fps; MotionError: cycles of different support patterns.
    """
    from kinodyn import phases as _phases

    motions = list(motions)
    if not motions or not all(isinstance(m, Motion) for m in motions):
        raise ParameterError("motions must be a non-empty list of Motion")
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (len(motions),) or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ParameterError(f"weights must be {len(motions)} non-negative numbers with a positive sum, "
                             f"got {weights!r}")
    w = w / w.sum()
    fps = float(motions[0].fps if fps is None else fps)
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"fps must be a positive number, got {fps}")
    if sequences is None:
        sequences = [_phases.from_motion(m, True, contact_config) for m in motions]
    sequences = list(sequences)
    if len(sequences) != len(motions):
        raise ParameterError(f"got {len(sequences)} sequences for {len(motions)} motions")
    shift = register_cycles(sequences)
    n = len(sequences[0])
    # element durations and starts of every cycle in the common order (C, K)
    dur = np.stack([np.roll(s.durations, -r) for s, r in zip(sequences, shift)])
    starts = []
    for s, r in zip(sequences, shift):
        b = s.bounds[:-1]
        starts.append(np.concatenate([b[r:], b[:r] + s.total]))
    starts = np.stack(starts)
    target = w @ dur
    frames = max(round(target.sum() * fps), 2)
    target *= (frames / fps) / target.sum()
    bounds = np.concatenate([[0.0], np.cumsum(target)])
    t = np.arange(frames + 1) / fps
    k = np.clip(np.searchsorted(bounds, t, side="right") - 1, 0, n - 1)
    u = np.clip((t - bounds[k]) / target[k], 0.0, 1.0)
    tau = starts[:, k] + u * dur[:, k]                       # (C, F): each cycle's clip time
    skeleton = motions[0].skeleton
    lib = ClipStore.empty(skeleton)
    for i, m in enumerate(motions):
        lib = lib.add(str(i), m, cyclic=True)
    clip = np.broadcast_to(np.arange(len(motions))[:, None], tau.shape)
    rot, z, delta = lib.sample(clip[:, 1:], tau[:, 1:], tau[:, :-1])   # (C, F-1, ...)
    rot0, z0 = lib.sample(clip[:, :1], tau[:, :1])
    rot = np.concatenate([rot0, rot], axis=1)
    z = np.concatenate([z0, z], axis=1)
    q = blend_rotations(np.swapaxes(rot, 0, 1), np.broadcast_to(w, (frames + 1, len(w))),
                        quat.identity((skeleton.num_joints,)), np.zeros(frames + 1))
    # integrate the blended displacement over each frame in the character's frame (xform.compose chained)
    step = np.einsum("c,cfk->fk", w, delta)
    heading = np.concatenate([[0.0], np.cumsum(step[:, 2])])
    ground = np.concatenate([np.zeros((frames, 2)), heading[:-1, None]], axis=1)
    xy = np.concatenate([np.zeros((1, 2)), np.cumsum(xform.apply_vector(ground, step[:, :2]), axis=0)])
    q[:, 0] = quat.mul(quat.from_heading(heading), q[:, 0])
    root = np.concatenate([xy, (w @ z)[:, None]], axis=1)
    label = "+".join(f"{m.name or i}:{wi:.2f}" for i, (m, wi) in enumerate(zip(motions, w)))
    motion = Motion(skeleton, root, q, fps, name=f"blend({label})")
    return motion, PhaseSequence(sequences[0].phases, target, cyclic=True)
