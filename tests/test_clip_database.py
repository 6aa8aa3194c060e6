"""Packed clip databases: packing, global frame indexing, npz round trip, validation."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn.errors import FileFormatError, MotionError, UnknownNameError
from kinodyn.io.library import ClipDatabase
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton


def _clips(rng) -> list[Motion]:
    sk = Skeleton(("root", "a", "b"), np.array([-1, 0, 1]), np.array([[0, 0, 0], [0, 0, 0.5], [0.3, 0, 0]]))
    out = []
    for i, n in enumerate((5, 9, 3)):
        out.append(Motion(sk, rng.normal(size=(n, 3)), quat.normalize(rng.normal(size=(n, 3, 4))), 30.0,
                          name=f"c{i}"))
    return out


def test_pack_index_and_round_trip(tmp_path, rng):
    clips = _clips(rng)
    db = ClipDatabase.from_motions(clips, tags=[("walk",), ("hit", "back"), ()])
    assert len(db) == 3 and db.num_frames == 17
    np.testing.assert_array_equal(db.starts, [0, 5, 14])
    np.testing.assert_array_equal(db.clip_of_frame([0, 4, 5, 13, 14, 16]), [0, 0, 1, 1, 2, 2])
    np.testing.assert_array_equal(db.clip("c1").local_rot, clips[1].local_rot)
    assert db.with_tag("hit") == [1]
    db.save(tmp_path / "db.npz")
    back = ClipDatabase.load(tmp_path / "db.npz")
    assert back.names == db.names and back.tags == db.tags
    np.testing.assert_array_equal(back.local_rot, db.local_rot)
    np.testing.assert_array_equal(back.clip(2).root_pos, clips[2].root_pos)


def test_rejects_mixed_inputs_and_bad_files(tmp_path, rng):
    clips = _clips(rng)
    with pytest.raises(MotionError, match="fps"):
        ClipDatabase.from_motions([clips[0], clips[1].replace(fps=60.0)])
    with pytest.raises(UnknownNameError, match="no clip named 'x'"):
        ClipDatabase.from_motions(clips).clip("x")
    bad = tmp_path / "bad.npz"
    np.savez(bad, meta=np.array('{"format": "other"}'))
    with pytest.raises(FileFormatError, match="not a kinodyn clip database"):
        ClipDatabase.load(bad)
