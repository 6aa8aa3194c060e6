"""The blend's clip stores: the neutral double-support pose the mixer blends in."""

from __future__ import annotations

import pytest

from kinodyn.blend.library import builtin, neutral_source, sequences
from kinodyn.phases import DS


def test_the_neutral_pose_is_the_named_clip_else_idle_else_the_first_double_support():
    store = builtin(["walk", "idle", "run"])
    seqs = sequences(store)
    assert neutral_source(store, seqs, "run") == (store.index("run"), 0.0)
    assert neutral_source(store, seqs) == (store.index("idle"), 0.0)
    store = builtin(["walk", "run"])
    seqs = sequences(store)
    k, t = neutral_source(store, seqs)
    seq = seqs[0]
    i = next(i for i, p in enumerate(seq.phases) if p == DS)
    assert k == 0 and t == pytest.approx((seq.bounds[i] + seq.bounds[i + 1]) / 2) and t > 0.0
