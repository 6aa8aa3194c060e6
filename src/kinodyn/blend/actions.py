"""Actions: one clip played on one character, started and stopped at any time, and its record.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, section 3: an *action* plays a clip
(or a clip adapted by a parametric model, such as a time scaling) with a priority and activation ramps.
:class:`ActionState` is its bookkeeping (the character owns it); :class:`Recording` the per-frame
record of one character (action times and weights) that analysis and plots read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from kinodyn.phases import PhaseSequence

__all__ = ["ActionRecord", "ActionState", "Recording"]


class ActionRecord(NamedTuple):
    """What became of one action (a frozen copy of its :class:`ActionState`, for analysis).

    Attributes:
        key: identifier; ``clip``: its clip's index in the store.
        seq: the adapted support-phase sequence; ``speed``: its time scaling; ``priority``.
        requested: time the start was asked for; ``t_on``: time it started (``None``: never);
        ``t_off``: time it was stopped (``None``: never).
    """

    key: object
    clip: int
    seq: PhaseSequence
    speed: float
    priority: float
    requested: float
    t_on: float | None
    t_off: float | None


@dataclass(eq=False)
class ActionState:
    """One action of one character (mutable bookkeeping; the mixer owns it).

    Attributes:
        key: identifier (unique per character).
        clip: library index.
        seq: the adapted support-phase sequence (time-scaled by ``speed``).
        speed: time scaling; clip time = action time * speed.
        priority: higher wins.
        ramp_in, ramp_out: activation and deactivation durations (s).
        requested: time the start was asked for.
        t_on: time it actually started (``None`` while waiting for synchronization).
        t_off: time it was stopped (``None``: playing).
        auto_stop: a non-cyclic action stops by itself so that it has faded out when its clip ends.
        h0: action time at the start (the first element's beginning).
        handover: stopped while another action waited for its synchronized start: it keeps playing
            until that action starts, then fades out (the character never falls back to the neutral
            pose between the two).
        free: ``(t, h)``: the action left the synchronizer at real time ``t`` and action time ``h`` (a
            locomotion cycle handing over to an in-place action at a closing step) and plays on at its
            own speed until it has faded out; ``None``: synchronized (or not synchronizing).
    """

    key: object
    clip: int
    seq: PhaseSequence
    speed: float
    priority: float
    ramp_in: float
    ramp_out: float
    requested: float
    t_on: float | None = None
    t_off: float | None = None
    auto_stop: bool = False
    h0: float = 0.0
    end_h: float = math.inf
    order: int = 0
    handover: bool = False
    free: tuple[float, float] | None = None

    def weight_params(self):
        return (math.inf if self.t_on is None else self.t_on, self.ramp_in,
                math.inf if self.t_off is None else self.t_off, self.ramp_out)

    def gone(self, t: float) -> bool:
        return self.t_off is not None and t >= self.t_off + self.ramp_out

    def record(self) -> ActionRecord:
        """A frozen copy of what the analysis needs."""
        return ActionRecord(self.key, self.clip, self.seq, self.speed, self.priority, self.requested, self.t_on,
                            self.t_off)


@dataclass
class Recording:
    """Per-frame record of one character: times, each action's action time and weight (NaN when absent),
    and how far the foot lock held each foot from the blended pose (:meth:`lock_offsets`)."""

    times: list = field(default_factory=list)
    action_time: dict = field(default_factory=dict)
    weight: dict = field(default_factory=dict)
    neutral: list = field(default_factory=list)
    lock_offset: list = field(default_factory=list)

    def lock_offsets(self) -> np.ndarray:
        """``(F, 2)`` metres between each held foot (left, right) and where the blended pose put it
        (:attr:`kinodyn.blend.footlock.FootLock.offset`); NaN where the foot is not held."""
        n = len(self.times)
        out = np.full((n, 2), np.nan)
        if self.lock_offset:
            out[:len(self.lock_offset)] = np.asarray(self.lock_offset[:n], dtype=np.float64)
        return out

    def arrays(self) -> dict:
        n = len(self.times)
        out = {"t": np.array(self.times), "neutral": np.array(self.neutral)}
        for k in self.action_time:
            h = np.full(n, np.nan)
            w = np.zeros(n)
            for i, v in self.action_time[k].items():
                h[i] = v
            for i, v in self.weight[k].items():
                w[i] = v
            out[k] = (h, w)
        return out

